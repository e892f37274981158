//! The benchmarks print what the issues ask for, one JSON line per figure.

use std::process::{Command, Output};

use serde_json::Value;

/// The JSON lines a successful `graybox-lab` run prints.
fn json_lines(args: &[&str]) -> Vec<Value> {
    let out = lab(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (out.stdout.split(|&b| b == b'\n'))
        .filter(|l| !l.is_empty())
        .map(|l| serde_json::from_slice(l).unwrap())
        .collect()
}

fn lab(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_graybox-lab"))
        .args(args)
        .output()
        .unwrap()
}

/// `bench train` prints one JSON line per model and batch size with the step-only
/// throughput, the throughput with validation (never higher: it adds work to the same
/// samples), and the CPU a timed epoch used per second of wall time.
#[test]
fn bench_train_reports_step_throughput_and_cpu() {
    let out = lab(&[
        "bench",
        "train",
        "--train",
        "512",
        "--val",
        "32",
        "--epochs",
        "1",
        "--min-steps",
        "4",
        "--models",
        "MVF",
        "--batch-sizes",
        "256",
        "--time-limit",
        "0",
        "--threads",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value =
        serde_json::from_slice(out.stdout.split(|&b| b == b'\n').next().unwrap()).unwrap();
    let f = |k: &str| line[k].as_f64().unwrap_or_else(|| panic!("{k} in {line}"));
    assert!(f("samples_per_second") > 0.0);
    assert!(
        f("samples_per_second_with_validation") <= f("samples_per_second"),
        "{line}"
    );
    assert!(f("cpu_per_wall") > 0.0, "{line}");
    assert_eq!(line["batch_size"], 256);
    // Two threads split a batch of 256 into two shards; 4 steps need 2 epochs of 2 batches.
    assert_eq!(line["threads"], 2, "{line}");
    assert_eq!(line["shards"], 2, "{line}");
    assert_eq!(line["epochs"], 2, "{line}");
}

/// `graybox-lab bench multibody` on the Panda (a mimic joint: no ABA figure) prints the agreement of
/// the two paths' q̈ and a positive µs per call for each figure, one JSON line each, and
/// without Pinocchio's C++ benchmark a line naming the missing binary and how to build it.
#[test]
fn bench_multibody_prints_agreement_and_figures() {
    let urdf = format!(
        "{}/../tests/fixtures/urdf/robots/panda.urdf",
        env!("CARGO_MANIFEST_DIR")
    );
    // No C++ benchmark at that path: a line says how to build it, and the rest runs.
    let missing = "no-such-dir/bench";
    let lines = json_lines(&[
        "bench",
        "multibody",
        "--urdf",
        &urdf,
        "--calls",
        "20",
        "--pinocchio-bench",
        missing,
    ]);
    assert_eq!(lines[0]["bench"], "multibody_agreement");
    assert_eq!(lines[0]["mimic"], true);
    assert!(
        lines[0]["max_rel_diff_qdd"].as_f64().unwrap() < 1e-12,
        "{}",
        lines[0]
    );
    let names: Vec<&str> = lines[1..]
        .iter()
        .map(|l| l["bench"].as_str().unwrap())
        .collect();
    assert!(!names.contains(&"aba_f64"), "{names:?}");
    for name in [
        "graybox_predict_1",
        "graybox_linearize_1",
        "template_white_box_acceleration_f64",
        "data_forward_dynamics_f64",
        "crba_cholesky_f64",
        "fd_derivatives_analytic",
    ] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
    let skipped = (lines.iter())
        .find(|l| l["bench"] == "pinocchio_cpp")
        .expect("a line for the C++ benchmark");
    let why = skipped["skipped"].as_str().unwrap();
    assert!(
        why.contains(missing) && why.contains("scripts/pinocchio_cpp/build.sh"),
        "{why}"
    );
    for l in lines[1..].iter().filter(|l| l["bench"] != "pinocchio_cpp") {
        assert!(l["p50_us"].as_f64().unwrap() > 0.0, "{l}");
    }
}

/// `graybox-lab bench events` prints one line per phase: no polls while nobody subscribes,
/// one shared poller for many subscribers of `/v1/events` or of one job, one per job when
/// each follows its own.
#[test]
fn bench_events_prints_the_polls_of_each_phase() {
    let lines = json_lines(&["bench", "events", "--subscribers", "3", "--seconds", "0.5"]);
    let polls = |phase: &str| {
        let line = lines.iter().find(|l| l["phase"] == phase).unwrap();
        assert_eq!(line["backend"], "sqlite", "{line}");
        line["polls_per_second"].as_f64().unwrap()
    };
    assert_eq!(polls("Idle"), 0.0);
    assert!(polls("AllJobs") > 0.0 && polls("OneJob") > 0.0, "{lines:?}");
    // Three pollers against one in the same window.
    assert!(polls("OwnJob") > polls("OneJob"), "{lines:?}");
}

/// `graybox-lab bench queue` prints the wait of jobs submitted to idle workers, in order.
#[test]
fn bench_queue_prints_the_claim_latency() {
    let lines = json_lines(&["bench", "queue", "--workers", "2", "--jobs", "3"]);
    assert_eq!(lines.len(), 1, "{lines:?}");
    let line = &lines[0];
    assert_eq!(
        (line["bench"].as_str(), line["jobs"].as_u64()),
        (Some("claim_latency"), Some(3))
    );
    let (p50, p99) = (
        line["p50_ms"].as_f64().unwrap(),
        line["p99_ms"].as_f64().unwrap(),
    );
    assert!(0.0 < p50 && p50 <= p99, "{line}");
}

/// `graybox-lab bench scale` prints one line per worker count and placement (one worker
/// once), the first its own reference; the processes are real `graybox worker`s.
#[test]
fn bench_scale_prints_each_worker_count() {
    let lines = json_lines(&["bench", "scale", "--jobs", "2", "--epochs", "1"]);
    let runs: Vec<(u64, &str)> = lines
        .iter()
        .map(|l| {
            let placement = l["placement"].as_str().unwrap();
            (l["workers"].as_u64().unwrap(), placement)
        })
        .collect();
    assert_eq!(runs, [(1, "processes"), (2, "processes"), (2, "threads")]);
    assert_eq!(lines[0]["ratio_to_first"], 1.0);
    assert!(
        lines.iter().all(|l| l["seconds"].as_f64().unwrap() > 0.0),
        "{lines:?}"
    );
}

/// `graybox-lab bench horizon` prints one line per horizon, the first its own reference.
#[test]
fn bench_horizon_prints_each_horizon() {
    let lines = json_lines(&[
        "bench",
        "horizon",
        "--horizons",
        "1,3",
        "--epochs",
        "1",
        "--trajectories",
        "2",
    ]);
    let h: Vec<u64> = lines
        .iter()
        .map(|l| l["horizon"].as_u64().unwrap())
        .collect();
    assert_eq!(h, [1, 3]);
    assert_eq!(lines[0]["epoch_time_over_first"], 1.0);
    assert_eq!(lines[1]["windows"], 2 * 198);
    assert!(
        lines
            .iter()
            .all(|l| l["samples_per_second"].as_f64().unwrap() > 0.0)
    );
}

/// `graybox-lab bench reads` prints a real `graybox serve` process's resident set at idle
/// and at its peak while concurrent replays of a dataset run, and how each was answered.
#[test]
fn bench_reads_prints_idle_and_peak_memory() {
    let lines = json_lines(&["bench", "reads", "--mb", "2", "--concurrent", "4"]);
    let line = &lines[0];
    assert_eq!(line["bench"], "reads");
    assert_eq!(line["statuses"], serde_json::json!({"200": 4}), "{line}");
    let (idle, peak) = (line["idle_rss_mb"].as_f64(), line["peak_rss_mb"].as_f64());
    assert!(
        idle.unwrap() > 0.0 && peak.unwrap() >= idle.unwrap(),
        "{line}"
    );
}

/// `graybox-lab bench uploads` prints, for each JSON form and where the bytes go, a real
/// `graybox serve` process's peak memory per body byte beside what its admission reserves.
#[test]
fn bench_uploads_prints_each_form_and_store() {
    let lines = json_lines(&["bench", "uploads", "--mb", "1"]);
    let runs: Vec<(&str, &str)> = (lines.iter())
        .map(|l| (l["form"].as_str().unwrap(), l["bytes_in"].as_str().unwrap()))
        .collect();
    let want = [
        ("flat", "rows"),
        ("flat", "object store"),
        ("trajectories", "rows"),
    ];
    assert_eq!(runs[..3], want, "{lines:?}");
    assert_eq!(runs[3], ("trajectories", "object store"), "{lines:?}");
    for l in &lines {
        assert!(l["peak_per_body_byte"].as_f64().unwrap() > 0.0, "{l}");
        assert_eq!(l["reserved_per_body_byte"], 10.0, "{l}");
    }
}
