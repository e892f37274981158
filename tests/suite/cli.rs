//! The `graybox` binary end to end: simulate → train → eval → inspect, and its errors.

use std::process::{Command, Output};

#[path = "cli/careless.rs"]
mod careless;
#[path = "cli/ensemble.rs"]
mod ensemble;
#[path = "cli/formula_limits.rs"]
mod formula_limits;
#[path = "cli/import.rs"]
mod import;
#[path = "cli/messages.rs"]
mod messages;
#[path = "cli/model_files.rs"]
mod model_files;
#[path = "cli/plan_methods.rs"]
mod plan_methods;

/// `graybox plan` of the pendulum's swing-up (T = 30, |u| ≤ 20) on `model`, and `extra`.
fn plan_swing_up(model: &str, out: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "plan",
        "--model",
        model,
        "--x0",
        "0,0",
        "--goal",
        "3.14159,0",
        "--horizon",
        "30",
        "--u-min",
        "-20",
        "--u-max",
        "20",
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    graybox(&args)
}

/// The built-in pendulum as a model at Δt = 0.05 s in the temporary file `name`: its path.
fn pendulum_model(name: &str) -> String {
    let m = tmp(name);
    json(&graybox(&[
        "model",
        "--template",
        "pendulum",
        "--dt",
        "0.05",
        "--out",
        &m,
    ]));
    m
}

