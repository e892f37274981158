//! The bad-input table: every case is a 4xx with `{"error": {"code", "message", "field"?}}`,
//! and the service keeps answering.

use graybox::app::Settings;
use serde_json::{Value, json};

use crate::helpers::*;

struct Case {
    what: &'static str,
    method: &'static str,
    path: String,
    body: Option<Value>,
    raw: Option<(&'static str, String)>,
    headers: Vec<(&'static str, &'static str)>,
    status: u16,
    code: &'static str,
    field: Option<&'static str>,
}

fn case(
    what: &'static str,
    method: &'static str,
    path: impl Into<String>,
    body: Option<Value>,
    status: u16,
    code: &'static str,
    field: Option<&'static str>,
) -> Case {
    Case {
        what,
        method,
        path: path.into(),
        body,
        raw: None,
        headers: vec![],
        status,
        code,
        field,
    }
}

async fn run(app: &TestApp, c: &Case) {
    let mut req = match c.method {
        "POST" => app.client.post(app.url(&c.path)),
        "DELETE" => app.client.delete(app.url(&c.path)),
        _ => app.client.get(app.url(&c.path)),
    };
    for (k, v) in &c.headers {
        req = req.header(*k, *v);
    }
    if let Some(b) = &c.body {
        req = req.json(b);
    }
    if let Some((ct, text)) = &c.raw {
        req = req.header("content-type", *ct).body(text.clone());
    }
    let r = req.send().await.unwrap();
    let status = r.status().as_u16();
    let body: Value = r.json().await.unwrap_or(Value::Null);
    assert_eq!(status, c.status, "{}: {body}", c.what);
    assert!((400..500).contains(&status), "{}", c.what);
    assert_eq!(body["error"]["code"], c.code, "{}: {body}", c.what);
    assert!(
        body["error"]["message"]
            .as_str()
            .is_some_and(|m| !m.is_empty()),
        "{}: {body}",
        c.what
    );
    if let Some(f) = c.field {
        assert_eq!(body["error"]["field"], f, "{}: {body}", c.what);
    }
}

#[tokio::test]
async fn bad_input_table() {
    let app = spawn_app(0).await;
    let good = dataset(8, 1);
    let ds = app.upload(&good).await;
    let cp = app.upload(&json!({"dt": 0.01, "q": [[0.0]], "qdot": [[0.0]], "u": [[1.0]], "q_next": [[0.0]], "qdot_next": [[0.1]]})).await;
    // A white-box model (nothing to train) for the inference cases.
    let t = graybox::physics::templates::Template::DoublePendulum;
    let file = graybox::model::file::ModelFile::from_template(
        &t,
        &t.defaults(),
        0.01,
        graybox::physics::integrator::Integrator::Rk4,
    )
    .unwrap();
    let r = (app.client.post(app.url("/v1/models")))
        .body(file.to_bytes().unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let mid = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let with = |f: &dyn Fn(&mut Value)| {
        let mut v = good.clone();
        f(&mut v);
        Some(v)
    };
    let job = |f: &dyn Fn(&mut Value)| {
        let mut v = job_body(&ds, "MVF", 2);
        f(&mut v);
        Some(v)
    };
    let mut cases = vec![
        Case {
            raw: Some(("application/json", "{\"dt\": 0.01, \"q\": [[".into())),
            ..case(
                "malformed JSON",
                "POST",
                "/v1/datasets",
                None,
                400,
                "invalid_argument",
                Some("body"),
            )
        },
        case(
            "dataset not an object",
            "POST",
            "/v1/datasets",
            Some(json!([1, 2])),
            400,
            "invalid_argument",
            Some("body"),
        ),
        case(
            "missing dt",
            "POST",
            "/v1/datasets",
            with(&|v| {
                v.as_object_mut().unwrap().remove("dt");
            }),
            400,
            "invalid_argument",
            Some("dt"),
        ),
        case(
            "negative dt",
            "POST",
            "/v1/datasets",
            with(&|v| v["dt"] = json!(-0.01)),
            400,
            "invalid_argument",
            Some("dt"),
        ),
        case(
            "dt wrong type",
            "POST",
            "/v1/datasets",
            with(&|v| v["dt"] = json!("fast")),
            400,
            "invalid_argument",
            Some("dt"),
        ),
        case(
            "ragged rows",
            "POST",
            "/v1/datasets",
            with(&|v| v["q"][1] = json!([0.5])),
            400,
            "invalid_argument",
            Some("q[1]"),
        ),
        case(
            "string in array",
            "POST",
            "/v1/datasets",
            with(&|v| v["u"][2] = json!(["x", 1])),
            400,
            "invalid_argument",
            Some("u[2]"),
        ),
        case(
            // qdot may be narrower than q (nv < nq), but qdot_next has qdot's width.
            "qdot and qdot_next of different widths",
            "POST",
            "/v1/datasets",
            with(&|v| {
                for r in v["qdot"].as_array_mut().unwrap() {
                    r.as_array_mut().unwrap().pop();
                }
            }),
            400,
            "invalid_argument",
            Some("qdot_next"),
        ),
        case(
            "row count mismatch",
            "POST",
            "/v1/datasets",
            with(&|v| {
                v["u"].as_array_mut().unwrap().pop();
            }),
            400,
            "invalid_argument",
            Some("u"),
        ),
        case(
            "empty dataset",
            "POST",
            "/v1/datasets",
            Some(json!({"dt": 0.01, "q": [], "qdot": [], "u": [], "q_next": [], "qdot_next": []})),
            400,
            "invalid_argument",
            Some("q"),
        ),
        Case {
            raw: Some((
                "text/csv",
                "q0,qdot0,u0,q_next0,qdot_next0\n1,2,3,4,5\n".into(),
            )),
            ..case(
                "CSV without dt",
                "POST",
                "/v1/datasets",
                None,
                400,
                "invalid_argument",
                Some("dt"),
            )
        },
        Case {
            raw: Some(("text/csv", "a,b\n1,2\n".into())),
            ..case(
                "CSV bad header",
                "POST",
                "/v1/datasets?dt=0.01",
                None,
                400,
                "invalid_argument",
                Some("csv.header"),
            )
        },
        Case {
            raw: Some((
                "text/csv",
                "q0,qdot0,u0,q_next0,qdot_next0\n1,2,3,NaN,5\n".into(),
            )),
            ..case(
                "CSV NaN",
                "POST",
                "/v1/datasets?dt=0.01",
                None,
                400,
                "invalid_argument",
                Some("q_next[0]"),
            )
        },
        case(
            "trajectory lengths",
            "POST",
            "/v1/datasets",
            Some(
                json!({"dt": 0.01, "trajectories": [{"q": [[0.0]], "qdot": [[0.0]], "u": [[1.0]]}]}),
            ),
            400,
            "invalid_argument",
            Some("trajectories[0]"),
        ),
        Case {
            raw: Some(("application/json", "{\"model\": ".into())),
            ..case(
                "job malformed JSON",
                "POST",
                "/v1/jobs",
                None,
                400,
                "invalid_argument",
                Some("body"),
            )
        },
        case(
            "job missing dataset_id",
            "POST",
            "/v1/jobs",
            Some(json!({"model": "MVF"})),
            422,
            "unprocessable",
            Some("dataset_id"),
        ),
        case(
            "epochs wrong type",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["epochs"] = json!("ten")),
            422,
            "unprocessable",
            Some("training.epochs"),
        ),
        case(
            "negative epochs",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["epochs"] = json!(-5)),
            422,
            "unprocessable",
            Some("training.epochs"),
        ),
        case(
            "zero epochs",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["epochs"] = json!(0)),
            422,
            "unprocessable",
            Some("training.epochs"),
        ),
        case(
            "zero batch size",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["batch_size"] = json!(0)),
            422,
            "unprocessable",
            Some("training.batch_size"),
        ),
        case(
            "zero learning rate",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["lr"] = json!(0.0)),
            422,
            "unprocessable",
            Some("training.lr"),
        ),
        case(
            "val_fraction out of range",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["val_fraction"] = json!(1.5)),
            422,
            "unprocessable",
            Some("training.val_fraction"),
        ),
        case(
            "evaluate: no horizons",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": ds, "horizons": []})),
            400,
            "invalid_argument",
            Some("horizons"),
        ),
        case(
            "evaluate: horizon 0",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": ds, "horizons": [0, 10]})),
            400,
            "invalid_argument",
            Some("horizons"),
        ),
        case(
            "evaluate: horizons missing",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": ds})),
            422,
            "unprocessable",
            Some("horizons"),
        ),
        case(
            "evaluate: unknown dataset",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": "ds_missing", "horizons": [1]})),
            404,
            "not_found",
            None,
        ),
        case(
            "evaluate: unknown model",
            "POST",
            "/v1/models/mdl_missing/evaluate",
            Some(json!({"dataset_id": ds, "horizons": [1]})),
            404,
            "not_found",
            None,
        ),
        case(
            "evaluate: timeout out of range",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": ds, "horizons": [1], "timeout_seconds": 0})),
            400,
            "invalid_argument",
            Some("timeout_seconds"),
        ),
        case(
            "evaluate: horizon over --max-rollout-steps",
            "POST",
            format!("/v1/models/{mid}/evaluate"),
            Some(json!({"dataset_id": ds, "horizons": [1, 100_001]})),
            400,
            "invalid_argument",
            Some("horizons"),
        ),
        case(
            "empty job name",
            "POST",
            "/v1/jobs",
            job(&|v| v["name"] = json!("   ")),
            422,
            "unprocessable",
            Some("name"),
        ),
        case(
            "job name with a line break",
            "POST",
            "/v1/jobs",
            job(&|v| v["name"] = json!("run\n2")),
            422,
            "unprocessable",
            Some("name"),
        ),
        case(
            "zero horizon",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["horizon"] = json!(0)),
            422,
            "unprocessable",
            Some("training.horizon"),
        ),
        case(
            "an ensemble of no members",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["ensemble"] = json!(0)),
            422,
            "unprocessable",
            Some("training.ensemble"),
        ),
        case(
            "an ensemble over 32 members",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["ensemble"] = json!(33)),
            422,
            "unprocessable",
            Some("training.ensemble"),
        ),
        case(
            "discount over 1",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["discount"] = json!(1.5)),
            422,
            "unprocessable",
            Some("training.discount"),
        ),
        case(
            "a torque loss for a naive model",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!("naive");
                v["training"]["loss"] = json!("torque");
            }),
            422,
            "unprocessable",
            Some("training.loss"),
        ),
        case(
            "loss weights both zero",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["loss"] = json!({"step": 0, "torque": 0})),
            422,
            "unprocessable",
            Some("training.loss"),
        ),
        case(
            "an unknown loss",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["loss"] = json!("energy")),
            422,
            "unprocessable",
            Some("training.loss"),
        ),
        case(
            "one-step epochs not fewer than epochs",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["training"]["horizon"] = json!(2);
                v["training"]["one_step_epochs"] = v["training"]["epochs"].clone();
            }),
            422,
            "unprocessable",
            Some("training.one_step_epochs"),
        ),
        // The table's dataset is independent samples: chains of one transition.
        case(
            "horizon longer than any trajectory",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["horizon"] = json!(5)),
            422,
            "unprocessable",
            Some("training.horizon"),
        ),
        case(
            "unknown training field",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["epochz"] = json!(3)),
            422,
            "unprocessable",
            Some("training.epochz"),
        ),
        case(
            "unknown model",
            "POST",
            "/v1/jobs",
            job(&|v| v["model"] = json!("XYZ")),
            422,
            "unprocessable",
            Some("model"),
        ),
        case(
            "white-box without template",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!("W-B");
                v.as_object_mut().unwrap().remove("template");
            }),
            422,
            "unprocessable",
            Some("template"),
        ),
        case(
            "spec part without template",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!({"kind": "structured", "mass": {"type": "template"}, "potential": {"type": "zero"}, "forces": {"type": "mlp"}});
                v.as_object_mut().unwrap().remove("template");
            }),
            422,
            "unprocessable",
            Some("template"),
        ),
        case(
            "unknown template",
            "POST",
            "/v1/jobs",
            job(&|v| v["template"] = json!("triple_pendulum")),
            422,
            "unprocessable",
            Some("template"),
        ),
        case(
            "template dims mismatch",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!("W-B");
                v["template"] = json!("cartpole");
            }),
            422,
            "unprocessable",
            Some("template"),
        ),
        case(
            "unknown init parameter",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!("W-B");
                v["init"] = json!({"mass": 3.0});
            }),
            422,
            "unprocessable",
            Some("init.mass"),
        ),
        case(
            "negative positive parameter",
            "POST",
            "/v1/jobs",
            job(&|v| {
                v["model"] = json!("W-B");
                v["init"] = json!({"m1": -1.0});
            }),
            422,
            "unprocessable",
            Some("init.m1"),
        ),
        case(
            "unknown dataset",
            "POST",
            "/v1/jobs",
            job(&|v| v["dataset_id"] = json!("ds_nope")),
            422,
            "unprocessable",
            Some("dataset_id"),
        ),
        case(
            "validation dims mismatch",
            "POST",
            "/v1/jobs",
            job(&|v| v["validation_dataset_id"] = json!(cp.clone())),
            422,
            "unprocessable",
            Some("validation_dataset_id"),
        ),
        case(
            "bad page token",
            "GET",
            "/v1/jobs?page_token=garbage",
            None,
            400,
            "invalid_argument",
            Some("page_token"),
        ),
        case(
            "zero page size",
            "GET",
            "/v1/jobs?page_size=0",
            None,
            400,
            "invalid_argument",
            Some("page_size"),
        ),
        case(
            "non-numeric page size",
            "GET",
            "/v1/datasets?page_size=ten",
            None,
            400,
            "invalid_argument",
            Some("page_size"),
        ),
        case(
            "unknown state filter",
            "GET",
            "/v1/jobs?state=sleeping",
            None,
            400,
            "invalid_argument",
            Some("state"),
        ),
        case(
            "unknown job",
            "GET",
            "/v1/jobs/job_nope",
            None,
            404,
            "not_found",
            None,
        ),
        case(
            "unknown model",
            "GET",
            "/v1/models/mdl_nope",
            None,
            404,
            "not_found",
            None,
        ),
        case(
            "trajectories of an unknown dataset",
            "GET",
            "/v1/datasets/ds_nope/trajectories",
            None,
            404,
            "not_found",
            None,
        ),
        case(
            "replay without a dataset",
            "GET",
            "/v1/models/mdl_nope/rollout?index=0",
            None,
            400,
            "invalid_argument",
            Some("dataset_id"),
        ),
        case(
            "URDF of an unknown model",
            "GET",
            "/v1/models/mdl_nope/urdf",
            None,
            404,
            "not_found",
            None,
        ),
        Case {
            raw: Some(("application/xml", "<robot name='x'><link name='a'>".into())),
            ..case(
                "malformed URDF template",
                "POST",
                "/v1/templates",
                None,
                422,
                "unprocessable",
                Some("urdf"),
            )
        },
        case(
            "cancel unknown job",
            "POST",
            "/v1/jobs/job_nope/cancel",
            None,
            404,
            "not_found",
            None,
        ),
        case(
            "delete unknown dataset",
            "DELETE",
            "/v1/datasets/ds_nope",
            None,
            404,
            "not_found",
            None,
        ),
        case(
            "unknown route",
            "GET",
            "/v2/everything",
            None,
            404,
            "not_found",
            None,
        ),
    ];
    // Idempotency-Key reuse with another body.
    app.client
        .post(app.url("/v1/jobs"))
        .header("Idempotency-Key", "reuse")
        .json(&job_body(&ds, "MVF", 2))
        .send()
        .await
        .unwrap();
    cases.push(Case {
        headers: vec![("Idempotency-Key", "reuse")],
        ..case(
            "idempotency key reused",
            "POST",
            "/v1/jobs",
            job(&|v| v["training"]["epochs"] = json!(3)),
            422,
            "unprocessable",
            Some("Idempotency-Key"),
        )
    });
    assert!(cases.len() >= 25);
    for c in &cases {
        run(&app, c).await;
    }
    assert_eq!(
        app.get("/healthz").await.0,
        200,
        "the service still answers"
    );
    app.stop().await;
}

