use super::*;
use crate::rng::Rng;

/// A log of `q = sin(ωt)`, `u = 2 + t`, at steps of h ± 5 %, with `pause` seconds missing after
/// t = 1 s and every 97th row's position missing.
fn log(h: f64, pause: f64) -> (String, Vec<f64>) {
    let mut rng = Rng::derive(11, 2);
    let (mut t, mut text, mut times) = (0.0f64, String::from("t,mode,q,u\n"), vec![]);
    let (mut row, mut paused) = (0, false);
    while t < 2.0 {
        let q = if row % 97 == 50 {
            String::new()
        } else {
            (3.0 * t).sin().to_string()
        };
        text += &format!("{t},run,{q},{}\n", 2.0 + t);
        times.push(t);
        t += h * (1.0 + 0.05 * (2.0 * rng.uniform() - 1.0));
        if !paused && t >= 1.0 {
            t += pause;
            paused = true;
        }
        row += 1;
    }
    (text, times)
}

fn columns() -> LogColumns {
    LogColumns {
        time: "t".into(),
        q: vec!["q".into()],
        qdot: vec![],
        qddot: vec![],
        u: vec!["u".into()],
    }
}

/// A jittered log with a pause and missing values, resampled: two trajectories, the rows
/// without a position left out and counted, the positions and estimated velocities those of
/// sin(3t) at the grid's times, each input the mean of 2 + t over its step.
#[test]
fn a_jittered_log_with_a_pause_becomes_trajectories() {
    let (text, times) = log(1e-3, 0.05);
    let opts = ImportOptions {
        resample: true,
        ..ImportOptions::default()
    };
    let (data, s) = import_log(text.as_bytes(), &columns(), &opts).unwrap();
    assert_eq!((data.steps.as_ref(), s.times.as_str()), (None, "grid"));
    assert_eq!(
        (s.rows, s.pauses, s.trajectories),
        (times.len(), 1, 2),
        "{s:?}"
    );
    assert_eq!(s.dropped_rows, (times.len() - 51) / 97 + 1, "{s:?}");
    assert_eq!(s.first_dropped_row, Some(50));
    // Steps of 1 ms ± 5 % (σ 0.03) and a 2 ms one wherever a row was left out (1 in 97).
    assert!(
        (s.median_step - 1e-3).abs() < 1e-4 && s.jitter > 0.02 && s.jitter < 0.15,
        "{s:?}"
    );
    assert_eq!((s.dt, s.velocities.as_str()), (s.median_step, "estimated"));
    // No delay, one-sided windows at the ends included: rounding of sums of 15 terms of
    // times of order one second.
    assert!(s.lag < 1e-12, "{s:?}");
    assert_eq!(
        (data.nq, data.nv, data.m, data.count()),
        (1, 1, 1, s.transitions)
    );
    let segments = data.segments();
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for seg in &segments {
        // Each trajectory starts at its first sample's time: the grid's times follow.
        let t0 = if seg.start == 0 {
            0.0
        } else {
            times.iter().copied().find(|&t| t > 1.0).unwrap()
        };
        for k in 0..seg.length {
            let (row, t) = (seg.start + k, t0 + k as f64 * data.dt);
            worst.0 = worst.0.max((data.q[row] - (3.0 * t).sin()).abs());
            worst.1 = worst.1.max((data.qdot[row] - 3.0 * (3.0 * t).cos()).abs());
            worst.2 = worst.2.max((data.u[row] - (2.0 + t + data.dt / 2.0)).abs());
        }
    }
    // A cubic fitted over 15 ms of sin(3t) errs by the neglected fourth-order term, at most
    // where the window is one-sided (a trajectory's ends): measured 1.4e-9 in value and 4.9e-7
    // in rate, bounded 10× above. The inputs are linear in t, so their mean over a step is
    // exact up to rounding.
    assert!(
        worst.0 < 1e-8 && worst.1 < 5e-6 && worst.2 < 1e-12,
        "{worst:?}"
    );
}

/// Given velocities are kept, and the fit's estimate checks them.
#[test]
fn given_velocities_are_kept_and_checked() {
    let mut text = String::from("t,q,qd,u\n");
    for k in 0..300 {
        let t = k as f64 * 0.002;
        text += &format!("{t},{},{},0\n", t * t, 2.0 * t + 0.01);
    }
    let cols = LogColumns {
        qdot: vec!["qd".into()],
        ..columns()
    };
    let (data, s) = import_log(text.as_bytes(), &cols, &ImportOptions::default()).unwrap();
    assert_eq!(
        (s.velocities.as_str(), s.acceleration_check_rms),
        ("given", None)
    );
    // The log's velocities are 0.01 off the positions' rate: the check says so.
    assert!((s.velocity_check_rms.unwrap() - 0.01).abs() < 1e-9, "{s:?}");
    assert!((data.qdot[10] - (2.0 * 10.0 * 0.002 + 0.01)).abs() < 1e-12);
}

