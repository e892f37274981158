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
    // best_val_loss is the loss over 4-step windows, and says so.
    assert_eq!(done["best_val_loss_steps"], 4, "{done}");
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
    assert_eq!(view["metrics"]["best_val_loss_steps"], 4, "{view}");
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

/// A horizon longer than every trajectory is refused naming `training.horizon`, even where
/// its windows' memory would be over the limit too (that refusal, naming
/// `training.batch_size`, came first and sent the user to the wrong field).
#[tokio::test]
async fn a_horizon_no_trajectory_holds_is_refused_as_such() {
    let mut settings = test_settings();
    settings.worker.workers = 0;
    settings.max_job_memory_mb = 64;
    let app = spawn_configured(settings).await;
    let ds = app.upload(&trajectories(2, 50, 3)).await;
    let mut body = job_body(&ds, "MVF", 3);
    body["training"]["horizon"] = json!(1000);
    body["training"]["batch_size"] = json!(4096);
    let (status, refused) = app.post("/v1/jobs", &body).await;
    assert_eq!(status, 422, "{refused}");
    assert_eq!(refused["error"]["field"], "training.horizon", "{refused}");
    assert!(
        refused["error"]["message"]
            .as_str()
            .unwrap()
            .contains("longest in the training data is 50"),
        "{refused}"
    );
    app.stop().await;
}

/// One form per body, and one reading of a dataset's rows: a body with both trajectories and
/// flat arrays is refused (one of them was dropped silently), and the same rows with other
/// trajectory boundaries are a conflict naming the stored dataset (the new boundaries were
/// dropped silently); the same boundaries again find the stored dataset.
#[tokio::test]
async fn a_dataset_has_one_form_and_one_set_of_boundaries() {
    let app = spawn_app(0).await;
    let body = trajectories(2, 10, 4);
    let mut both = body.clone();
    both["q"] = json!([[0.0, 0.0]]);
    let (status, refused) = app.post("/v1/datasets", &both).await;
    assert_eq!(
        (status, &refused["error"]["field"]),
        (400, &json!("trajectories")),
        "{refused}"
    );
    let ds = app.upload(&body).await;
    let (status, again) = app.post("/v1/datasets", &body).await;
    assert_eq!((status, &again["id"]), (200, &json!(ds)), "{again}");
    // The same rows cut at another place: the first trajectory split after 4 of its 10
    // transitions (4 + 6 + 10 instead of 10 + 10).
    let first = &body["trajectories"][0];
    let part = |k: &str, from: usize, to: usize| json!(first[k].as_array().unwrap()[from..to]);
    let recut = json!({"dt": body["dt"], "trajectories": [
        {"q": part("q", 0, 5), "qdot": part("qdot", 0, 5), "u": part("u", 0, 4)},
        {"q": part("q", 4, 11), "qdot": part("qdot", 4, 11), "u": part("u", 4, 10)},
        body["trajectories"][1],
    ]});
    let (status, conflict) = app.post("/v1/datasets", &recut).await;
    assert_eq!(status, 409, "{conflict}");
    let message = conflict["error"]["message"].as_str().unwrap();
    assert!(
        message.contains(&ds) && message.contains("boundaries"),
        "{conflict}"
    );
    let (_, stored) = app.get(&format!("/v1/datasets/{ds}/trajectories")).await;
    assert_eq!(stored["count"], 2, "{stored}");
    app.stop().await;
}
