//! `bench infer --model F --c-library LIB`: the C library's latency beside the Rust figures of
//! the same model and state. examples/c/latency.c is built with the system's C compiler
//! against LIB (what `cargo build --release -p graybox-c` leaves in target/release) and run;
//! its figures come back as JSON lines with their ratio to the in-process Rust median.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::{Value, json};

use graybox::error::{Error, Result};

fn failed(what: &str, detail: impl std::fmt::Display) -> Error {
    Error::Training(format!("the C benchmark {what}: {detail}"))
}

/// examples/c/latency.c built against the library at `lib`, in a fresh temporary directory.
fn build(lib: &Path) -> Result<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = lib
        .canonicalize()
        .map_err(|e| failed("library", format!("{}: {e}", lib.display())))?;
    let dir = dir.parent().expect("a file has a directory");
    let tmp = std::env::temp_dir().join(format!("graybox-latency-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)?;
    let exe = tmp.join("latency");
    let out = Command::new("cc")
        .args(["-O2", "-std=c11", "-D_POSIX_C_SOURCE=199309L", "-I"])
        .arg(root.join("capi/include"))
        .arg(root.join("examples/c/latency.c"))
        .arg("-o")
        .arg(&exe)
        .arg(format!("-L{}", dir.display()))
        .arg(format!("-Wl,-rpath,{}", dir.display()))
        .arg("-lgraybox_c")
        .output()
        .map_err(|e| failed("compiler", e))?;
    if !out.status.success() {
        return Err(failed("build", String::from_utf8_lossy(&out.stderr)));
    }
    Ok(exe)
}

/// The C figures of `calls` calls of predict and linearize at (x, u), each with its median's
/// ratio to Rust's (`rust_p50`: predict's, then linearize's).
pub(super) fn figures(
    lib: &Path,
    model: &Path,
    calls: usize,
    (x, u): (&[f64], &[f64]),
    rust_p50: [f64; 2],
) -> Result<Vec<Value>> {
    let exe = build(lib)?;
    let mut child = Command::new(&exe)
        .arg(model)
        .arg(calls.to_string())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| failed("run", e))?;
    let state: Vec<String> = x.iter().chain(u).map(f64::to_string).collect();
    let mut stdin = child.stdin.take().expect("piped");
    writeln!(stdin, "{}", state.join(" "))?;
    drop(stdin);
    let out = child.wait_with_output()?;
    std::fs::remove_dir_all(exe.parent().expect("a directory")).ok();
    if !out.status.success() {
        return Err(failed("run", String::from_utf8_lossy(&out.stderr)));
    }
    let lines = String::from_utf8_lossy(&out.stdout);
    let mut figures = vec![];
    for (line, rust) in lines.lines().zip(rust_p50) {
        let mut v: Value = serde_json::from_str(line).map_err(|e| failed("output", e))?;
        let p50 = v["p50_us"].as_f64().unwrap_or(f64::NAN);
        v["ratio_to_rust_p50"] = json!(p50 / rust);
        v["rust_p50_us"] = json!(rust);
        v["transport"] = json!("C ABI, in the caller's process");
        figures.push(v);
    }
    Ok(figures)
}
