//! `graybox worker`: a training worker process, no API. Any number of them, on any machines,
//! share one PostgreSQL database (or, on one machine, a SQLite file) with the API nodes.

use clap::Args;

use super::serve::{announce_forced, announce_stop, long_running, until_forced};
use crate::app::WorkerSettings;
use crate::error::{Error, Result};
use crate::service::signal;

#[derive(Args, Debug)]
pub struct WorkerArgs {
    #[command(flatten)]
    pub settings: WorkerSettings,
    /// Answer GET /healthz (alive), /readyz (the database and the object store answer) and
    /// /metrics on this address (`graybox health --http ADDR` asks it). Without it the worker opens no port;
    /// its exit status tells instead: 0 after SIGTERM or ctrl-c, 1 if the database cannot be
    /// opened or a training worker failed.
    #[arg(long, env = "GRAYBOX_WORKER_HEALTH")]
    pub health: Option<String>,
}

pub(super) fn worker(a: WorkerArgs) -> Result<()> {
    let grace = a.settings.shutdown_grace();
    long_running(async move {
        let mut worker = crate::service::start_worker(a.settings, a.health.as_deref()).await?;
        let n = worker.app.settings.worker.workers;
        match worker.health_addr {
            Some(addr) => eprintln!("graybox worker: {n} worker(s), health on http://{addr}"),
            None => eprintln!("graybox worker: {n} worker(s)"),
        }
        let died = tokio::select! {
            () = signal() => None,
            why = worker.died() => Some(why),
        };
        match died {
            None => {
                announce_stop(grace);
                announce_forced(worker.shutdown_by(until_forced(grace)).await);
                Ok(())
            }
            // The remaining workers' jobs go back at once: a failing process should not
            // hold leases until they expire.
            Some(why) => {
                announce_forced(worker.shutdown_by(async {}).await);
                Err(Error::Internal(why))
            }
        }
    })
}
