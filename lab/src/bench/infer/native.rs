//! `bench infer --model F --c-library LIB --python PY`: the C library's and the Python
//! module's latency beside the Rust figures of the same model and state. examples/c/latency.c
//! is built with the system's C compiler against LIB (what `cargo build --release -p
//! graybox-c` leaves in target/release) and run; lab/python/native_latency.py runs in PY's
//! environment (where `pip install ./clients/native` put graybox_native). Their figures come
//! back as JSON lines with their ratio to the in-process Rust median.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use std::collections::BTreeMap;

use serde_json::{Value, json};

use super::{BenchInferArgs, summary, time_calls};
use graybox::error::{Error, Result};
use graybox::infer::Evaluator;

fn failed(what: &str, detail: impl std::fmt::Display) -> Error {
    Error::Training(format!("the C benchmark {what}: {detail}"))
}

/// `a.rounds` rounds of Predict and Linearize of one state: in process, then through the C
/// library and in Python when asked, each with its ratio to this round's Rust median (the
/// machine's speed drifts between rounds more than the libraries differ), then the median
/// of each ratio over the rounds.
pub(super) fn one_state(
    a: &BenchInferArgs,
    eval: &Evaluator,
    path: &Path,
    (x, u): (&[f64], &[f64]),
    with: &dyn Fn(Value) -> Value,
) -> Result<()> {
    let mut ratios: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for round in 0..a.rounds.max(1) {
        let predict = time_calls(a.calls, || {
            std::hint::black_box(eval.predict(x, u, false));
        });
        let linearize = time_calls(a.calls, || {
            std::hint::black_box(eval.linearize_batch(x, u));
        });
        let mut figures = vec![
            summary("model_predict_1", predict, json!({})),
            summary("model_linearize_1", linearize, json!({})),
        ];
        let rust = [0, 1].map(|i| figures[i]["p50_us"].as_f64().unwrap_or(f64::NAN));
        if let Some(lib) = &a.c_library {
            figures.extend(c_figures(lib, path, a.calls, (x, u), rust)?);
        }
        if let Some(python) = &a.python {
            figures.extend(python_figures(python, path, a.calls, (x, u), rust)?);
        }
        for mut v in figures {
            v["round"] = json!(round);
            if let (Some(bench), Some(r)) = (v["bench"].as_str(), v["ratio_to_rust_p50"].as_f64()) {
                ratios.entry(bench.to_string()).or_default().push(r);
            }
            println!("{}", with(v));
        }
    }
    if !ratios.is_empty() {
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let medians: serde_json::Map<String, Value> = ratios
            .into_iter()
            .map(|(k, v)| (k, json!(median(v))))
            .collect();
        let line = json!({"bench": "ratio_to_rust_p50_median", "rounds": a.rounds.max(1),
                          "ratios": medians});
        println!("{}", with(line));
    }
    Ok(())
}

/// The soname the shared library at `lib` says it is (`readelf -d`).
fn soname_of(lib: &Path) -> Result<String> {
    let out = Command::new("readelf")
        .arg("-d")
        .arg(lib)
        .output()
        .map_err(|e| failed("readelf", e))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let name = text
        .lines()
        .find_map(|l| l.split("Library soname: [").nth(1))
        .and_then(|rest| rest.split(']').next());
    name.map(str::to_string)
        .ok_or_else(|| failed("library", format!("{} names no soname", lib.display())))
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
    // The program looks for the library by its soname (libgraybox_c.so.<ABI version>).
    let soname = tmp.join(soname_of(&dir.join("libgraybox_c.so"))?);
    let _ = std::fs::remove_file(&soname);
    std::os::unix::fs::symlink(dir.join("libgraybox_c.so"), &soname)?;
    let exe = tmp.join("latency");
    let out = Command::new("cc")
        .args(["-O2", "-std=c11", "-D_POSIX_C_SOURCE=199309L", "-I"])
        .arg(root.join("capi/include"))
        .arg(root.join("examples/c/latency.c"))
        .arg("-o")
        .arg(&exe)
        .arg(format!("-L{}", dir.display()))
        .arg(format!("-Wl,-rpath,{}", tmp.display()))
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
pub(super) fn c_figures(
    lib: &Path,
    model: &Path,
    calls: usize,
    state: (&[f64], &[f64]),
    rust_p50: [f64; 2],
) -> Result<Vec<Value>> {
    let exe = build(lib)?;
    let out = run(Command::new(&exe).arg(model).arg(calls.to_string()), state);
    std::fs::remove_dir_all(exe.parent().expect("a directory")).ok();
    with_ratios(&out?, rust_p50, "C ABI, in the caller's process")
}

/// graybox_native's figures (lab/python/native_latency.py run by `python`, in whose
/// environment the module is installed), the first two with their ratios to Rust's.
pub(super) fn python_figures(
    python: &Path,
    model: &Path,
    calls: usize,
    state: (&[f64], &[f64]),
    rust_p50: [f64; 2],
) -> Result<Vec<Value>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/native_latency.py");
    let mut cmd = Command::new(python);
    let out = run(cmd.arg(script).arg(model).arg(calls.to_string()), state)?;
    with_ratios(&out, rust_p50, "graybox_native, in the Python process")
}

/// A benchmark program's JSON lines, given the state (x then u) on its standard input.
fn run(cmd: &mut Command, (x, u): (&[f64], &[f64])) -> Result<String> {
    let mut child = cmd
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
    if !out.status.success() {
        return Err(failed("run", String::from_utf8_lossy(&out.stderr)));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The figures, the first two (predict's, linearize's) with their medians' ratios to Rust's.
fn with_ratios(lines: &str, rust_p50: [f64; 2], transport: &str) -> Result<Vec<Value>> {
    let mut figures = vec![];
    for (i, line) in lines.lines().enumerate() {
        let mut v: Value = serde_json::from_str(line).map_err(|e| failed("output", e))?;
        if let Some(&rust) = rust_p50.get(i) {
            let p50 = v["p50_us"].as_f64().unwrap_or(f64::NAN);
            v["ratio_to_rust_p50"] = json!(p50 / rust);
            v["rust_p50_us"] = json!(rust);
        }
        v["transport"] = json!(transport);
        figures.push(v);
    }
    Ok(figures)
}
