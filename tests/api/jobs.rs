use std::process::Command;

use serde_json::{Value, json};

use crate::helpers::*;

/// A job trains to `succeeded`; its best validation loss equals `graybox eval` of the model
/// file the API serves, on the validation dataset; the name it was given (trimmed) is its and
/// its model's.
#[tokio::test]
async fn job_lifecycle_and_checkpoint_matches_cli_eval() {
    let app = spawn_app(1).await;
    let train = dataset(256, 10);
    let val = dataset(64, 11);
    let (ds, vs) = (app.upload(&train).await, app.upload(&val).await);
    let body = json!({"dataset_id": ds, "validation_dataset_id": vs, "model": "MVB",
                      "name": "  pendulum, run 1 ",
                      "training": {"epochs": 4, "batch_size": 64, "lr": 0.01}});
    let (s, job) = app.post("/v1/jobs", &body).await;
    assert_eq!(s, 201, "{job}");
    assert_eq!(job["name"], "pendulum, run 1");
    assert_eq!(
        (job["state"].as_str(), job["epoch"].as_i64()),
        (Some("queued"), Some(0))
    );
    let id = job["id"].as_str().unwrap();
    let done = app.wait_job(id, 120, final_state).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["epoch"], 4);
    let model_id = done["model_id"].as_str().unwrap();
    let (_, metrics) = app.get(&format!("/v1/jobs/{id}/metrics")).await;
    let epochs: Vec<i64> = metrics["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["epoch"].as_i64().unwrap())
        .collect();
    assert_eq!(epochs, vec![1, 2, 3, 4]);
    let (s, model) = app.get(&format!("/v1/models/{model_id}")).await;
    assert_eq!(s, 200);
    assert_eq!(
        (model["n"].as_i64(), model["job_id"].as_str()),
        (Some(2), Some(id))
    );
    assert_eq!(model["name"], "pendulum, run 1");
    // The job's id reads its model too (as gRPC does).
    let (s, by_job) = app.get(&format!("/v1/models/{id}")).await;
    assert_eq!((s, &by_job["id"]), (200, &model["id"]), "{by_job}");

    let file = app.model_file(model_id).await;
    let dir = tempfile::tempdir().unwrap();
    let (mpath, vpath) = (dir.path().join("m.gbx"), dir.path().join("v.json"));
    std::fs::write(&mpath, &file).unwrap();
    std::fs::write(&vpath, val.to_string()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args([
            "eval",
            "--model",
            mpath.to_str().unwrap(),
            "--data",
            vpath.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let eval: Value = serde_json::from_slice(&out.stdout).unwrap();
    let (loss, best) = (
        eval["loss"].as_f64().unwrap(),
        done["best_val_loss"].as_f64().unwrap(),
    );
    assert!(
        (loss - best).abs() <= 1e-6 * best,
        "eval {loss} vs best_val_loss {best}"
    );

    let r = app
        .client
        .delete(app.url(&format!("/v1/models/{model_id}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 204);
    assert_eq!(app.get(&format!("/v1/models/{model_id}")).await.0, 404);
    app.stop().await;
}

#[tokio::test]
async fn cancel_queued_and_running_jobs() {
    let app = spawn_app(1).await;
    let ds = app.upload(&dataset(2048, 12)).await;
    // The worker takes the first (long) job; the second waits in the queue.
    let (_, running) = app.post("/v1/jobs", &job_body(&ds, "MVF", 500)).await;
    let rid = running["id"].as_str().unwrap().to_string();
    app.wait_job(&rid, 60, |j| j["epoch"].as_i64() >= Some(1))
        .await;
    let (_, queued) = app.post("/v1/jobs", &job_body(&ds, "MVF", 500)).await;
    let qid = queued["id"].as_str().unwrap().to_string();

    let (s, q) = app
        .post(&format!("/v1/jobs/{qid}/cancel"), &json!({}))
        .await;
    assert_eq!(
        (s, q["state"].as_str()),
        (200, Some("cancelled")),
        "queued → cancelled at once"
    );
    let (s, _) = app
        .post(&format!("/v1/jobs/{rid}/cancel"), &json!({}))
        .await;
    assert_eq!(s, 200);
    let r = app.wait_job(&rid, 60, final_state).await;
    assert_eq!(r["state"], "cancelled", "{r}");
    assert!(r["epoch"].as_i64().unwrap() < 500);
    // Cancelling again is harmless; a finished job cannot be cancelled into another state.
    assert_eq!(
        app.post(&format!("/v1/jobs/{qid}/cancel"), &json!({}))
            .await
            .0,
        200
    );
    app.stop().await;
}

#[tokio::test]
async fn events_stream_progress_and_end() {
    let app = spawn_app(1).await;
    let ds = app.upload(&dataset(128, 13)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "W-B", 3)).await;
    let id = job["id"].as_str().unwrap();
    let resp = app
        .client
        .get(app.url(&format!("/v1/jobs/{id}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(resp.headers()["content-type"], "text/event-stream");
    // Reading the whole body returns only because the stream ends after the final state.
    let body = tokio::time::timeout(std::time::Duration::from_secs(60), resp.text())
        .await
        .expect("the stream ends after the final state")
        .unwrap();
    let progress = body.matches("event: progress").count();
    assert_eq!(progress, 3, "{body}");
    assert!(body.contains("\"state\":\"succeeded\""), "{body}");
    app.stop().await;
}

/// One stream for every job (the dashboard's): both jobs submitted after subscribing appear,
/// with their epochs as they train, and each reaches its final state on the stream.
#[tokio::test]
async fn all_jobs_stream_every_change_on_one_connection() {
    let app = spawn_app(1).await;
    let ds = app.upload(&dataset(64, 15)).await;
    let mut resp = app.client.get(app.url("/v1/events")).send().await.unwrap();
    let mut ids = vec![];
    for epochs in [2, 3] {
        let (_, job) = app.post("/v1/jobs", &job_body(&ds, "W-B", epochs)).await;
        ids.push(job["id"].as_str().unwrap().to_string());
    }
    let mut text = String::new();
    let mut last: std::collections::HashMap<String, Value> = Default::default();
    let mut epochs_seen: std::collections::HashMap<String, Vec<i64>> = Default::default();
    let read = async {
        while let Some(chunk) = resp.chunk().await.unwrap() {
            text.push_str(&String::from_utf8_lossy(&chunk));
            while let Some(end) = text.find("\n\n") {
                let event: String = text.drain(..end + 2).collect();
                let Some(data) = event.lines().find_map(|l| l.strip_prefix("data: ")) else {
                    continue; // keep-alive
                };
                assert!(event.contains("event: job"), "{event}");
                let job: Value = serde_json::from_str(data).unwrap();
                let id = job["id"].as_str().unwrap().to_string();
                epochs_seen
                    .entry(id.clone())
                    .or_default()
                    .push(job["epoch"].as_i64().unwrap());
                last.insert(id, job);
            }
            if ids
                .iter()
                .all(|id| last.get(id).is_some_and(|j| j["state"] == "succeeded"))
            {
                return;
            }
        }
    };
    tokio::time::timeout(std::time::Duration::from_secs(120), read)
        .await
        .expect("both jobs succeed on the stream");
    for id in &ids {
        let seen = &epochs_seen[id];
        assert!(
            seen.windows(2).all(|w| w[0] <= w[1]),
            "{id}: epochs {seen:?}"
        );
        assert_eq!(last[id]["epoch"], last[id]["epochs"], "{id}");
    }
    app.stop().await;
}

#[tokio::test]
async fn idempotency_key_returns_the_same_job() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 14)).await;
    let send = |body: Value, key: &'static str| {
        let c = app.client.clone();
        let url = app.url("/v1/jobs");
        async move {
            let r = c
                .post(url)
                .header("Idempotency-Key", key)
                .json(&body)
                .send()
                .await
                .unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        }
    };
    let (s1, a) = send(job_body(&ds, "W-B", 2), "k1").await;
    let (s2, b) = send(job_body(&ds, "W-B", 2), "k1").await;
    assert_eq!((s1, s2), (201, 200));
    assert_eq!(a["id"], b["id"]);
    let (s3, e) = send(job_body(&ds, "W-B", 3), "k1").await;
    assert_eq!(
        (s3, e["error"]["code"].as_str()),
        (422, Some("unprocessable"))
    );
    app.stop().await;
}

/// 20 job submissions and 20 dataset uploads at once while a worker trains: every one
/// succeeds (no SQLITE_BUSY reaches a client).
#[tokio::test]
async fn concurrent_writes_while_training() {
    let app = spawn_app(1).await;
    let ds = app.upload(&dataset(1024, 15)).await;
    let (_, j) = app.post("/v1/jobs", &job_body(&ds, "MVF", 50)).await;
    app.wait_job(j["id"].as_str().unwrap(), 60, |j| j["state"] == "running")
        .await;
    let mut tasks = vec![];
    for i in 0..20u64 {
        let (c, url, body) = (
            app.client.clone(),
            app.url("/v1/jobs"),
            job_body(&ds, "W-B", 1),
        );
        tasks.push(tokio::spawn(async move {
            c.post(url)
                .json(&body)
                .send()
                .await
                .unwrap()
                .status()
                .as_u16()
        }));
        let (c, url, body) = (
            app.client.clone(),
            app.url("/v1/datasets"),
            dataset(64, 1000 + i),
        );
        tasks.push(tokio::spawn(async move {
            c.post(url)
                .json(&body)
                .send()
                .await
                .unwrap()
                .status()
                .as_u16()
        }));
    }
    for t in tasks {
        assert_eq!(t.await.unwrap(), 201);
    }
    let (_, list) = app.get("/v1/jobs?page_size=100").await;
    assert_eq!(list["items"].as_array().unwrap().len(), 21);
    app.stop().await;
}

/// `/metrics` is Prometheus text: HELP/TYPE comments and `name{labels} value` samples.
#[tokio::test]
async fn metrics_are_prometheus_text() {
    let app = spawn_app(0).await;
    app.get("/healthz").await;
    app.get("/v1/jobs").await;
    let r = app.client.get(app.url("/metrics")).send().await.unwrap();
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/plain")
    );
    let text = r.text().await.unwrap();
    let mut samples = 0;
    for line in text.lines().filter(|l| !l.is_empty()) {
        if let Some(rest) = line.strip_prefix("# ") {
            assert!(
                rest.starts_with("HELP ") || rest.starts_with("TYPE "),
                "{line}"
            );
            continue;
        }
        let (series, value) = line
            .rsplit_once(' ')
            .unwrap_or_else(|| panic!("no value: {line}"));
        assert!(value.parse::<f64>().is_ok() || value == "+Inf", "{line}");
        let name = series.split('{').next().unwrap();
        assert!(
            name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
            "{line}"
        );
        if let Some(labels) = series.strip_prefix(name) {
            assert!(
                labels.is_empty() || (labels.starts_with('{') && labels.ends_with('}')),
                "{line}"
            );
        }
        samples += 1;
    }
    assert!(samples > 5);
    assert!(text.contains("graybox_jobs{state=\"queued\"} 0"));
    assert!(text.contains(
        "graybox_http_requests_total{method=\"GET\",route=\"/v1/jobs\",status=\"200\"} 1"
    ));
    let (s, doc) = app.get("/openapi.json").await;
    assert_eq!(s, 200);
    assert!(doc["paths"]["/v1/jobs"].is_object());
    app.stop().await;
}

/// A job whose run went nowhere still succeeds, and says so: its warnings are on the job and
/// in the model's metrics (the data's own warnings on the dataset).
#[tokio::test]
async fn a_job_on_degrees_succeeds_with_warnings() {
    let app = spawn_app(1).await;
    let mut body = dataset(256, 7);
    for field in ["q", "qdot", "q_next", "qdot_next"] {
        for row in body[field].as_array_mut().unwrap() {
            for v in row.as_array_mut().unwrap() {
                *v = json!(v.as_f64().unwrap().to_degrees());
            }
        }
    }
    let (s, ds) = app.post("/v1/datasets", &body).await;
    assert_eq!(s, 201, "{ds}");
    assert!(!ds["warnings"].as_array().unwrap().is_empty(), "{ds}");
    let (s, job) = app
        .post("/v1/jobs", &job_body(ds["id"].as_str().unwrap(), "W-B", 6))
        .await;
    assert_eq!(s, 201, "{job}");
    let job = app
        .wait_job(job["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(job["state"], "succeeded", "{job}");
    let codes: Vec<&str> = job["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["code"].as_str().unwrap())
        .collect();
    assert!(codes.contains(&"no_better_than_zero_acceleration"), "{job}");
    let (_, model) = app
        .get(&format!("/v1/models/{}", job["model_id"].as_str().unwrap()))
        .await;
    assert_eq!(model["metrics"]["warnings"], job["warnings"], "{model}");
    app.stop().await;
}
