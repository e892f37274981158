//! `graybox-lab bench reads`: the memory a `graybox serve` process takes for many concurrent
//! replays (GET /v1/models/{id}/rollout) of one large trajectory dataset: its resident set at
//! idle and its peak while they run (VmRSS and VmHWM from /proc, the peak reset first), in a
//! process of its own that did not take the upload (restarted after it), so that the upload's
//! memory does not count. Linux only.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use clap::Args;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use graybox::error::{Error, Result};
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;

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
    let bin = match &a.graybox {
        Some(b) => b.clone(),
        None => std::env::current_exe()?.with_file_name("graybox"),
    };
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
    let mut uploader = Serve::start(bin, &db)?;
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

    let mut serve = Serve::start(bin, &db)?;
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

/// POSTs `body` and returns the `id` of the created item.
async fn post(addr: &str, path: &str, content_type: &str, body: Vec<u8>) -> Result<String> {
    let (status, answer) = http(addr, "POST", path, Some((content_type, body))).await?;
    let v: Value = serde_json::from_slice(&answer).unwrap_or_default();
    match v["id"].as_str() {
        Some(id) if status < 300 => Ok(id.to_string()),
        _ => Err(Error::Internal(format!("POST {path}: {status} {v}"))),
    }
}

/// One HTTP/1.1 request on a connection of its own: the status and the body.
async fn http(
    addr: &str,
    method: &str,
    path: &str,
    body: Option<(&str, Vec<u8>)>,
) -> Result<(u16, Vec<u8>)> {
    let mut s = TcpStream::connect(addr).await?;
    let mut head = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    if let Some((ct, b)) = &body {
        head += &format!("Content-Type: {ct}\r\nContent-Length: {}\r\n", b.len());
    }
    head += "\r\n";
    s.write_all(head.as_bytes()).await?;
    if let Some((_, b)) = &body {
        s.write_all(b).await?;
    }
    let mut out = Vec::new();
    s.read_to_end(&mut out).await?;
    let end = (out.windows(4).position(|w| w == b"\r\n\r\n"))
        .ok_or_else(|| Error::Internal(format!("{method} {path}: no HTTP answer")))?;
    let head = String::from_utf8_lossy(&out[..end]).to_ascii_lowercase();
    let status = (head.split(' ').nth(1).and_then(|s| s.parse().ok()))
        .ok_or_else(|| Error::Internal(format!("{method} {path}: {head}")))?;
    let mut body = out[end + 4..].to_vec();
    if head.contains("transfer-encoding: chunked") {
        body = dechunk(&body);
    }
    Ok((status, body))
}

/// A chunked body's bytes.
fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(eol) = b.windows(2).position(|w| w == b"\r\n") {
        let size = String::from_utf8_lossy(&b[..eol]);
        let Ok(n) = usize::from_str_radix(size.trim(), 16) else {
            break;
        };
        if n == 0 || b.len() < eol + 2 + n {
            break;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[(eol + 4 + n).min(b.len())..];
    }
    out
}

/// A `kB` field of /proc/PID/status.
fn status_kb(pid: u32, field: &str) -> Result<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status"))?;
    (text.lines())
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .ok_or_else(|| Error::Internal(format!("no {field} in /proc/{pid}/status")))
}

/// `graybox serve` on `db`, no workers, bodies up to 256 MB.
struct Serve {
    child: Child,
    addr: String,
}

impl Serve {
    fn start(bin: &Path, db: &Path) -> Result<Self> {
        let mut child = Command::new(bin)
            .args(["serve", "--workers", "0", "--http", "127.0.0.1:0"])
            .args(["--grpc", "127.0.0.1:0", "--max-body-mb", "256"])
            .args(["--max-inflight-body-mb", "2048", "--db"])
            .arg(db)
            .env("RUST_LOG", "warn")
            .stderr(Stdio::piped())
            .spawn()?;
        let stderr = child.stderr.take().expect("piped");
        let mut lines = BufReader::new(stderr).lines();
        let addr = loop {
            let Some(line) = lines.next().transpose()? else {
                return Err(Error::Internal(format!("{} serve exited", bin.display())));
            };
            if let Some(rest) = line.strip_prefix("graybox: REST on http://") {
                break rest.split(',').next().unwrap_or_default().to_string();
            }
        };
        // Keeps reading its log, so that a full pipe never blocks it.
        std::thread::spawn(move || lines.for_each(drop));
        Ok(Self { child, addr })
    }

    fn pid(&self) -> u32 {
        self.child.id()
    }

    fn stop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.pid().to_string()])
            .status();
        let _ = self.child.wait();
    }
}
