//! Issue 26: one rule for names and physical values wherever they enter (a dataset, a model
//! file's report, a template document of either kind, a job), W-B jobs with nothing to train
//! refused at submission, and plans that go non-finite refused saying where.

use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

/// Names that break the rule: too long, NUL, ESC, a right-to-left override.
fn bad_names() -> Vec<String> {
    vec![
        "x".repeat(20_000),
        "a\0b".into(),
        "a\u{1b}[2J".into(),
        "ab\u{202E}cd".into(),
    ]
}

fn assert_refused(status: u16, body: &Value, field: &str, words: &str) {
    assert_eq!(status, 422, "{body}");
    assert_eq!(body["error"]["field"], field, "{body}");
    let message = body["error"]["message"].as_str().unwrap();
    assert!(message.contains(words), "{message}");
    assert!(message.len() < 500, "{message}");
}

/// A one-coordinate formula template (θ, an input u) with these parameters.
fn formula(name: &str, parameters: Value) -> Value {
    json!({
        "kind": "formula", "name": name, "coordinates": ["th"], "inputs": ["u"],
        "parameters": parameters,
        "mass": [["1"]], "potential": "-10*cos(th)", "forces": ["u"]
    })
}

fn urdf(edit: impl FnOnce(String) -> String) -> Value {
    let path = format!(
        "{}/tests/fixtures/urdf/double_pendulum.urdf",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = edit(std::fs::read_to_string(path).unwrap());
    json!({"kind": "urdf", "urdf": text})
}

/// A model file uploaded without `?name=` took its name from the file's report whatever it
/// was; template documents' names and values bypassed the rules that `?name=` and a job's
/// `init` follow, and then failed at the first epoch.
#[tokio::test]
async fn names_and_values_follow_one_rule_wherever_they_enter() {
    let app = spawn_app(1).await;
    let model = trained(&app, "W-B").await;
    let file: Value = serde_json::from_slice(&app.model_file(&model).await).unwrap();
    let upload = |file: &Value, query: &'static str| {
        let r = app
            .client
            .post(app.url(&format!("/v1/models{query}")))
            .body(serde_json::to_vec(file).unwrap())
            .send();
        async move {
            let r = r.await.unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        }
    };
    for name in bad_names() {
        let mut f = file.clone();
        f["report"]["model"] = json!(name);
        let (status, body) = upload(&f, "").await;
        assert_refused(status, &body, "report.model", "");
        // The file is fine once it is given a name of its own.
        let (status, body) = upload(&f, "?name=renamed").await;
        assert!(status == 201 || status == 200, "{body}");
        assert_eq!(body["name"], "renamed");

        let (status, body) = app.post("/v1/templates", &formula(&name, json!({}))).await;
        assert_refused(status, &body, "name", "");
    }
    // XML has no NUL or ESC: a URDF's names can break the rule only by length or direction.
    for name in ["x".repeat(20_000), "ab\u{202E}cd".into()] {
        let renamed = urdf(|t| t.replace("\"rod1\"", &format!("\"{name}\"")));
        let (status, body) = app.post("/v1/templates", &renamed).await;
        assert_refused(status, &body, "urdf", "link");
    }

    let ds = app.upload(&dataset(16, 2)).await;
    let job = |template: Value| json!({"dataset_id": ds, "model": "W-B", "template": template});
    for (value, positive, words) in [
        (1e7, false, "≤ 1e6"),
        (1e300, true, "≤ 1e6"),
        (1e-320, true, "at least 1e-6"),
    ] {
        let t = formula("f", json!({"k": {"value": value, "positive": positive}}));
        let (status, body) = app.post("/v1/templates", &t).await;
        assert_refused(status, &body, "parameters.k.value", words);
        let (status, body) = app.post("/v1/jobs", &job(t)).await;
        assert_refused(status, &body, "template.parameters.k.value", words);
    }
    let heavy = urdf(|t| t.replacen("<mass value=\"10\"/>", "<mass value=\"1e308\"/>", 1));
    let (status, body) = app.post("/v1/jobs", &job(heavy)).await;
    assert_refused(status, &body, "template.urdf", "link 'rod1'");
    let damped = urdf(|t| t.replacen("damping=\"0.5\"", "damping=\"1e7\"", 1));
    let (status, body) = app.post("/v1/jobs", &job(damped)).await;
    assert_refused(status, &body, "template.urdf", "joint 'q1'");
    // Damping and friction are ≥ 0 (issue 28): in the file, in `init`, and said in the
    // template's parameters.
    let giving = urdf(|t| t.replacen("damping=\"0.5\"", "damping=\"-0.5\"", 1));
    let (status, body) = app.post("/v1/jobs", &job(giving)).await;
    assert_refused(status, &body, "template.urdf", "joint 'q1'");
    let mut negative = job(urdf(|t| t));
    negative["init"] = json!({"q2.friction": -0.1});
    let (status, body) = app.post("/v1/jobs", &negative).await;
    assert_refused(status, &body, "init.q2.friction", "≥ 0");
    let (status, body) = app.post("/v1/templates", &urdf(|t| t)).await;
    assert_eq!(status, 201, "{body}");
    let bounds: Vec<(&str, &Value)> = body["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["name"].as_str().unwrap(), &p["min"]))
        .collect();
    for (name, min) in bounds {
        let bounded = name.ends_with(".damping") || name.ends_with(".friction");
        assert_eq!(
            *min,
            if bounded { json!(0.0) } else { Value::Null },
            "{name}"
        );
    }
    app.stop().await;
}

/// A W-B job on a template with nothing to train was queued and failed with a panic's
/// message ("Tensor::backward requires a tracked autodiff tensor").
#[tokio::test]
async fn white_box_jobs_with_nothing_to_train_are_refused_at_submission() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(16, 2)).await;
    let two = |parameters: Value, force: &str| {
        json!({
            "kind": "formula", "name": "still", "coordinates": ["a", "b"], "inputs": ["u", "v"],
            "parameters": parameters,
            "mass": [["1", "0"], ["0", "1"]], "potential": "0", "forces": [force, "v"]
        })
    };
    // No parameter, one no part uses, one F uses but that is fixed (known, not trained).
    for (parameters, force) in [
        (json!({}), "u"),
        (json!({"k": {"value": 1.0}}), "u"),
        (json!({"k": {"value": 1.0, "fixed": true}}), "k*u"),
    ] {
        let template = two(parameters, force);
        let body = json!({"dataset_id": ds, "model": "W-B", "template": template.clone()});
        let (status, v) = app.post("/v1/jobs", &body).await;
        assert_refused(status, &v, "template", "no trainable parameter");
        // A network has something to train.
        let body = json!({"dataset_id": ds, "model": "MVF", "template": template});
        let (status, v) = app.post("/v1/jobs", &body).await;
        assert_eq!(status, 201, "{v}");
    }
    app.stop().await;
}

