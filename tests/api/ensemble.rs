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
