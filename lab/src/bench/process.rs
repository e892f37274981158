//! A `graybox serve` process for the benchmarks that measure one (its memory from /proc), and
//! a plain HTTP/1.1 client to talk to it. Linux only.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use serde_json::Value;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use graybox::error::{Error, Result};

/// The graybox binary: `given`, else the one beside this one.
pub fn graybox_bin(given: Option<&Path>) -> Result<PathBuf> {
    match given {
        Some(b) => Ok(b.to_path_buf()),
        None => Ok(std::env::current_exe()?.with_file_name("graybox")),
    }
}

/// POSTs `body` and returns the `id` of the created item.
pub async fn post(addr: &str, path: &str, content_type: &str, body: Vec<u8>) -> Result<String> {
    let (status, answer) = http(addr, "POST", path, Some((content_type, body))).await?;
    let v: Value = serde_json::from_slice(&answer).unwrap_or_default();
    match v["id"].as_str() {
        Some(id) if status < 300 => Ok(id.to_string()),
        _ => Err(Error::Internal(format!("POST {path}: {status} {v}"))),
    }
}

/// One HTTP/1.1 request on a connection of its own: the status and the body.
pub async fn http(
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
pub fn status_kb(pid: u32, field: &str) -> Result<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status"))?;
    (text.lines())
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .ok_or_else(|| Error::Internal(format!("no {field} in /proc/{pid}/status")))
}

/// `graybox serve` on `db` with `args`, no workers, bodies up to 256 MB.
pub struct Serve {
    child: Child,
    pub addr: String,
}

impl Serve {
    pub fn start(bin: &Path, db: &Path, args: &[&str]) -> Result<Self> {
        let mut child = Command::new(bin)
            .args(["serve", "--workers", "0", "--http", "127.0.0.1:0"])
            .args(["--grpc", "127.0.0.1:0", "--max-body-mb", "256"])
            .args(["--max-inflight-body-mb", "3072", "--db"])
            .arg(db)
            .args(args)
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

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn stop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.pid().to_string()])
            .status();
        let _ = self.child.wait();
    }
}
