//! `graybox serve`: REST, gRPC and training workers in one process over one SQLite file.
//! Graceful shutdown: stop claiming, let running jobs reach an epoch end, checkpoint them and
//! give them back to the queue, then stop the listeners.

use std::net::SocketAddr;

use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tracing::info;

use crate::api::listen::{TlsFiles, TlsListener, acceptor};
use crate::api::rest::router;
use crate::app::{App, Settings};
use crate::error::{Error, Result};
use crate::store::Store;

/// A started service. Dropping it does not stop it; call `shutdown`.
pub struct Running {
    pub http_addr: SocketAddr,
    pub grpc_addr: SocketAddr,
    pub app: App,
    stop: watch::Sender<bool>,
    workers: Vec<JoinHandle<()>>,
    servers: Vec<JoinHandle<Result<()>>>,
}

async fn bind(addr: &str, what: &str) -> Result<TcpListener> {
    TcpListener::bind(addr)
        .await
        .map_err(|e| Error::invalid(what, format!("cannot listen on {addr}: {e}")))
}

/// Starts the service `settings` describe (checked first).
pub async fn start(settings: Settings) -> Result<Running> {
    settings.validate()?;
    let cfg = settings.clone();
    let store = Store::open(&cfg.db).await?;
    let app = App::new(store, settings);
    let http = bind(&cfg.http, "http").await?;
    let grpc = bind(&cfg.grpc, "grpc").await?;
    let (http_addr, grpc_addr) = (http.local_addr()?, grpc.local_addr()?);
    let (stop, stopped) = watch::channel(false);
    let files = cfg
        .tls_cert
        .clone()
        .zip(cfg.tls_key.clone())
        .map(|(cert, key)| TlsFiles { cert, key });
    let tls = |alpn: &[&[u8]]| files.as_ref().map(|f| acceptor(f, alpn)).transpose();
    let servers = vec![
        tokio::spawn(serve_rest(
            app.clone(),
            http,
            tls(&[b"http/1.1"])?,
            until_stopped(stopped.clone()),
        )),
        tokio::spawn(crate::api::grpc::serve(
            app.clone(),
            grpc,
            cfg.token().map(String::from),
            tls(&[b"h2"])?,
            until_stopped(stopped.clone()),
        )),
        tokio::spawn(sweep_model_cache(
            app.clone(),
            until_stopped(stopped.clone()),
        )),
    ];
    let workers = (0..cfg.workers)
        .map(|i| {
            let owner = format!("{}-w{i}", crate::store::new_id("proc"));
            tokio::spawn(crate::jobs::run_worker(app.clone(), owner, stopped.clone()))
        })
        .collect();
    info!(%http_addr, %grpc_addr, db = %cfg.db, workers = cfg.workers, "graybox serving");
    Ok(Running {
        http_addr,
        grpc_addr,
        app,
        stop,
        workers,
        servers,
    })
}

/// Resolves once `rx` turns true (or its sender is gone).
async fn until_stopped(mut rx: watch::Receiver<bool>) {
    while !*rx.borrow() {
        if rx.changed().await.is_err() {
            return;
        }
    }
}

/// The REST API on `listener`, over TLS when `tls` is given, until `stop` resolves.
async fn serve_rest(
    app: App,
    listener: TcpListener,
    tls: Option<tokio_rustls::TlsAcceptor>,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<()> {
    let rest = router(app);
    let served = match tls {
        None => {
            axum::serve(listener, rest)
                .with_graceful_shutdown(stop)
                .await
        }
        Some(a) => {
            axum::serve(TlsListener::new(listener, a)?, rest)
                .with_graceful_shutdown(stop)
                .await
        }
    };
    served.map_err(Error::Io)
}

/// Evicts cached models that another process on the same database deleted, every
/// `CACHE_SWEEP`, until `stop` resolves.
async fn sweep_model_cache(app: App, stop: impl std::future::Future<Output = ()>) -> Result<()> {
    tokio::pin!(stop);
    loop {
        tokio::select! {
            () = tokio::time::sleep(crate::app::inference::CACHE_SWEEP) => {}
            () = &mut stop => return Ok(()),
        }
        if let Err(e) = app.sweep_model_cache().await {
            tracing::warn!(error = %e, "checking cached models failed");
        }
    }
}

impl Running {
    /// Stops claiming, releases running jobs at their next epoch end (checkpointed), then
    /// stops the listeners.
    pub async fn shutdown(self) {
        let _ = self.stop.send(true);
        for w in self.workers {
            let _ = w.await;
        }
        // Open server-sent event streams would hold a graceful HTTP shutdown forever.
        for s in self.servers {
            let abort = s.abort_handle();
            if tokio::time::timeout(std::time::Duration::from_secs(5), s)
                .await
                .is_err()
            {
                abort.abort();
            }
        }
    }
}

/// Resolves on SIGTERM or SIGINT.
pub async fn signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .expect("signal handler");
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = ctrl_c.await;
    }
}