#[tokio::test]
async fn body_limit_and_auth() {
    let app = spawn_configured(Settings {
        api_token: Some("s3cret".into()),
        max_body_mb: 1,
        ..test_settings()
    })
    .await;
    // Over the 1 MiB limit: 8000 transitions are ~1.7 MB of JSON.
    let big = dataset(8000, 2);
    assert!(big.to_string().len() > 1 << 20);
    let authed = [("Authorization", "Bearer s3cret")];
    let cases = vec![
        Case {
            headers: authed.to_vec(),
            ..case(
                "oversized body",
                "POST",
                "/v1/datasets",
                Some(big),
                413,
                "payload_too_large",
                None,
            )
        },
        case(
            "missing token",
            "POST",
            "/v1/datasets",
            Some(dataset(2, 3)),
            401,
            "unauthorized",
            None,
        ),
        Case {
            headers: vec![("Authorization", "Bearer wrong")],
            ..case(
                "wrong token",
                "POST",
                "/v1/jobs",
                Some(json!({})),
                401,
                "unauthorized",
                None,
            )
        },
        case(
            "delete without token",
            "DELETE",
            "/v1/models/mdl_x",
            None,
            401,
            "unauthorized",
            None,
        ),
    ];
    for c in &cases {
        run(&app, c).await;
    }
    // Reads stay open; writes with the token work.
    assert_eq!(app.get("/v1/jobs").await.0, 200);
    let r = app
        .client
        .post(app.url("/v1/datasets"))
        .header("Authorization", "Bearer s3cret")
        .json(&dataset(2, 4))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    app.stop().await;
}

