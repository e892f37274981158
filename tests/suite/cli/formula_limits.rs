//! The CLI reads templates as the service does: a nested template file is a clear error
//! (exit 2) in every command that reads one, and a long one (a 3000-term potential, which
//! used to overflow the main thread's stack) simulates, trains, evaluates and plans.

use super::{graybox, json, tmp};

fn pendulum(potential: &str) -> serde_json::Value {
    serde_json::json!({
        "kind": "formula", "name": "long", "coordinates": ["theta"], "inputs": ["u"],
        "parameters": {"m": {"value": 1.0, "positive": true}, "l": {"value": 1.0, "positive": true},
                       "g": {"value": 9.81, "positive": true}, "b": {"value": 0.1}},
        "mass": [["m*l^2"]], "potential": potential, "forces": ["u - b*theta_dot"],
    })
}

/// Slow, the slowest of the suite (tens of seconds): every command evaluates the
/// 3000-term potential, `train` through Burn's autodiff (an op per term per step) and `plan`
/// through dual numbers; shorter, it would not show that nothing recurses per term.
#[test]
fn nested_template_files_are_refused_and_long_ones_work_in_every_command() {
    let (deep, long, d, m, w, p) = (
        tmp("deep.json"),
        tmp("long.json"),
        tmp("long-d.json"),
        tmp("long.gbx"),
        tmp("long-true.gbx"),
        tmp("long-plan.json"),
    );
    let nested = format!("{}theta{}", "(".repeat(3000), ")".repeat(3000));
    std::fs::write(&deep, pendulum(&nested).to_string()).unwrap();
    for args in [
        vec!["model", "--template", &deep, "--dt", "0.05", "--out", &w],
        vec!["simulate", "--template", &deep, "--count", "8", "--out", &d],
    ] {
        let out = graybox(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("potential") && err.contains("levels"), "{err}");
    }

    let part = format!("{}*m*g*l*cos(theta)", 1.0 / 3000.0);
    std::fs::write(
        &long,
        pendulum(&vec![format!("-{part}"); 3000].join(" ")).to_string(),
    )
    .unwrap();
    json(&graybox(&[
        "simulate",
        "--template",
        &long,
        "--count",
        "64",
        "--seed",
        "2",
        "--out",
        &d,
    ]));
    json(&graybox(&[
        "train",
        "--data",
        &d,
        "--model",
        "W-B",
        "--template",
        &long,
        "--epochs",
        "2",
        "--batch-size",
        "32",
        "--out",
        &m,
    ]));
    let eval = json(&graybox(&["eval", "--model", &m, "--data", &d]));
    assert!(eval["loss"].as_f64().unwrap().is_finite(), "{eval}");
    json(&graybox(&[
        "model",
        "--template",
        &long,
        "--dt",
        "0.05",
        "--out",
        &w,
    ]));
    json(&graybox(&[
        "plan",
        "--model",
        &w,
        "--x0",
        "0,0",
        "--goal",
        "0.5,0",
        "--horizon",
        "20",
        "--out",
        &p,
    ]));
    let plan: serde_json::Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
    assert!(plan["cost"].as_f64().unwrap().is_finite(), "{plan}");
}
