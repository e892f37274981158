//! examples/c/control_loop.c, built with the system's C compiler against this library and
//! run on every recorded model: 1000 steps of gbx_predict_ws in a C loop, the first ten equal
//! to the service's recorded Rollout bit for bit, and a warning on stderr when the loop takes
//! the model far from its training data.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Where cargo put this build's libgraybox_c: `cargo test` leaves it in `deps/` beside the
/// test binary (only `cargo build` copies it up to the profile's directory).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().unwrap().to_path_buf()
}

/// The soname of this ABI's library.
fn soname() -> String {
    format!("libgraybox_c.so.{}", graybox_c::GBX_ABI_VERSION)
}

/// The library says its soname, the ABI version's, so that a program built for another ABI
/// does not load it.
#[test]
fn the_librarys_soname_is_its_abi_version() {
    let out = Command::new("readelf")
        .arg("-d")
        .arg(library_dir().join("libgraybox_c.so"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains(&format!("Library soname: [{}]", soname())),
        "{text}"
    );
}

fn numbers(v: &Value, out: &mut String) {
    match v {
        Value::Array(a) => a.iter().for_each(|v| numbers(v, out)),
        // Rust prints an f64 in its shortest round-trip form, which strtod reads back exactly.
        v => write!(out, "{} ", v.as_f64().unwrap()).unwrap(),
    }
}

/// Builds `source` (under examples/c/) with `compiler` and `std` against this build's library
/// into a fresh temporary directory; the executable's path.
fn build(compiler: &str, std: &str, source: &str, libs: &[&str]) -> PathBuf {
    let lib = library_dir();
    assert!(
        lib.join("libgraybox_c.so").exists(),
        "no libgraybox_c.so in {}",
        lib.display()
    );
    let stem = source.split('.').next().unwrap();
    let tmp = std::env::temp_dir().join(format!("graybox-{stem}-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    // The program looks for the library by its soname, as an installed one is named.
    let soname = tmp.join(soname());
    let _ = std::fs::remove_file(&soname);
    std::os::unix::fs::symlink(lib.join("libgraybox_c.so"), &soname).unwrap();
    let exe = tmp.join(stem);
    let built = Command::new(compiler)
        .args(["-O2", std, "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(root().join("capi/include"))
        .arg(root().join("examples/c").join(source))
        .arg("-o")
        .arg(&exe)
        .arg(format!("-L{}", lib.display()))
        .arg(format!("-Wl,-rpath,{}", tmp.display()))
        .args(libs)
        .output()
        .unwrap();
    assert!(
        built.status.success(),
        "{compiler}: {}",
        String::from_utf8_lossy(&built.stderr)
    );
    exe
}

#[test]
fn the_c_example_runs_a_control_loop_with_the_services_answers() {
    let exe = build("cc", "-std=c11", "control_loop.c", &["-lgraybox_c", "-lm"]);
    let tmp = exe.parent().unwrap().to_path_buf();

    let text = std::fs::read_to_string(root().join("tests/fixtures/inference/answers.json"));
    let record: Value = serde_json::from_str(&text.unwrap()).unwrap();
    for (name, entry) in record.as_object().unwrap() {
        let calls = entry["calls"].as_array().unwrap();
        let rollout = calls.iter().find(|c| c["rpc"] == "rollout").unwrap();
        let nx = rollout["x0"].as_array().unwrap().len();
        let m = entry["m"].as_u64().unwrap();
        let steps = rollout["u"].as_array().unwrap().len();
        let mut txt = format!("{nx} {m} {steps}\n");
        numbers(&rollout["x0"], &mut txt);
        numbers(&rollout["u"], &mut txt);
        numbers(&rollout["answer"]["xs"], &mut txt);
        let path = tmp.join(format!("{name}.txt"));
        std::fs::write(&path, txt).unwrap();
        let run = Command::new(&exe)
            .arg(root().join(entry["file"].as_str().unwrap()))
            .arg(&path)
            .output()
            .unwrap();
        let (out, err) = (
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr),
        );
        assert!(run.status.success(), "{name}: {out}{err}");
        assert!(
            out.contains("1000 steps; the first 10 equal"),
            "{name}: {out}"
        );
    }
    // Without a record: a loop from rest, as a user first runs it. The UR5 falls under no
    // torque, far out of the states it was trained on, and the example says so.
    let (out, err) = run_on(&exe, "ur5-residual");
    assert!(
        out.starts_with("1000 steps of 0.01 s from rest; q ends at "),
        "{out}"
    );
    let warning = err
        .lines()
        .find(|l| l.starts_with("warning: step "))
        .unwrap_or_default();
    assert!(
        warning.contains(": z = ") && warning.contains(" > 4: ") && warning.contains("doubt"),
        "no warning of z on stderr: {err}"
    );
    assert!(err.contains("warning: z went above 4 at step "), "{err}");
    std::fs::remove_dir_all(&tmp).ok();
}

/// `exe`'s output and error output on a recorded model file, after it succeeded.
fn run_on(exe: &Path, model: &str) -> (String, String) {
    let run = Command::new(exe)
        .arg(root().join(format!("tests/fixtures/inference/{model}.gbx")))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&run.stdout).into_owned();
    let err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "{out}{err}");
    (out, err)
}

#[test]
fn the_cpp_wrapper_owns_the_model_and_throws_the_librarys_errors() {
    let exe = build("c++", "-std=c++17", "wrapper.cpp", &["-lgraybox_c"]);
    let (out, _) = run_on(&exe, "cartpole-wb");
    assert!(
        out.starts_with("one step of 0.01 s from rest: qdot[0] = "),
        "{out}"
    );
    assert!(
        out.contains("ten steps from rest: z at the last = "),
        "{out}"
    );
    // The workspace's rollout is the thread's own, bit for bit.
    assert!(out.contains("the same in a workspace: equal"), "{out}");
    // GBX_STATUS_IO, with the message naming the file.
    assert!(
        out.contains("status 3: i/o error: cannot read no/such/model.gbx"),
        "{out}"
    );
    std::fs::remove_dir_all(exe.parent().unwrap()).ok();
}
