//! Ensembles through the service: admission counts every member.

use serde_json::json;

use crate::helpers::{dataset, job_body, spawn_configured, test_settings};

/// A job whose one model fits the memory limit is refused as an ensemble of 32 (each member
/// keeps its own tape and parameters), naming the field and the members.
#[tokio::test]
async fn admission_counts_every_member() {
    let mut settings = test_settings();
    settings.worker.workers = 0;
    // MVF at batch 64 takes about 8 MB at its peak: 32 members take about 260.
    settings.max_job_memory_mb = 64;
    let app = spawn_configured(settings).await;
    let ds = app.upload(&dataset(512, 3)).await;
    let (status, one) = app.post("/v1/jobs", &job_body(&ds, "MVF", 3)).await;
    assert_eq!(status, 201, "{one}");
    let mut body = job_body(&ds, "MVF", 3);
    body["training"]["ensemble"] = json!(32);
    let (status, refused) = app.post("/v1/jobs", &body).await;
    assert_eq!(status, 422, "{refused}");
    assert_eq!(
        refused["error"]["field"], "training.batch_size",
        "{refused}"
    );
    let message = refused["error"]["message"].as_str().unwrap();
    assert!(message.contains("32 ensemble members"), "{message}");
    app.stop().await;
}

/// A model file of tests/fixtures/compat uploaded: its id.
pub(crate) async fn upload_fixture(app: &crate::helpers::TestApp, name: &str) -> String {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/compat");
    let bytes = std::fs::read(dir.join(format!("{name}.gbx"))).unwrap();
    let r = (app.client.post(app.url("/v1/models")).body(bytes))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    let v: serde_json::Value = r.json().await.unwrap();
    v["id"].as_str().unwrap().to_string()
}

/// Serving admits an ensemble's calls with its members' answers counted: near the per-call
/// budget, the largest batch one model is admitted for is refused on an ensemble of three
/// (each member's x' is held until their mean is taken), and the ensemble's own largest
/// batch is refused once every member's x' is also asked back.
#[tokio::test]
async fn serving_counts_the_members_answers_near_the_call_budget() {
    use crate::helpers::{client, predict_req};
    let mut settings = test_settings();
    settings.worker.workers = 0;
    settings.max_call_memory_mb = 1;
    let app = spawn_configured(settings).await;
    let (single, ensemble) = (
        upload_fixture(&app, "wb").await,
        upload_fixture(&app, "wb-x3").await,
    );
    let mut c = client(&app).await;
    let mut admitted = async |model: &str, b: usize, members: bool| -> bool {
        let req = graybox::api::grpc::pb::PredictRequest {
            members,
            ..predict_req(model, b)
        };
        match c.predict(req).await {
            Ok(_) => true,
            Err(s) if s.code() == tonic::Code::ResourceExhausted => {
                assert!(s.message().contains("per-call memory budget"), "{s:?}");
                false
            }
            Err(s) => panic!("{s:?}"),
        }
    };
    // The largest admitted batch, by bisection between an admitted and a refused size.
    let mut largest = async |model: &str, members: bool| -> usize {
        let (mut lo, mut hi) = (1usize, 1usize << 16);
        assert!(admitted(model, lo, members).await && !admitted(model, hi, members).await);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if admitted(model, mid, members).await {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    let one = largest(&single, false).await;
    let three = largest(&ensemble, false).await;
    let every_member = largest(&ensemble, true).await;
    assert!(three < one, "{three} vs {one}");
    assert!(every_member < three, "{every_member} vs {three}");
    app.stop().await;
}

/// A plan on an ensemble's average cost stacks every member's state: over the call budget it
/// is refused naming the horizon and the ensemble cost as the way out, not "fewer states",
/// and the same plan on the mean dynamics is admitted.
#[tokio::test]
async fn a_mean_cost_plan_over_the_budget_names_the_horizon_and_the_ensemble_cost() {
    use crate::helpers::{arr, client};
    let mut settings = test_settings();
    settings.worker.workers = 0;
    settings.max_call_memory_mb = 1;
    let app = spawn_configured(settings).await;
    let model = upload_fixture(&app, "wb-x3").await;
    let mut c = client(&app).await;
    let eye = |s: f64| {
        let mut d = vec![0.0; 16];
        (0..4).for_each(|i| d[i * 5] = s);
        arr(&[4, 4], d)
    };
    let plan = |ensemble_cost: &str| graybox::api::grpc::pb::PlanRequest {
        model_id: model.clone(),
        x0: vec![0.0; 4],
        goal: vec![0.5, 0.0, 0.0, 0.0],
        horizon: 10,
        q: eye(1.0),
        r: arr(&[2, 2], vec![0.01, 0.0, 0.0, 0.01]),
        qf: eye(10.0),
        max_iterations: Some(2),
        method: "dircol".into(),
        ensemble_cost: ensemble_cost.into(),
        ..Default::default()
    };
    let refused = c.plan(plan("mean")).await.unwrap_err();
    assert_eq!(
        refused.code(),
        tonic::Code::ResourceExhausted,
        "{refused:?}"
    );
    let message = refused.message();
    for words in [
        "horizon:",
        "--max-call-memory-mb",
        "shorter horizon",
        "ensemble_cost",
        "mean_dynamics",
        "3 members",
    ] {
        assert!(message.contains(words), "{words}: {message}");
    }
    assert!(!message.contains("fewer states"), "{message}");
    c.plan(plan("mean_dynamics")).await.unwrap();
    app.stop().await;
}
