//! `graybox plan --method`: direct collocation from the command line, its initial states, and
//! what it says about a method or initial states it cannot use.

use super::{json, pendulum_model, plan_swing_up, tmp};

#[test]
fn plan_by_direct_collocation_from_the_command_line() {
    let m = pendulum_model("dircol.gbx");
    let p = tmp("dircol.json");
    let plan = |extra: &[&str]| plan_swing_up(&m, &p, extra);
    for extra in [
        vec!["--method", "dircol"],
        vec!["--method", "dircol", "--x-init", "line"],
    ] {
        let summary = json(&plan(&extra));
        assert_eq!(summary["method"], "dircol", "{summary}");
        assert_eq!(summary["converged"], true, "{summary}");
        assert!(summary["goal_error"].as_f64().unwrap() < 0.1, "{summary}");
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        assert!(
            written["constraint_violation"].as_f64().unwrap() < 1e-6,
            "{written}"
        );
        assert!(
            written["rollout_deviation"].as_f64().unwrap() >= 0.0,
            "{written}"
        );
        assert_eq!(written["u"].as_array().unwrap().len(), 30);
    }
    let summary = json(&plan(&[]));
    assert_eq!(summary["method"], "ilqr", "{summary}");

    let rows = tmp("short-x-init.json");
    std::fs::write(&rows, "[[0, 0], [1, 0]]").unwrap();
    for (extra, wanted) in [
        (vec!["--method", "shooting"], "ilqr, dircol"),
        (vec!["--method", "dircol", "--x-init", &rows], "[31, 2]"),
        (
            vec!["--method", "dircol", "--x-init", "/nonexistent.json"],
            "cannot read",
        ),
        (vec!["--x-init", "line"], "dircol"),
        (vec!["--x-min", "-inf,-1"], "x_min"),
        (
            vec!["--method", "dircol", "--x-min", "1,0", "--x-max", "2,1"],
            "outside",
        ),
    ] {
        let out = plan(&extra);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(wanted), "{extra:?}: {err}");
    }
}
