//! The long-running processes: `graybox serve` (REST, gRPC and training workers over one
//! database) and `graybox worker` (training workers alone).
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
use tracing::info;

use crate::api::listen::{TlsListener, acceptor};
use crate::api::rest::router;
use crate::api::tls::TlsFiles;
use crate::app::{App, Settings, WorkerSettings};
use crate::error::{Error, Result};
use crate::store::Store;
use crate::worker::Pool;
pub use crate::worker::Stopped;

/// A started service. Dropping it does not stop it; call `shutdown`.
pub struct Running {
    pub http_addr: SocketAddr,
    pub grpc_addr: SocketAddr,
    pub app: App,
    tasks: Tasks,
}

/// A started `graybox worker`: training workers alone, and the health listener if asked
/// for. Dropping it does not stop it; call `shutdown`.
pub struct Worker {
    /// Where `/healthz` and `/readyz` answer (`--health`).
    pub health_addr: Option<SocketAddr>,
    pub app: App,
    tasks: Tasks,
}

/// What a process runs and stops together: its training workers, then its listeners.
struct Tasks {
    stop: watch::Sender<bool>,
    pool: Pool,
    servers: Vec<JoinHandle<Result<()>>>,
}

/// How long the listeners may finish answering once the workers are done: an open
/// server-sent event stream would hold a graceful HTTP shutdown forever.
const DRAIN: Duration = Duration::from_secs(5);

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
    // The ports before the database: a port another process holds stops the start-up
    // without creating database files.
    let http = bind(&cfg.http, "http").await?;
    let grpc = bind(&cfg.grpc, "grpc").await?;
    let store = open_store(&cfg.worker).await?;
    let app = App::new(store, settings);
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
        spawn_collector(&app, &stopped),
    ];
    let pool = Pool::spawn(&app, &stopped);
    let db = crate::store::redacted(&cfg.worker.db);
    info!(%http_addr, %grpc_addr, %db, workers = cfg.worker.workers, "graybox serving");
    Ok(Running {
        http_addr,
        grpc_addr,
        app,
        tasks: Tasks {
            stop,
            pool,
            servers,
        },
    })
}

/// Starts a training worker process: `settings`' workers on its database, and `/healthz` and
/// `/readyz` on `health` when given (no port otherwise).
pub async fn start_worker(settings: WorkerSettings, health: Option<&str>) -> Result<Worker> {
    let settings = Settings {
        worker: settings,
        ..Settings::default()
    };
    settings.validate()?;
    if settings.worker.workers == 0 {
        return Err(Error::invalid(
            "workers",
            "a worker process needs at least 1",
        ));
    }
    let store = open_store(&settings.worker).await?;
    let db = crate::store::redacted(&settings.worker.db);
    let app = App::new(store, settings);
    let (stop, stopped) = watch::channel(false);
    let mut servers = vec![spawn_collector(&app, &stopped)];
    let mut health_addr = None;
    if let Some(addr) = health {
        let listener = bind(addr, "health").await?;
        health_addr = Some(listener.local_addr()?);
        let router = crate::api::rest::health_router(app.clone());
        let stop = until_stopped(stopped.clone());
        servers.push(tokio::spawn(async move {
            let served = axum::serve(listener, router).with_graceful_shutdown(stop);
            served.await.map_err(Error::Io)
        }));
    }
    let pool = Pool::spawn(&app, &stopped);
    info!(%db, health = ?health_addr, workers = app.settings.worker.workers, "graybox worker");
    Ok(Worker {
        health_addr,
        app,
        tasks: Tasks {
            stop,
            pool,
            servers,
        },
    })
}

/// The database and object store `settings` name, the store's calls retried as they say.
async fn open_store(settings: &WorkerSettings) -> Result<Store> {
    let store = Store::open_with(&settings.db, settings.blobs.as_deref()).await?;
    Ok(store.with_retry(settings.blobs_retry()))
}

/// The process's collector of unreferenced objects and ended jobs' checkpoints (every
/// process runs one: whichever claims an object first deletes it), until the process stops.
fn spawn_collector(app: &App, stopped: &watch::Receiver<bool>) -> JoinHandle<Result<()>> {
    let (store, stop) = (app.store.clone(), until_stopped(stopped.clone()));
    tokio::spawn(async move {
        store.run_collector(crate::store::COLLECT_EVERY, stop).await;
        Ok(())
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
        let grace = self.app.settings.worker.shutdown_grace();
        self.shutdown_by(tokio::time::sleep(grace)).await
    }

    /// [`Running::shutdown`], forced when `force` resolves first: the workers are dropped,
    /// the jobs they hold go back to the queue at once (no new checkpoint), the listeners
    /// stop. Computations on blocking threads are not waited for: the caller shuts its
    /// runtime down without waiting for them (see `cli::serve`); dropping the calls' futures
    /// there tells their solvers to stop at the next time step.
    pub async fn shutdown_by(self, force: impl Future<Output = ()>) -> Stopped {
        self.tasks.stop_by(&self.app, force).await
    }
}

impl Worker {
    /// Resolves (with the reason) if a training worker ends without being told to: the
    /// process should stop and exit with a failure.
    pub async fn died(&mut self) -> String {
        self.tasks.pool.died().await
    }

    /// As [`Running::shutdown_by`]: jobs go back at their next epoch end, or at once when
    /// `force` resolves first.
    pub async fn shutdown_by(self, force: impl Future<Output = ()>) -> Stopped {
        self.tasks.stop_by(&self.app, force).await
    }
}

impl Tasks {
    async fn stop_by(self, app: &App, force: impl Future<Output = ()>) -> Stopped {
        let _ = self.stop.send(true);
        tokio::pin!(force);
        let stopped = self.pool.stop_by(app, &mut force).await;
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