fn graybox(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

fn tmp(name: &str) -> String {
    let dir = std::env::temp_dir().join(format!("graybox-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name).to_string_lossy().into_owned()
}

#[test]
fn simulate_train_eval_inspect() {
    let (d, v, m, r) = (tmp("d.json"), tmp("v.json"), tmp("m.gbx"), tmp("r.json"));
    json(&graybox(&[
        "simulate",
        "--system",
        "double_pendulum",
        "--count",
        "64",
        "--seed",
        "0",
        "--out",
        &d,
    ]));
    json(&graybox(&[
        "simulate",
        "--system",
        "double_pendulum",
        "--count",
        "32",
        "--seed",
        "1",
        "--out",
        &v,
    ]));
    let report = json(&graybox(&[
        "train",
        "--data",
        &d,
        "--val-data",
        &v,
        "--model",
        "W-B",
        "--template",
        "double_pendulum",
        "--init",
        "m1=12,l2=0.9",
        "--epochs",
        "3",
        "--batch-size",
        "32",
        "--out",
        &m,
        "--report",
        &r,
    ]));
    for key in [
        "model",
        "epochs",
        "train_loss",
        "val_loss",
        "best_epoch",
        "seconds",
        "samples_per_second",
        "physical_parameters",
        "identifiable",
    ] {
        assert!(report.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(report["epochs"], 3);
    assert!(report["physical_parameters"]["m1"].as_f64().unwrap() > 0.0);
    // stdout is the report without the per-epoch history; --report has it all.
    assert!(report.get("history").is_none(), "{report}");
    let full: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&r).unwrap()).unwrap();
    assert_eq!(full["history"].as_array().map(Vec::len), Some(3));
    assert_eq!(full["best_val_loss"], report["best_val_loss"]);
    let eval = json(&graybox(&["eval", "--model", &m, "--data", &v]));
    assert_eq!(eval["count"], 32);
    let best = report["best_val_loss"].as_f64().unwrap();
    let loss = eval["loss"].as_f64().unwrap();
    assert!(
        (loss - best).abs() <= 1e-6 * best,
        "eval {loss} vs best {best}"
    );
    let info = json(&graybox(&["inspect", "--model", &m]));
    assert_eq!((info["n"].as_u64(), info["m"].as_u64()), (Some(2), Some(2)));
    assert_eq!(info["template"], "double_pendulum");
    assert!(
        info["identifiable"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["name"] == "m1/m2")
    );
}

#[test]
fn bad_input_exits_2_naming_the_field() {
    let bad = tmp("bad.json");
    std::fs::write(&bad, r#"{"dt":0.01,"q":[[0,1],[2]],"qdot":[[0,0],[1,1]],"u":[[1],[2]],"q_next":[[0,1],[2,3]],"qdot_next":[[0,0],[1,1]]}"#).unwrap();
    let out = graybox(&["train", "--data", &bad, "--out", &tmp("x.gbx")]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("q[1]"));
    let out = graybox(&[
        "simulate",
        "--system",
        "triple_pendulum",
        "--out",
        &tmp("y.json"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("double_pendulum"));
    let out = graybox(&[
        "simulate",
        "--system",
        "pendulum",
        "--set",
        "mass=3",
        "--out",
        &tmp("y.json"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown parameter 'mass'"));
}

/// `graybox model` writes the true system as a model file: it loads, inspects as made (not
/// trained) with the values given, and plans; a bad template or dt exits 2 naming it.
#[test]
fn model_writes_a_white_box_model_that_plans() {
    let m = tmp("made.gbx");
    let out = json(&graybox(&[
        "model",
        "--template",
        "pendulum",
        "--set",
        "m=2",
        "--dt",
        "0.05",
        "--out",
        &m,
    ]));
    assert_eq!(out["physical_parameters"]["m"], 2.0);
    let info = json(&graybox(&["inspect", "--model", &m]));
    assert_eq!(info["made"]["physical_parameters"]["m"], 2.0);
    assert!(
        info["made"]["note"]
            .as_str()
            .unwrap()
            .contains("not trained")
    );
    assert!(info.get("training").is_none(), "{info}");
    let p = tmp("plan.json");
    let summary = json(&plan_swing_up(&m, &p, &[]));
    assert!(summary["goal_error"].as_f64().unwrap() < 0.1, "{summary}");
    let plan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    assert_eq!(plan["x"].as_array().unwrap().len(), 31);
    assert_eq!(plan["K"].as_array().unwrap().len(), 30);
    for (args, field) in [
        (
            vec!["model", "--template", "acrobot", "--dt", "0.1", "--out", &m],
            "template",
        ),
        (
            vec!["model", "--template", "pendulum", "--dt", "0", "--out", &m],
            "dt",
        ),
    ] {
        let o = graybox(&args);
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(field), "{err}");
    }
}

/// Issue 25: `plan --horizon 1000000000` aborted on allocation and `--horizon 2⁶⁴ − 1`
/// panicked ("capacity overflow"). The command applies the service's limits: a horizon over
/// --max-plan-horizon (10⁴ by default, as the service's) and restarts over 1000 exit 2
/// naming them; max_iterations 0 plans no iteration.
#[test]
fn plan_applies_the_services_limits() {
    let m = pendulum_model("limits.gbx");
    let p = tmp("limits.json");
    let plan = |extra: &[&str]| {
        let mut args = vec![
            "plan", "--model", &m, "--x0", "0,0", "--goal", "1,0", "--out", &p,
        ];
        args.extend_from_slice(extra);
        graybox(&args)
    };
    for (extra, wanted) in [
        (vec!["--horizon", "1000000000"], "--max-plan-horizon"),
        (
            vec!["--horizon", "18446744073709551615"],
            "--max-plan-horizon",
        ),
        (vec!["--horizon", "10001"], "limit of 10000"),
        (
            vec!["--horizon", "100", "--max-plan-horizon", "99"],
            "limit of 99",
        ),
        (
            vec!["--horizon", "10", "--restarts", "4294967295"],
            "restarts",
        ),
        (vec!["--horizon", "0"], "horizon"),
    ] {
        let out = plan(&extra);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {err}");
        assert!(
            err.contains(wanted) && !err.contains("panicked"),
            "{extra:?}: {err}"
        );
    }
    let summary = json(&plan(&["--horizon", "10", "--max-iterations", "0"]));
    assert_eq!(summary["iterations"], 0, "{summary}");
    assert_eq!(summary["converged"], false, "{summary}");
}

/// A formula template file works wherever a template name does: simulate from it, train W-B
/// on it from other starting values, make its white-box model, plan on it; a bad file's
/// error names the file, the field and the offset.
#[test]
fn formula_template_files_simulate_train_and_plan() {
    let doc = serde_json::json!({
        "kind": "formula", "name": "cartpole_formula", "coordinates": ["x", "theta"],
        "inputs": ["f"],
        "parameters": {"mc": {"value": 1.0, "positive": true}, "mp": {"value": 0.5, "positive": true},
                       "l": {"value": 0.6, "positive": true}, "g": {"value": 9.81, "positive": true},
                       "eta": {"value": -0.1}},
        "mass": [["mc + mp", "mp*l*cos(theta)"], ["mp*l*cos(theta)", "mp*l^2"]],
        "potential": "-mp*g*l*cos(theta)",
        "forces": ["f + eta*x_dot", "0"]
    });
    let (t, d, m, w, p) = (
        tmp("cp.json"),
        tmp("cp-d.json"),
        tmp("cp.gbx"),
        tmp("cp-true.gbx"),
        tmp("cp-plan.json"),
    );
    std::fs::write(&t, doc.to_string()).unwrap();
    let sim = json(&graybox(&[
        "simulate",
        "--template",
        &t,
        "--count",
        "128",
        "--seed",
        "3",
        "--q-range",
        "1",
        "--qdot-range",
        "1",
        "--u-std",
        "5",
        "--set",
        "l=0.5",
        "--out",
        &d,
    ]));
    assert_eq!((sim["n"].as_u64(), sim["m"].as_u64()), (Some(2), Some(1)));
    let report = json(&graybox(&[
        "train",
        "--data",
        &d,
        "--model",
        "W-B",
        "--template",
        &t,
        "--init",
        "l=0.7,mp=0.4",
        "--epochs",
        "30",
        "--batch-size",
        "32",
        "--lr",
        "0.01",
        "--out",
        &m,
    ]));
    let best = report["best_val_loss"].as_f64().unwrap();
    assert!(
        best.is_finite() && report["physical_parameters"]["l"].as_f64().is_some(),
        "{report}"
    );
    let made = json(&graybox(&[
        "model",
        "--template",
        &t,
        "--dt",
        "0.05",
        "--out",
        &w,
    ]));
    assert_eq!(made["template"], "cartpole_formula");
    json(&graybox(&[
        "plan",
        "--model",
        &w,
        "--x0",
        "0,0,0,0",
        "--goal",
        "0.5,0,0,0",
        "--horizon",
        "20",
        "--out",
        &p,
    ]));
    let plan: serde_json::Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
    assert!(plan["goal_error"].as_f64().unwrap() < 0.1, "{plan}");

    let mut bad = doc.clone();
    bad["mass"][1][1] = serde_json::json!("mp*l^2 + f");
    std::fs::write(&t, bad.to_string()).unwrap();
    let out = graybox(&["simulate", "--template", &t, "--count", "8", "--out", &d]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cp.json: mass[1][1]") && err.contains("'f' at offset 9"),
        "{err}"
    );
}

/// `inspect` names a template model's coordinates and inputs in the model's order (on a
/// branching robot it need not be Pinocchio's, so a user needs it to map rows to joints), with
/// its angles, and `train --help` names URDF among the template kinds.
#[test]
fn inspect_names_a_robots_coordinates_in_order() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let urdf = format!("{dir}/tests/fixtures/urdf/tree.urdf");
    let fixture: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(format!("{dir}/tests/fixtures/urdf/tree.json")).unwrap(),
    )
    .unwrap();
    let m = tmp("tree.gbx");
    json(&graybox(&[
        "model",
        "--template",
        &urdf,
        "--dt",
        "0.01",
        "--out",
        &m,
    ]));
    let info = json(&graybox(&["inspect", "--model", &m]));
    assert_eq!(info["coordinates"], fixture["coordinates"], "{info}");
    assert_eq!(
        info["inputs"], fixture["coordinates"],
        "one input per joint: {info}"
    );
    assert_eq!(
        info["periodic"],
        serde_json::json!([false, false, false, true])
    );
    let help = Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args(["train", "--help"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&help.stdout).contains("URDF"));
}

/// A `serve` whose port another process holds stops at once, naming the port, and leaves no
/// database file behind.
#[test]
fn serve_on_a_taken_port_creates_no_database() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let db = tmp("taken-port.db");
    let _ = std::fs::remove_file(&db);
    let out = graybox(&[
        "serve",
        "--db",
        &db,
        "--http",
        &addr,
        "--grpc",
        "127.0.0.1:0",
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&addr), "{stderr}");
    assert!(!std::path::Path::new(&db).exists(), "{db} was created");
}
