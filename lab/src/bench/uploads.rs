//! `graybox-lab bench uploads`: the memory one dataset upload takes a `graybox serve` process,
//! per byte of its body, for each JSON form (flat transitions, trajectories), its bytes kept
//! in the database's rows and in an object store (`--blobs file://…`): the peak resident set
//! (VmHWM, reset first) over the idle one of a fresh process, divided by the body's length.
//! `--max-inflight-body-mb` reserves `app::uploads::BodyKind::cost` per body: this measures
//! what that reservation has to cover.

use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use graybox::app::uploads::BodyKind;
use graybox::error::{Error, Result};
use graybox::sim::{SimConfig, double_pendulum_trajectories, simulate};

use super::process::{Serve, graybox_bin, http, status_kb};

#[derive(Args, Debug)]
pub struct BenchUploadsArgs {
    /// The body's size, roughly, in MB.
    #[arg(long, default_value_t = 20)]
    pub mb: usize,
    /// The graybox binary to measure [default: the one beside this one].
    #[arg(long)]
    pub graybox: Option<PathBuf>,
}

/// Bytes of JSON per transition, roughly, of each form (to size the body).
const FLAT_BYTES: usize = 200;
const TRAJECTORY_BYTES: usize = 120;

pub fn run(a: BenchUploadsArgs) -> Result<()> {
    let bin = graybox_bin(a.graybox.as_deref())?;
    let t = graybox::physics::templates::Template::DoublePendulum;
    let flat = simulate(
        &t,
        t.defaults(),
        &SimConfig {
            count: (a.mb << 20) / FLAT_BYTES,
            ..SimConfig::default()
        },
    )?;
    let trajectories =
        double_pendulum_trajectories(((a.mb << 20) / TRAJECTORY_BYTES) / 1000, 1000, 1)?;
    for (form, body) in [
        ("flat", flat.to_json()),
        ("trajectories", trajectories.to_json()),
    ] {
        for store in ["rows", "object store"] {
            let dir = std::env::temp_dir().join(graybox::store::new_id("graybox-bench-uploads"));
            std::fs::create_dir_all(&dir)?;
            let measured = measure(&bin, &dir, store, body.as_bytes());
            let _ = std::fs::remove_dir_all(&dir);
            let (idle, peak) = measured?;
            let per_byte = (peak.saturating_sub(idle) * 1024) as f64 / body.len() as f64;
            let line = json!({
                "bench": "uploads",
                "form": form,
                "bytes_in": store,
                "body_mb": (body.len() as f64 / 1048576.0 * 10.0).round() / 10.0,
                "idle_rss_mb": idle / 1024,
                "peak_rss_mb": peak / 1024,
                "peak_per_body_byte": (per_byte * 100.0).round() / 100.0,
                "reserved_per_body_byte": BodyKind::Dataset.cost(body.len()) as f64 / body.len() as f64,
            });
            println!("{line}");
        }
    }
    Ok(())
}

/// The idle and peak resident set (kB) of a fresh `graybox serve` over one upload of `body`.
fn measure(bin: &Path, dir: &Path, store: &str, body: &[u8]) -> Result<(u64, u64)> {
    let blobs = format!("file://{}", dir.join("blobs").display());
    let args: &[&str] = if store == "rows" {
        &[]
    } else {
        &["--blobs", &blobs]
    };
    let mut serve = Serve::start(bin, &dir.join("uploads.db"), args)?;
    let idle = status_kb(serve.pid(), "VmRSS")?;
    std::fs::write(format!("/proc/{}/clear_refs", serve.pid()), "5")?;
    let rt = tokio::runtime::Runtime::new()?;
    let sent = ("application/json", body.to_vec());
    let (status, answer) = rt.block_on(http(&serve.addr, "POST", "/v1/datasets", Some(sent)))?;
    let peak = status_kb(serve.pid(), "VmHWM")?;
    serve.stop();
    if status != 201 {
        let why = String::from_utf8_lossy(&answer[..answer.len().min(300)]).into_owned();
        return Err(Error::Internal(format!("upload: {status} {why}")));
    }
    Ok((idle, peak))
}