/// An error quotes what it refuses (an unknown model name, a key, a value that is not a
/// number); a megabyte of it used to come back whole. Now message and field are cut to a
/// bound, with a note of what was left off, on REST and gRPC alike, and still name the field.
#[tokio::test]
async fn errors_echo_a_bounded_part_of_huge_input() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 1)).await;
    let huge = "X".repeat(1 << 20);
    let small = |what: &str, status: u16, text: &str| {
        assert!(text.len() < 4096, "{what}: {} bytes", text.len());
        let body: Value = serde_json::from_str(text).unwrap();
        assert!(
            body["error"]["message"]
                .as_str()
                .unwrap()
                .contains("more bytes)"),
            "{what}: {body}"
        );
        (status, body)
    };
    let post = |body: Value| {
        let r = app.client.post(app.url("/v1/jobs")).json(&body).send();
        async move {
            let r = r.await.unwrap();
            (r.status().as_u16(), r.text().await.unwrap())
        }
    };

    let mut job = job_body(&ds, "MVF", 1);
    job["model"] = json!(huge);
    let (status, text) = post(job).await;
    let (_, body) = small("model name", status, &text);
    assert_eq!(status, 422, "{body}");
    assert_eq!(body["error"]["field"], "model", "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .starts_with("unknown model 'XXX"),
        "{body}"
    );

    // The field itself holds the caller's key.
    let mut job = job_body(&ds, "MVF", 1);
    job["training"][huge.as_str()] = json!(1);
    let (status, text) = post(job).await;
    let (_, body) = small("training key", status, &text);
    assert_eq!(status, 422, "{body}");
    let field = body["error"]["field"].as_str().unwrap();
    assert!(
        field.starts_with("training.XXX") && field.ends_with("more bytes)"),
        "{field}"
    );

    // A query value (within hyper's URI limit), multi-byte so that the cut must find a
    // character boundary.
    let value = "é".repeat(5_000); // 30 KB percent-encoded, under hyper's 64 KiB URI
    let r = app
        .client
        .get(app.url(&format!("/v1/jobs?page_size={value}")))
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    let (_, body) = small("query value", status, &r.text().await.unwrap());
    assert_eq!(status, 400, "{body}");
    assert_eq!(body["error"]["field"], "page_size", "{body}");

    // gRPC: an unknown model id of 1 MB is a short NOT_FOUND, not a status no client takes.
    let mut c = client(&app).await;
    let e = c.predict(predict_req(&huge, 1)).await.unwrap_err();
    let head: String = e.message().chars().take(200).collect();
    assert_eq!(e.code(), tonic::Code::NotFound, "{head}");
    assert!(
        e.message().len() < 4096 && e.message().ends_with("more bytes)"),
        "{} bytes",
        e.message().len()
    );
    assert_eq!(app.get("/healthz").await.0, 200);
    app.stop().await;
}