/// An angle wrapped into (−π, π] is unwrapped: 3t grows past π without jumping back.
#[test]
fn wrapped_angles_are_unwrapped() {
    let mut text = String::from("t,q,u\n");
    for k in 0..400 {
        let t = k as f64 * 0.005;
        let wrapped = (3.0 * t).sin().atan2((3.0 * t).cos());
        text += &format!("{t},{wrapped},0\n");
    }
    let opts = ImportOptions {
        wrapped: vec!["q".into()],
        ..ImportOptions::default()
    };
    let (data, _) = import_log(text.as_bytes(), &columns(), &opts).unwrap();
    for (k, q) in data.q.iter().enumerate() {
        assert!((q - 3.0 * k as f64 * 0.005).abs() < 1e-9, "q[{k}] = {q}");
    }
    let err = import_log(
        text.as_bytes(),
        &columns(),
        &ImportOptions {
            wrapped: vec!["u".into()],
            ..ImportOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.starts_with("wrapped"), "{err}");
}

/// Each bad log is refused naming the field, the column and the row, before anything is made.
#[test]
fn bad_logs_are_refused_naming_the_column_or_row() {
    let opts = ImportOptions::default();
    let refuse = |text: &str| {
        import_log(text.as_bytes(), &columns(), &opts)
            .unwrap_err()
            .to_string()
    };
    let e = refuse("time,q,u\n0,1,2\n");
    assert!(
        e.starts_with("time: no column 't'") && e.contains("time, q, u"),
        "{e}"
    );
    let e = refuse("t,q,u\n0,0,0\n0.01,0,0\n0.005,0,0\n");
    assert!(
        e.starts_with("time:") && e.contains("row 2 has 0.005 after row 1"),
        "{e}"
    );
    let e = refuse("t,q,u\n0,0,0\n0.01,zero,0\n");
    assert!(e.starts_with("q: column 'q', row 1: 'zero'"), "{e}");
    let e = refuse("t,q,u\n0,0,\n0.01,0,nan\n");
    assert!(e.starts_with("u: column 'u' has no value"), "{e}");
    let e = refuse("t,q,u\n0,0,0\n");
    assert!(e.starts_with("log: 1 complete row(s)"), "{e}");
    let e = refuse("");
    assert!(e.starts_with("log:"), "{e}");
    let e = refuse("t,q,u\n0,0,0\n1,0\n");
    assert!(e.starts_with("log: row 1 has 2 values"), "{e}");
    let fine = ImportOptions {
        dt: Some(0.004),
        ..ImportOptions::default()
    };
    let text = "t,q,u\n0,0,0\n0.01,0,0\n0.02,0,0\n0.03,0,0\n0.04,0,0\n";
    let e = import_log(text.as_bytes(), &columns(), &fine)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("dt: 0.004 s is finer than half"), "{e}");
    // A step outside the accepted range (time in milliseconds, read as seconds: 1000 s steps).
    let e = refuse("t,q,u\n0,0,0\n1000,0,0\n2000,0,0\n3000,0,0\n4000,0,0\n");
    assert!(e.starts_with("time: the step must be in"), "{e}");
}

/// Kept on its samples' own times (the default): each transition from one kept sample to the
/// next, its Δt their distance, the states sin(3t) at the samples, each input the mean of
/// 2 + t over its step, and the dataset's Δt the median step.
#[test]
fn a_jittered_log_keeps_its_samples_times() {
    let (text, times) = log(1e-3, 0.05);
    let (data, s) = import_log(text.as_bytes(), &columns(), &ImportOptions::default()).unwrap();
    assert_eq!(
        (s.times.as_str(), s.trajectories, s.pauses),
        ("samples", 2, 1)
    );
    // The kept samples: every row but each 97th's (its position is missing).
    let kept: Vec<f64> = (times.iter().enumerate())
        .filter(|(row, _)| row % 97 != 50)
        .map(|(_, &t)| t)
        .collect();
    let steps = data.steps.as_ref().expect("jittered steps are kept");
    assert_eq!(steps.len(), kept.len() - 2, "one step fewer per trajectory");
    assert_eq!(data.dt, median(steps));
    let (mut k, mut worst) = (0, (0.0f64, 0.0f64, 0.0f64));
    for seg in data.segments() {
        let rows = seg.start..seg.start + seg.length;
        for (row, step) in rows.zip(&steps[seg.start..]) {
            let (a, b) = (kept[k], kept[k + 1]);
            assert!((step - (b - a)).abs() < 1e-15, "row {row}");
            worst.0 = worst.0.max((data.q[row] - (3.0 * a).sin()).abs());
            worst.1 = worst.1.max((data.qdot[row] - 3.0 * (3.0 * a).cos()).abs());
            worst.2 = worst.2.max((data.u[row] - (2.0 + 0.5 * (a + b))).abs());
            k += 1;
        }
        k += 1; // the pause: the next trajectory starts at the next sample
    }
    // The grid's bounds: a cubic over 15 ms of sin(3t) errs by its fourth-order term; u is
    // linear, its mean exact up to rounding.
    assert!(
        worst.0 < 1e-8 && worst.1 < 5e-6 && worst.2 < 1e-12,
        "{worst:?}"
    );
}

