//! A careless caller of the command line (issue 72): output piped into a reader that stops
//! early, figures that do not fit in JSON, a weight written with a minus sign.

use std::process::{Command, Stdio};

use super::{graybox, pendulum_model, tmp};

/// A dataset file of the pendulum (n = m = 1) with these velocities.
fn pendulum_data(name: &str, qdot: &[f64]) -> String {
    let rows = |v: f64| qdot.iter().map(|_| vec![v]).collect::<Vec<_>>();
    let qd: Vec<Vec<f64>> = qdot.iter().map(|v| vec![*v]).collect();
    let doc = serde_json::json!({
        "dt": 0.05, "q": rows(0.1), "qdot": qd, "u": rows(0.0),
        "q_next": rows(0.1), "qdot_next": qd,
    });
    let path = tmp(name);
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

/// `graybox … | head`: the reader has closed its end before the command writes a line. The
/// command stops quietly with 0 (it panicked with a backtrace and exit 101).
#[test]
fn a_reader_that_stops_early_ends_the_command_quietly() {
    let model = pendulum_model("careless-pipe.gbx");
    let data = pendulum_data("careless-pipe.json", &vec![0.5; 2000]);
    let commands: [&[&str]; 2] = [
        &["energy", "--model", &model, "--data", &data],
        &[
            "simulate",
            "--system",
            "pendulum",
            "--count",
            "10",
            "--out",
            &tmp("careless-sim.json"),
        ],
    ];
    for args in commands {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(env!("CARGO_BIN_EXE_graybox"))
            .args(args)
            .stdout(Stdio::from(writer))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// Energies that overflow f64 are refused naming the data's row, as the service refuses
/// them: the command printed `null` and exited 0.
#[test]
fn energies_that_are_not_finite_are_refused() {
    let model = pendulum_model("careless-energy.gbx");
    let data = pendulum_data("careless-energy.json", &[0.5, 1e200]);
    let out = graybox(&["energy", "--model", &model, "--data", &data]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("data") && stderr.contains("row 1") && stderr.contains("not finite"),
        "{stderr}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("null"));
}

/// A negative weight reaches the check that explains it instead of being taken for a flag.
#[test]
fn a_negative_weight_is_explained_not_taken_for_a_flag() {
    let model = pendulum_model("careless-weight.gbx");
    for (flag, field, what) in [
        ("--r-diag", "R", "positive definite"),
        ("--q-diag", "Q", "positive semidefinite"),
        ("--qf-diag", "Qf", "positive semidefinite"),
    ] {
        let value = if flag == "--r-diag" { "-1" } else { "-1,1" };
        let out = super::plan_swing_up(&model, &tmp("careless-plan.json"), &[flag, value]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {stderr}");
        assert!(
            stderr.contains(field) && stderr.contains(what),
            "{flag}: {stderr}"
        );
    }
}
