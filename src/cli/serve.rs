//! `graybox serve`: its flags and the runtime it starts the service on.

use crate::app::Settings;
use crate::app::settings::MAX_BLOCKING_THREADS;
use crate::error::Result;

/// `graybox serve`'s flags are the service's settings.
pub type ServeArgs = Settings;

pub fn serve(settings: Settings) -> Result<()> {
    settings.validate()?;
    let tls = settings.tls_cert.is_some();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .max_blocking_threads(MAX_BLOCKING_THREADS)
        .enable_all()
        .build()?;
    rt.block_on(async {
        let running = crate::service::start(settings).await?;
        let scheme = if tls { "https" } else { "http" };
        eprintln!(
            "graybox: REST on {scheme}://{}, gRPC on {}{}",
            running.http_addr,
            running.grpc_addr,
            if tls { " (TLS)" } else { "" }
        );
        crate::service::signal().await;
        eprintln!("graybox: shutting down (running jobs are checkpointed at their next epoch end)");
        running.shutdown().await;
        Ok(())
    })
}