/// An id with a control character names nothing, on either backend: 404 on a path, 422 naming
/// the body's field, never the database's refusal (PostgreSQL refuses a NUL in text, which was
/// a 503 carrying the database's own error text, and clients retry a 503).
#[tokio::test]
async fn ids_with_control_characters_are_missing_not_a_database_fault() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 3)).await;
    let mut cases = Vec::new();
    for id in ["x%00y", "%01", "job_%7F"] {
        for (method, path) in [
            ("GET", format!("/v1/datasets/{id}")),
            ("DELETE", format!("/v1/datasets/{id}")),
            ("GET", format!("/v1/jobs/{id}")),
            ("GET", format!("/v1/jobs/{id}/metrics")),
            ("POST", format!("/v1/jobs/{id}/cancel")),
            ("GET", format!("/v1/models/{id}")),
            ("GET", format!("/v1/models/{id}/checkpoint")),
            ("DELETE", format!("/v1/models/{id}")),
            ("GET", format!("/v1/templates/{id}")),
            ("DELETE", format!("/v1/templates/{id}")),
        ] {
            cases.push(case(
                "an id with a control character",
                method,
                path,
                None,
                404,
                "not_found",
                None,
            ));
        }
    }
    let mut body = |field: &'static str, set: &dyn Fn(&mut Value)| {
        let mut v = job_body(&ds, "MVF", 2);
        set(&mut v);
        cases.push(case(
            "a body id with NUL",
            "POST",
            "/v1/jobs",
            Some(v),
            422,
            "unprocessable",
            Some(field),
        ));
    };
    body("dataset_id", &|v| v["dataset_id"] = json!("ds_\u{0}1"));
    body("validation_dataset_id", &|v| {
        v["validation_dataset_id"] = json!("ds_\u{0}")
    });
    for c in &cases {
        run(&app, c).await;
    }
    app.stop().await;
}