/// A Plan from x0 = (1e300, 0, 0, 0) returned OK with cost = inf, and a plan whose states went
/// non-finite blamed R ("R + BᵀSB lost positive definiteness").
#[tokio::test]
async fn plans_that_go_non_finite_are_refused_saying_where() {
    let app = spawn_app(1).await;
    let model = trained(&app, "W-B").await;
    let mut c = client(&app).await;
    let eye = |n: usize, s: f64| {
        let mut d = vec![0.0; n * n];
        (0..n).for_each(|i| d[i * n + i] = s);
        arr(&[n as u64, n as u64], d)
    };
    let plan = |x0: Vec<f64>| graybox::api::grpc::pb::PlanRequest {
        id: String::new(),
        model_id: model.clone(),
        x0,
        goal: vec![std::f64::consts::PI, 0.0, 0.0, 0.0],
        horizon: 20,
        q: eye(4, 1.0),
        r: eye(2, 1e-4),
        qf: eye(4, 1000.0),
        u_min: vec![],
        u_max: vec![],
        u_init: None,
        max_iterations: Some(5),
        tolerance: None,
        restarts: 0,
        seed: 0,
        time_limit_ms: 0,
        ..Default::default()
    };
    let status = c.plan(plan(vec![1e300, 0.0, 0.0, 0.0])).await.unwrap_err();
    assert_eq!(status.code(), Code::InvalidArgument, "{status:?}");
    assert!(status.message().starts_with("x0:"), "{}", status.message());
    assert!(status.message().contains("cost"), "{}", status.message());

    let status = c.plan(plan(vec![0.0, 0.0, 1e200, 0.0])).await.unwrap_err();
    assert_eq!(status.code(), Code::InvalidArgument, "{status:?}");
    let message = status.message();
    assert!(
        message.starts_with("x0:") && message.contains("step"),
        "{message}"
    );
    assert!(!message.contains("R + B"), "{message}");

    let ok = c.plan(plan(vec![0.0; 4])).await.unwrap().into_inner();
    assert!(ok.cost.is_finite());
    app.stop().await;
}
