//! Several nodes on one database, as API nodes and workers run behind a load balancer: each
//! node here is a whole service (its own App, caches, event pollers and workers) on the test's
//! database, so under `GRAYBOX_TEST_POSTGRES` this is the scale-out deployment.

use std::time::Duration;

use serde_json::Value;
use tonic::Code;

use graybox::store::blobs::Kind;

use crate::helpers::*;

/// Twenty clients retry one submission through two API nodes at once: one job, and every
/// answer names it (201 once, 200 for the rest).
#[tokio::test]
async fn one_idempotency_key_across_two_nodes_makes_one_job() {
    let a = spawn_app(0).await;
    let b = spawn_app_on(&a, 0).await;
    let ds = a.upload(&dataset(8, 31)).await;
    let body = job_body(&ds, "W-B", 2);
    let sends = (0..20).map(|i| {
        let node = if i % 2 == 0 { &a } else { &b };
        let request = node
            .client
            .post(node.url("/v1/jobs"))
            .header("Idempotency-Key", "retry-1")
            .json(&body);
        async move {
            let r = request.send().await.unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        }
    });
    let answers = futures_util::future::join_all(sends).await;
    let created = answers.iter().filter(|(s, _)| *s == 201).count();
    let found = answers.iter().filter(|(s, _)| *s == 200).count();
    assert_eq!((created, found), (1, 19), "{answers:?}");
    let id = &answers[0].1["id"];
    assert!(
        answers.iter().all(|(_, job)| job["id"] == *id),
        "{answers:?}"
    );
    for node in [&a, &b] {
        let (_, jobs) = node.get("/v1/jobs").await;
        assert_eq!(jobs["items"].as_array().unwrap().len(), 1, "{jobs}");
    }
    b.stop().await;
    a.stop().await;
}

/// A job submitted through one API node and trained by a worker node streams its progress and
/// end on another API node; the model it made is served by both, and once deleted through one
/// it is refused by the other (within its cache sweep), its object then collected from the store.
#[tokio::test]
async fn a_job_trained_by_a_worker_shows_and_serves_on_every_api_node() {
    let a = spawn_app(0).await;
    let b = spawn_app_on(&a, 0).await;
    let worker = spawn_app_on(&a, 1).await;
    let ds = a.upload(&dataset(64, 32)).await;
    let all_jobs = b.client.get(b.url("/v1/events")).send().await.unwrap();
    let (_, job) = a.post("/v1/jobs", &job_body(&ds, "W-B", 3)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let events = b.client.get(b.url(&format!("/v1/jobs/{id}/events")));
    let body = tokio::time::timeout(Duration::from_secs(60), async {
        events.send().await.unwrap().text().await.unwrap()
    })
    .await
    .expect("the job's stream on the other node ends after its final state");
    assert_eq!(body.matches("event: progress").count(), 3, "{body}");
    assert!(body.contains("\"state\":\"succeeded\""), "{body}");
    let seen = first_success(all_jobs, &id).await;
    assert_eq!(seen["epoch"], 3, "{seen}");

    let (_, done) = a.get(&format!("/v1/jobs/{id}")).await;
    let model = done["model_id"].as_str().unwrap().to_string();
    let (mut ca, mut cb) = (client(&a).await, client(&b).await);
    let (pa, pb) = (
        ca.predict(predict_req(&model, 2))
            .await
            .unwrap()
            .into_inner(),
        cb.predict(predict_req(&model, 2))
            .await
            .unwrap()
            .into_inner(),
    );
    assert_eq!(pa.x_next, pb.x_next, "both nodes serve the same model");

    // With an object store, the file is an object, and it goes with the model's row.
    let blobs = blobs_for(&a.db).map(|url| graybox::store::blobs::Blobs::open(&url).unwrap());
    let key = graybox::store::blobs::Blobs::key(Kind::Model, &a.model_file(&model).await);
    if let Some(blobs) = &blobs {
        assert!(blobs.exists(&key).await.unwrap(), "{key}");
    }
    let del = a.client.delete(a.url(&format!("/v1/models/{model}")));
    assert!(del.send().await.unwrap().status().is_success());
    // Deleted by node A's collector, which the release wakes (after, not inside, the
    // deletion's transaction).
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while let Some(blobs) = &blobs
        && blobs.exists(&key).await.unwrap()
    {
        assert!(
            tokio::time::Instant::now() < deadline,
            "{key} outlived its row"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let e = ca.predict(predict_req(&model, 1)).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    // The other node's sweep (every CACHE_SWEEP, 0.5 s) drops it; the deadline is generous
    // only so that a loaded machine does not fail the test, not the bound itself.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        match cb.predict(predict_req(&model, 1)).await {
            Err(e) if e.code() == Code::NotFound => break,
            Err(e) => panic!("{e:?}"),
            Ok(_) => assert!(tokio::time::Instant::now() < deadline, "still served"),
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    worker.stop().await;
    b.stop().await;
    a.stop().await;
}

/// Reads the all-jobs stream until job `id` appears succeeded.
async fn first_success(mut stream: reqwest::Response, id: &str) -> Value {
    let read = async {
        let mut text = String::new();
        while let Some(chunk) = stream.chunk().await.unwrap() {
            text.push_str(&String::from_utf8_lossy(&chunk));
            while let Some(end) = text.find("\n\n") {
                let event: String = text.drain(..end + 2).collect();
                let Some(data) = event.lines().find_map(|l| l.strip_prefix("data: ")) else {
                    continue;
                };
                let job: Value = serde_json::from_str(data).unwrap();
                if job["id"] == id && job["state"] == "succeeded" {
                    return job;
                }
            }
        }
        panic!("the stream ended before the job succeeded")
    };
    tokio::time::timeout(Duration::from_secs(60), read)
        .await
        .expect("the job shows as succeeded on the other node's stream")
}
