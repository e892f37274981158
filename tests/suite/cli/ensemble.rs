//! An ensemble from the command line: `train --ensemble`, `eval`'s mean loss and the members'
//! spread, and `plan --ensemble-cost`.

use super::{graybox, json, plan_swing_up, tmp};

/// A W-B pendulum ensemble of three members, trained for a few epochs on simulated data.
fn pendulum_ensemble() -> (String, String) {
    let (d, m) = (tmp("ens-data.json"), tmp("ens.gbx"));
    let sim = [
        "simulate", "--system", "pendulum", "--count", "128", "--dt", "0.05",
    ];
    json(&graybox(
        &[&sim[..], &["--seed", "4", "--out", &d]].concat(),
    ));
    json(&graybox(&[
        "train",
        "--data",
        &d,
        "--model",
        "W-B",
        "--template",
        "pendulum",
        "--epochs",
        "3",
        "--batch-size",
        "32",
        "--ensemble",
        "3",
        "--out",
        &m,
    ]));
    (d, m)
}

#[test]
fn eval_and_plan_an_ensemble() {
    let (d, m) = pendulum_ensemble();
    let e = json(&graybox(&["eval", "--model", &m, "--data", &d]));
    assert_eq!(e["members"], 3, "{e}");
    let losses: Vec<f64> = (e["member_losses"].as_array().unwrap().iter())
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(losses.len(), 3);
    let mean = losses.iter().sum::<f64>() / 3.0;
    let member_mean = e["member_loss"]["mean"].as_f64().unwrap();
    assert!((member_mean - mean).abs() <= 1e-12 * mean, "{e}");
    assert!(e["member_loss"]["std"].as_f64().unwrap() > 0.0, "{e}");
    // The mean prediction's squared error is at most the members' average (Jensen).
    assert!(e["loss"].as_f64().unwrap() <= mean, "{e}");
    assert_eq!(e["prediction_std"].as_array().unwrap().len(), 2, "{e}");

    let p = tmp("ens-plan.json");
    for cost in ["mean_dynamics", "mean"] {
        json(&plan_swing_up(&m, &p, &["--ensemble-cost", cost]));
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        assert_eq!(written["ensemble_cost"], cost);
        let std = written["x_std"].as_array().unwrap();
        assert_eq!((std.len(), std[0].as_array().unwrap().len()), (31, 2));
        assert!(std[30][0].as_f64().unwrap() > 0.0, "the members differ");
    }
    let out = plan_swing_up(&m, &p, &["--ensemble-cost", "median"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("ensemble_cost"), "{err}");
}
