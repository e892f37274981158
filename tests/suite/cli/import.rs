//! `graybox import` end to end: a pendulum's motion recorded as a robot logs it (positions
//! only, at jittered times, a pause, rows with a missing value, a text column) imports as
//! trajectories, on an even grid or on its samples' own times, that the true system's
//! white-box model predicts.

use super::{graybox, json, tmp};

/// The log: every `stride ± 1` states of a trajectory simulated at 1 ms (so the times are
/// jittered by up to 20 %), 0.2 s of samples left out after t = 1 s, every 41st position
/// empty, and a column of text.
fn log_of(fine: &serde_json::Value, stride: usize) -> (String, usize) {
    let traj = &fine["trajectories"][0];
    let (q, u) = (traj["q"].as_array().unwrap(), traj["u"].as_array().unwrap());
    let mut text = String::from("time,mode,theta,tau\n");
    let (mut k, mut rows) = (0, 0);
    while k < u.len() {
        let t = k as f64 * 1e-3;
        if !(1.0..1.2).contains(&t) {
            let theta = match rows % 41 {
                20 => String::new(),
                _ => q[k][0].to_string(),
            };
            text += &format!("{t},run,{theta},{}\n", u[k][0]);
            rows += 1;
        }
        // Steps of stride − 1, stride, stride + 1 in turn.
        k += stride - 1 + rows % 3;
    }
    (text, rows)
}

#[test]
fn a_jittered_log_of_positions_imports_as_the_systems_trajectories() {
    let (fine, log, data, model) = (
        tmp("fine.json"),
        tmp("log.csv"),
        tmp("imported.json"),
        tmp("true.gbx"),
    );
    // Inputs held for 0.5 s: the import's mean over a step blurs only the steps that span a
    // change.
    json(&graybox(&[
        "simulate",
        "--template",
        "pendulum",
        "--trajectories",
        "1",
        "--steps",
        "3000",
        "--dt",
        "0.001",
        "--hold",
        "500",
        "--substeps",
        "10",
        "--u-std",
        "3",
        "--q-range",
        "1",
        "--qdot-range",
        "1",
        "--seed",
        "4",
        "--out",
        &fine,
    ]));
    let fine: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&fine).unwrap()).unwrap();
    let (text, rows) = log_of(&fine, 5);
    std::fs::write(&log, text).unwrap();
    let out = json(&graybox(&[
        "import", &log, "--time", "time", "--q", "theta", "--u", "tau", "--dt", "0.005", "--out",
        &data,
    ]));
    let s = &out["import"];
    assert_eq!(
        (out["nq"].as_u64(), out["m"].as_u64()),
        (Some(1), Some(1)),
        "{out}"
    );
    assert_eq!(s["rows"].as_u64(), Some(rows as u64), "{s}");
    assert_eq!(
        s["dropped_rows"].as_u64(),
        Some((rows as u64 + 20) / 41),
        "{s}"
    );
    assert_eq!(
        (s["pauses"].as_u64(), s["trajectories"].as_u64()),
        (Some(1), Some(2)),
        "{s}"
    );
    assert_eq!(s["velocities"], "estimated");
    let jitter = s["jitter"].as_f64().unwrap();
    // Steps of 4, 5 and 6 ms (σ 0.8 ms) and a 10 ms one wherever a row was left out.
    assert!(jitter > 0.1 && jitter < 0.3, "{s}");

    // The true system's model predicts the imported transitions: the loss (q error² + λ q̇
    // error², λ = 1) is what the fit's velocity error and the few steps across an input's
    // change leave, far below the motion's own scale (q̇ of order 1 rad/s): measured 1.4e-5.
    json(&graybox(&[
        "model",
        "--template",
        "pendulum",
        "--dt",
        "0.005",
        "--out",
        &model,
    ]));
    let eval = json(&graybox(&["eval", "--model", &model, "--data", &data]));
    let loss = eval["loss"].as_f64().unwrap();
    assert!(loss < 1e-4, "{eval}");

    // On its samples' own times (no --dt): each transition its own 4–6 ms, which the true
    // model steps (`eval` integrates each over its Δt), with the same small loss. Stepped at
    // the median 5 ms instead, the same transitions miss by their 20 % jitter: measured 1.2e-5
    // against 8.0e-5 (the fit's velocity error and the inputs' blur are the floor of both).
    let out = json(&graybox(&[
        "import", &log, "--time", "time", "--q", "theta", "--u", "tau", "--out", &data,
    ]));
    assert_eq!(out["import"]["times"], "samples", "{out}");
    let kept = json(&graybox(&["eval", "--model", &model, "--data", &data]));
    assert!(kept["loss"].as_f64().unwrap() < 1e-4, "{kept}");
    let mut uniform: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&data).unwrap()).unwrap();
    for t in uniform["trajectories"].as_array_mut().unwrap() {
        t.as_object_mut().unwrap().remove("t");
    }
    uniform["dt"] = 0.005.into();
    std::fs::write(&data, uniform.to_string()).unwrap();
    let wrong = json(&graybox(&["eval", "--model", &model, "--data", &data]));
    assert!(
        wrong["loss"].as_f64().unwrap() > 4.0 * kept["loss"].as_f64().unwrap(),
        "{wrong} vs {kept}"
    );

    // A log whose time runs backwards is refused naming the column and the rows.
    std::fs::write(&log, "time,theta,tau\n0,0,0\n0.01,0,0\n0.005,0,0\n").unwrap();
    let bad = graybox(&[
        "import", &log, "--time", "time", "--q", "theta", "--u", "tau", "--out", &data,
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{err}");
    assert!(
        err.contains("time: time must increase") && err.contains("row 2"),
        "{err}"
    );
}