/// Given accelerations are checked against the fit's second derivative of the positions: a
/// log of q = t³ with q̈ = 6t off by 0.5 says 0.5 (a cubic's second derivative is exact).
#[test]
fn given_accelerations_are_checked() {
    let mut text = String::from("t,q,qdd,u\n");
    for k in 0..300 {
        let t = 0.1 + k as f64 * 0.002;
        text += &format!("{t},{},{},0\n", t * t * t, 6.0 * t + 0.5);
    }
    let cols = LogColumns {
        qddot: vec!["qdd".into()],
        ..columns()
    };
    let (_, s) = import_log(text.as_bytes(), &cols, &ImportOptions::default()).unwrap();
    // Rounding of the fit's weights over a 28 ms window, divided by its half-width squared.
    assert!(
        (s.acceleration_check_rms.unwrap() - 0.5).abs() < 1e-4,
        "{s:?}"
    );
    let line = ImportOptions {
        fit: Fit {
            window: 5,
            order: 1,
        },
        ..ImportOptions::default()
    };
    let e = import_log(text.as_bytes(), &cols, &line)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("order"), "{e}");
    let two = LogColumns {
        qddot: vec!["qdd".into(), "q".into()],
        ..columns()
    };
    let e = import_log(text.as_bytes(), &two, &ImportOptions::default()).unwrap_err();
    assert!(e.to_string().starts_with("qddot"), "{e}");
}

/// Inputs held from sample to sample (a controller's command): on the samples' own times each
/// transition's input is its first sample's; on a grid, the mean of the steps it spans. As a
/// measured signal (the default) they are joined by straight lines instead.
#[test]
fn held_inputs_are_their_samples_values() {
    let (text, _) = log(1e-3, 0.05);
    let held = ImportOptions {
        inputs: Inputs::Held,
        ..ImportOptions::default()
    };
    let (data, s) = import_log(text.as_bytes(), &columns(), &held).unwrap();
    assert_eq!(s.inputs, "held");
    // Each row's u is 2 + t: the transition from a sample holds that sample's.
    let steps = data.steps.as_ref().unwrap();
    let first = data.trajectories.as_ref().unwrap()[0];
    let mut t = 0.0;
    for (k, (u, step)) in data.u.iter().zip(steps).take(first).enumerate() {
        // t summed from the steps rounds apart from the log's own times by ~1e-16 s.
        assert!((u - (2.0 + t)).abs() < 1e-12, "transition {k}");
        t += step;
    }
    let (linear, _) = import_log(text.as_bytes(), &columns(), &ImportOptions::default()).unwrap();
    assert!((linear.u[0] - (2.0 + 0.5 * steps[0])).abs() < 1e-12);
    // On a grid of 2.5 ms from t = 0, the first step spans samples of u = 2 + t held: its mean
    // is below the line's (the held value lags the line by half a sample's step).
    let grid = ImportOptions {
        dt: Some(2.5e-3),
        ..held
    };
    let (g, _) = import_log(text.as_bytes(), &columns(), &grid).unwrap();
    assert!(g.u[0] > 2.0 && g.u[0] < 2.0 + 1.25e-3, "{}", g.u[0]);
}

/// Inputs through the positions' fit (parallel filtering): a log of q = sin(ωt) at 1 kHz with
/// jitter and u = −ω² q (a unit mass's force) balances each transition's mean acceleration
/// from a wide fit (51 samples) to the O(Δt²) of joining u's samples by lines (measured 6e-4
/// of ω² at worst), where the unfiltered input is off by what the fit takes out of q̈ (worst
/// at the ends, where the window is one-sided: measured 1.2 ω²).
#[test]
fn smoothed_inputs_balance_the_fitted_accelerations() {
    let w = 2.0 * std::f64::consts::PI * 12.0;
    let mut rng = Rng::derive(5, 3);
    let (mut t, mut text) = (0.0f64, String::from("t,q,u\n"));
    while t < 1.0 {
        text += &format!("{t},{},{}\n", (w * t).sin(), -w * w * (w * t).sin());
        t += 1e-3 * (1.0 + 0.05 * (2.0 * rng.uniform() - 1.0));
    }
    let cols = LogColumns {
        time: "t".into(),
        q: vec!["q".into()],
        ..columns()
    };
    let fit = Fit {
        window: 51,
        order: 3,
    };
    let worst = |smooth_inputs: bool| {
        let opts = ImportOptions {
            fit,
            smooth_inputs,
            ..ImportOptions::default()
        };
        let (data, s) = import_log(text.as_bytes(), &cols, &opts).unwrap();
        assert_eq!(s.smooth_inputs, smooth_inputs);
        let steps = data.steps.as_ref().unwrap();
        (0..data.count())
            .map(|i| {
                let a = (data.qdot_next[i] - data.qdot[i]) / steps[i];
                (data.u[i] - a).abs() / (w * w)
            })
            .fold(0.0, f64::max)
    };
    let (plain, smoothed) = (worst(false), worst(true));
    assert!(smoothed < 2e-3 && plain > 0.1, "{smoothed:e} vs {plain:e}");
}
