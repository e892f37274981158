//! Multi-step jobs and the error-against-horizon call through the REST API.

use graybox::sim::double_pendulum_trajectories;
use serde_json::{Value, json};

use crate::helpers::*;

/// `count` double-pendulum trajectories of `steps` transitions, as an upload body.
pub fn trajectories(count: usize, steps: usize, seed: u64) -> Value {
    let ds = double_pendulum_trajectories(count, steps, seed).unwrap();
    serde_json::from_str(&ds.to_json()).unwrap()
}

/// A job with a horizon trains on windows, reports the horizon loss beside the one-step loss
/// in its metrics and its view, and its model's error against horizon is served; an
/// evaluation over the step limit is refused before it computes.
#[tokio::test]
async fn a_multi_step_job_reports_its_horizon_loss_and_its_model_evaluates() {
    let mut settings = test_settings();
    settings.worker.workers = 1;
    settings.max_rollout_steps = 10;
    let app = spawn_configured(settings).await;
    let ds = app.upload(&trajectories(4, 30, 1)).await;
    let (_, listed) = app.get(&format!("/v1/datasets/{ds}/trajectories")).await;
    assert_eq!(listed["source"], "uploaded", "{listed}");
    let mut body = job_body(&ds, "MVF", 3);
    body["training"]["horizon"] = json!(4);
    let (s, job) = app.post("/v1/jobs", &body).await;
    assert_eq!(s, 201, "{job}");
    assert_eq!(job["training"]["horizon"], 4, "{job}");
    let done = app
        .wait_job(job["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert!(done["val_horizon_loss"].as_f64().is_some(), "{done}");
    let (_, metrics) = app
        .get(&format!("/v1/jobs/{}/metrics", job["id"].as_str().unwrap()))
        .await;
    let items = metrics["items"].as_array().unwrap();
    assert_eq!(items.len(), 3);
    for m in items {
        let (one, h) = (m["val_loss"].as_f64(), m["val_horizon_loss"].as_f64());
        assert!(one.is_some() && h.is_some(), "{m}");
    }

    let model = done["model_id"].as_str().unwrap();
    // The held-out trajectory (one of 30 transitions) reports the error at the horizons it
    // is long enough for.
    let (_, view) = app.get(&format!("/v1/models/{model}")).await;
    let at: Vec<u64> = (view["metrics"]["horizon_errors"].as_array())
        .unwrap_or_else(|| panic!("{view}"))
        .iter()
        .map(|e| e["horizon"].as_u64().unwrap())
        .collect();
    assert_eq!(at, [1, 10], "{view}");
    let path = format!("/v1/models/{model}/evaluate");
    let (s, ev) = app
        .post(&path, &json!({"dataset_id": ds, "horizons": [5, 1]}))
        .await;
    assert_eq!(s, 200, "{ev}");
    let items = ev["items"].as_array().unwrap();
    assert_eq!(items.len(), 2);
    assert_eq!(
        (items[0]["horizon"].as_u64(), items[0]["windows"].as_u64()),
        (Some(1), Some(4 * 30))
    );
    assert_eq!(items[1]["windows"], 4 * 26);
    // 4 × 30 starts rolled out up to 10 steps: over 100 × --max-rollout-steps (1000).
    let (s, refused) = app
        .post(&path, &json!({"dataset_id": ds, "horizons": [10]}))
        .await;
    assert_eq!(s, 413, "{refused}");
    assert!(
        refused["error"]["message"]
            .as_str()
            .unwrap()
            .contains("--max-rollout-steps"),
        "{refused}"
    );
    app.stop().await;
}
