//! `graybox serve`: REST, gRPC and training workers in one process over one SQLite file.
//! Graceful shutdown: stop accepting and claiming, let running jobs reach an epoch end,
//! checkpoint them and give them back to the queue, then stop the listeners. A shutdown has a
//! bound (`--shutdown-grace-secs`): past it, jobs still mid-epoch go back to the queue from
//! their last checkpoint and the process exits without waiting for its computations.

use std::future::Future;
use std::net::SocketAddr;
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tracing::{info, warn};

use crate::api::listen::{TlsListener, acceptor};
use crate::api::rest::router;
use crate::api::tls::TlsFiles;
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
    /// The workers' lease owners: a forced shutdown gives back what they hold.
    owners: Vec<String>,
    servers: Vec<JoinHandle<Result<()>>>,
}

/// How a shutdown ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stopped {
    /// Every worker gave its job back at an epoch end, checkpointed.
    Clean,
    /// The grace ran out first: `released` jobs went back to the queue from their last
    /// checkpoint, and whatever was still computing was abandoned.
    Forced { released: u64 },
}

/// How long the listeners may finish answering once the workers are done: an open
/// server-sent event stream would hold a graceful HTTP shutdown forever.
const DRAIN: Duration = Duration::from_secs(5);

/// Giving held jobs back on a forced shutdown waits this long for the database at most;
/// past it their leases expire instead (and the jobs are reclaimed then).
const RELEASE_TIMEOUT: Duration = Duration::from_secs(5);

async fn bind(addr: &str, what: &str) -> Result<TcpListener> {
    TcpListener::bind(addr)
        .await
        .map_err(|e| Error::invalid(what, format!("cannot listen on {addr}: {e}")))
}

/// Starts the service `settings` describe (checked first).
pub async fn start(settings: Settings) -> Result<Running> {
    settings.validate()?;
    let cfg = settings.clone();
    // Before the database and the ports: a bad file stops the start-up with nothing opened.
    let identity = cfg
        .tls_cert
        .clone()
        .zip(cfg.tls_key.clone())
        .map(|(cert, key)| TlsFiles { cert, key }.load())
        .transpose()?;
    let store = Store::open(&cfg.db).await?;
    let app = App::new(store, settings);
    let http = bind(&cfg.http, "http").await?;
    let grpc = bind(&cfg.grpc, "grpc").await?;
    let (http_addr, grpc_addr) = (http.local_addr()?, grpc.local_addr()?);
    let (stop, stopped) = watch::channel(false);
    let tls = |alpn: &[&[u8]]| identity.as_ref().map(|i| acceptor(i, alpn)).transpose();
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
    let owners: Vec<String> = (0..cfg.workers)
        .map(|i| format!("{}-w{i}", crate::store::new_id("proc")))
        .collect();
    let workers = owners
        .iter()
        .map(|owner| {
            let worker = crate::worker::run_worker(app.clone(), owner.clone(), stopped.clone());
            tokio::spawn(worker)
        })
        .collect();
    let db = crate::store::redacted(&cfg.db);
    info!(%http_addr, %grpc_addr, %db, workers = cfg.workers, "graybox serving");
    Ok(Running {
        http_addr,
        grpc_addr,
        app,
        stop,
        workers,
        owners,
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
    /// Stops accepting and claiming, releases running jobs at their next epoch end
    /// (checkpointed), then stops the listeners; forced after `--shutdown-grace-secs`.
    pub async fn shutdown(self) -> Stopped {
        let grace = self.app.settings.shutdown_grace();
        self.shutdown_by(tokio::time::sleep(grace)).await
    }

    /// [`Running::shutdown`], forced when `force` resolves first: the workers are dropped,
    /// the jobs they hold go back to the queue at once (no new checkpoint), the listeners
    /// stop. Computations on blocking threads are not waited for: the caller shuts its
    /// runtime down without waiting for them (see `cli::serve`); dropping the calls' futures
    /// there tells their solvers to stop at the next time step.
    pub async fn shutdown_by(self, force: impl Future<Output = ()>) -> Stopped {
        let _ = self.stop.send(true);
        tokio::pin!(force);
        let aborts: Vec<_> = self.workers.iter().map(JoinHandle::abort_handle).collect();
        let workers = async {
            for w in self.workers {
                let _ = w.await;
            }
        };
        let stopped = tokio::select! {
            biased;
            () = &mut force => {
                aborts.iter().for_each(tokio::task::AbortHandle::abort);
                let held = crate::worker::release_held(&self.app, &self.owners);
                let released = match tokio::time::timeout(RELEASE_TIMEOUT, held).await {
                    Ok(Ok(n)) => n,
                    Ok(Err(e)) => {
                        warn!(error = %e, "giving jobs back failed; their leases will expire");
                        0
                    }
                    Err(_) => {
                        warn!("giving jobs back timed out; their leases will expire");
                        0
                    }
                };
                Stopped::Forced { released }
            }
            () = workers => Stopped::Clean,
        };
        let drain = tokio::time::sleep(DRAIN);
        tokio::pin!(drain);
        // `force` may be any future: never polled again once it has resolved.
        let mut forced = stopped != Stopped::Clean;
        for s in self.servers {
            let abort = s.abort_handle();
            if forced {
                abort.abort();
                continue;
            }
            tokio::select! {
                _ = s => {}
                () = &mut drain => abort.abort(),
                () = &mut force => {
                    forced = true;
                    abort.abort();
                }
            }
        }
        stopped
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
