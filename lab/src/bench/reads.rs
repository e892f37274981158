//! `graybox-lab bench reads`: the memory a `graybox serve` process takes for many concurrent
//! replays (GET /v1/models/{id}/rollout) of one large trajectory dataset: its resident set at
//! idle and its peak while they run (VmRSS and VmHWM from /proc, the peak reset first), in a
//! process of its own that did not take the upload (restarted after it), so that the upload's
//! memory does not count. Linux only.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use serde_json::{Value, json};

use graybox::error::Result;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;

use super::process::{Serve, graybox_bin, http, post, status_kb};

#[derive(Args, Debug)]
pub struct BenchReadsArgs {
    /// The dataset's arrays, in MB (double pendulum trajectories of 1000 steps).
    #[arg(long, default_value_t = 100)]
    pub mb: usize,
    /// Replays sent at once.
    #[arg(long, default_value_t = 100)]
    pub concurrent: usize,
    /// The graybox binary to measure [default: the one beside this one].
    #[arg(long)]
    pub graybox: Option<PathBuf>,
}

/// Steps of each trajectory.
const STEPS: usize = 1000;

pub fn run(a: BenchReadsArgs) -> Result<()> {
    let bin = graybox_bin(a.graybox.as_deref())?;
    let dir = std::env::temp_dir().join(graybox::store::new_id("graybox-bench-reads"));
    std::fs::create_dir_all(&dir)?;
    let measured = measure(&a, &bin, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    println!("{}", measured?);
    Ok(())
}

fn measure(a: &BenchReadsArgs, bin: &Path, dir: &Path) -> Result<Value> {
    let rt = tokio::runtime::Runtime::new()?;
    let db = dir.join("reads.db");
    // 8 bytes × (4n + m) per transition, n = m = 2.
    let count = (a.mb << 20) / 80;
    let trajectories = count.div_ceil(STEPS).max(1);
    let data = graybox::sim::double_pendulum_trajectories(trajectories, STEPS, 1)?;
    let body = data.to_json().into_bytes();
    drop(data);
    let mut uploader = Serve::start(bin, &db, &[])?;
    let ds = rt.block_on(post(
        &uploader.addr,
        "/v1/datasets",
        "application/json",
        body,
    ))?;
    let t = Template::DoublePendulum;
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4)?;
    let model = rt.block_on(post(
        &uploader.addr,
        "/v1/models",
        "application/octet-stream",
        file.to_bytes()?,
    ))?;
    uploader.stop();

    let mut serve = Serve::start(bin, &db, &[])?;
    let idle = status_kb(serve.pid(), "VmRSS")?;
    std::fs::write(format!("/proc/{}/clear_refs", serve.pid()), "5")?;
    let start = Instant::now();
    let statuses = rt.block_on(replays(
        &serve.addr,
        &model,
        &ds,
        a.concurrent,
        trajectories,
    ));
    let seconds = start.elapsed().as_secs_f64();
    let peak = status_kb(serve.pid(), "VmHWM")?;
    serve.stop();
    let mb = |kb: u64| (kb as f64 / 1024.0 * 10.0).round() / 10.0;
    Ok(json!({
        "bench": "reads",
        "dataset_mb": a.mb,
        "trajectories": trajectories,
        "concurrent": a.concurrent,
        "idle_rss_mb": mb(idle),
        "peak_rss_mb": mb(peak),
        "raise_mb": mb(peak.saturating_sub(idle)),
        "statuses": statuses,
        "seconds": (seconds * 100.0).round() / 100.0,
    }))
}

/// Sends `concurrent` replays at once (trajectory i mod `trajectories`); how many answered
/// with each status.
async fn replays(
    addr: &str,
    model: &str,
    ds: &str,
    concurrent: usize,
    trajectories: usize,
) -> Value {
    let calls = (0..concurrent).map(|i| {
        let path = format!(
            "/v1/models/{model}/rollout?dataset_id={ds}&index={}",
            i % trajectories
        );
        let addr = addr.to_string();
        tokio::spawn(async move { http(&addr, "GET", &path, None).await.map(|(s, _)| s) })
    });
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    for call in calls.collect::<Vec<_>>() {
        let status = match call.await {
            Ok(Ok(s)) => s.to_string(),
            _ => "no answer".into(),
        };
        *counts.entry(status).or_default() += 1;
    }
    json!(counts)
}
