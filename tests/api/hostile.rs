//! A hostile client's findings (the hardening issue), each reproduced: well-formed requests
//! that used to take the service down or around its guards. Process-level probes (memory,
//! threads, TLS) are in tests/python/test_hostile.py.

use std::time::Duration;

use graybox::api::grpc::pb::{self, rollout_request::Inputs};
use graybox::app::{App, Settings};
use graybox::array::Array;
use graybox::records::JobState;
use graybox::store::Store;
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;
// These lived here; kept importable from here.
pub(crate) use crate::helpers::{arr, client};

/// Finding 1: a call whose response is over the message limit (Linearize of 10⁶ states) or
/// whose memory is over the budget is refused before it computes; an accepted large batch
/// still answers (in chunks).
#[tokio::test]
async fn oversized_calls_are_refused_before_computing() {
    let app = spawn_app(1).await;
    let model = trained(&app, "MVF").await;
    let mut c = client(&app).await;
    let b = 1_000_000u64;
    let lin = pb::LinearizeRequest {
        id: String::new(),
        model_id: model.clone(),
        x: arr(&[b, 4], vec![0.0; 4 * b as usize]),
        u: arr(&[b, 2], vec![0.0; 2 * b as usize]),
    };
    let e = c.linearize(lin).await.unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("--grpc-max-message-mb"), "{e:?}");

    // The memory budget alone (a tiny one) refuses a mid-size Predict and names its flag.
    let tight = App::new(
        app.open_store().await,
        Settings {
            max_call_memory_mb: 1,
            ..Settings::default()
        },
    );
    let x = Array::new(&[50_000, 4], vec![0.0; 4 * 50_000]);
    let u = Array::new(&[50_000, 2], vec![0.0; 2 * 50_000]);
    let e = tight
        .predict(&model, x, u, Default::default(), None)
        .await
        .err()
        .unwrap();
    assert!(e.to_string().contains("--max-call-memory-mb"), "{e}");

    // 20 000 states pass the budget and come back whole, split over several chunks.
    let r = c
        .predict(predict_req(&model, 20_000))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.x_next.unwrap().shape, vec![20_000, 4]);
    assert_eq!(r.max_abs_z.len(), 20_000);
    app.stop().await;
}

/// Finding 10: client-supplied numbers use checked arithmetic: a shape whose product wraps
/// around to the number of values, and a grpc-timeout too large for an `Instant`.
#[tokio::test]
async fn overflowing_numbers_are_rejected_not_wrapped() {
    let app = spawn_app(1).await;
    let model = trained(&app, "W-B").await;
    let mut c = client(&app).await;
    let mut req = predict_req(&model, 1);
    req.x = arr(&[(1u64 << 63) + 1, 4], vec![0.1; 4]);
    let e = c.predict(req).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");

    let mut rollout = tonic::Request::new(pb::RolloutRequest {
        id: String::new(),
        model_id: model,
        x0: vec![0.1, 0.2, 0.0, 0.0],
        inputs: Some(Inputs::U(pb::Array {
            shape: vec![3, 2],
            data: vec![0.0; 6],
        })),
        chunk: 0,
        particles: None,
        dt: None,
    });
    rollout
        .metadata_mut()
        .insert("grpc-timeout", "99999999S".parse().unwrap());
    let mut s = c.rollout(rollout).await.unwrap().into_inner();
    let chunk = s.message().await.unwrap().unwrap();
    assert_eq!(chunk.x.unwrap().shape, vec![4, 4]);
    assert_eq!(chunk.max_abs_z.len(), 3);
    app.stop().await;
}

/// Findings 2–4: jobs over the service's limits are refused at submission (422 naming the
/// field and the estimate), before any work.
#[tokio::test]
async fn jobs_over_the_limits_are_refused_at_submission() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(64, 2)).await;
    let huge = json!({"type": "mlp", "hidden": vec![4096; 16]});
    let refuse = |body: Value, field: &'static str, words: &'static str| {
        let app = &app;
        async move {
            let (status, v) = app.post("/v1/jobs", &body).await;
            assert_eq!(status, 422, "{v}");
            assert_eq!(v["error"]["field"], field, "{v}");
            let msg = v["error"]["message"].as_str().unwrap();
            assert!(msg.contains(words), "{msg}");
        }
    };
    refuse(
        json!({"dataset_id": ds, "model": {"kind": "structured", "mass": huge, "potential": huge,
               "forces": huge}, "training": {"batch_size": 4_000_000}}),
        "model",
        "--max-model-params",
    )
    .await;
    refuse(
        json!({"dataset_id": ds, "model": {"kind": "naive", "hidden": [4096, 4096, 4096]}}),
        "model",
        "trainable parameters",
    )
    .await;
    // Within the parameter limit but over the memory limit (set low here).
    let tight = spawn_configured(Settings {
        max_job_memory_mb: 1,
        ..Settings::default()
    })
    .await;
    let tight_ds = tight.upload(&dataset(512, 3)).await;
    let (status, v) = tight.post("/v1/jobs", &job_body(&tight_ds, "MVF", 1)).await;
    assert_eq!(status, 422, "{v}");
    assert_eq!(v["error"]["field"], "training.batch_size", "{v}");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap()
            .contains("--max-job-memory-mb")
    );
    tight.stop().await;
    // n = 500 coordinates.
    let n = 500;
    let row = vec![0.1; n];
    let wide = json!({"dt": 0.01, "q": vec![row.clone(); 2], "qdot": vec![row.clone(); 2],
                      "u": [[1.0], [2.0]], "q_next": vec![row.clone(); 2], "qdot_next": vec![row; 2]});
    let wide_ds = app.upload(&wide).await;
    refuse(
        json!({"dataset_id": wide_ds, "model": "MVF"}),
        "dataset_id",
        "--max-dof",
    )
    .await;
    // A batch larger than the training set is the whole set, not an error.
    let (status, v) = app
        .post(
            "/v1/jobs",
            &json!({"dataset_id": ds, "model": "MVF", "training": {"batch_size": 1_000_000}}),
        )
        .await;
    assert_eq!(status, 201, "{v}");
    app.stop().await;
}

/// Findings 9 and 12: Δt outside the documented range, names counted in bytes or carrying
/// control and bidi characters, and initial values that overflow the first epoch.
#[tokio::test]
async fn values_outside_their_ranges_are_refused() {
    let app = spawn_app(0).await;
    for dt in [1e-320, 1e-12, 1e6] {
        let mut d = dataset(8, 1);
        d["dt"] = json!(dt);
        let (status, v) = app.post("/v1/datasets", &d).await;
        assert_eq!(status, 400, "dt {dt}: {v}");
        assert_eq!(v["error"]["field"], "dt", "{v}");
    }
    let upload_named = |name: String| {
        let app = &app;
        async move {
            let r = app
                .client
                .post(app.url("/v1/datasets"))
                .query(&[("name", name)])
                .json(&dataset(8, 7))
                .send()
                .await
                .unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        }
    };
    let (status, v) = upload_named("é".repeat(150)).await;
    assert!(status == 201 || status == 200, "{v}");
    for bad in ["a\u{0}b", "evil\u{202E}txt.exe", "x".repeat(201).as_str()] {
        let (status, v) = upload_named(bad.to_string()).await;
        assert_eq!(status, 400, "{bad:?}: {v}");
        assert_eq!(v["error"]["field"], "name");
    }
    // Finite values whose statistics are not (their sum overflows): refused at submission,
    // where the job used to "succeed" with a model file that cannot be read back.
    let mut d = dataset(8, 11);
    d["q"] = json!(vec![vec![1.5e308, 1.5e308]; 8]);
    let huge = app.upload(&d).await;
    let (status, v) = app.post("/v1/jobs", &job_body(&huge, "MVF", 1)).await;
    assert_eq!(status, 422, "{v}");
    assert_eq!(v["error"]["field"], "dataset_id", "{v}");

    let ds = app.upload(&dataset(8, 1)).await;
    let mut body = job_body(&ds, "W-B", 1);
    body["init"] = json!({"m1": 1e308});
    let (status, v) = app.post("/v1/jobs", &body).await;
    assert_eq!(status, 422, "{v}");
    assert_eq!(v["error"]["field"], "init.m1");
    app.stop().await;
}

/// Finding 8: a submission racing the deletion of its dataset: one wins, never both.
#[tokio::test]
async fn job_submission_and_dataset_deletion_exclude_each_other() {
    let app = spawn_app(0).await;
    for i in 0..30 {
        let ds = app.upload(&dataset(8, 100 + i)).await;
        let body = job_body(&ds, "MVF", 1);
        let del = app.client.delete(app.url(&format!("/v1/datasets/{ds}")));
        let (job, deleted) = tokio::join!(app.post("/v1/jobs", &body), del.send());
        let deleted = deleted.unwrap().status().as_u16();
        match (job.0, deleted) {
            (201, 409) | (422, 204) | (422, 200) => {}
            other => panic!("trial {i}: submission and deletion both decided {other:?}"),
        }
    }
    app.stop().await;
}

/// Finding 7: after DELETE returns, this process never serves the model again, even when a
/// Predict on the not-yet-cached model raced the delete; another process on the same
/// database stops within the documented bound (CACHE_SWEEP).
#[tokio::test]
async fn deleted_models_stop_being_served() {
    let app = spawn_app(1).await;
    let mut c = client(&app).await;
    let store = app.open_store().await;
    for trial in 0..6 {
        let model = trained(&app, "W-B").await;
        let mut racing = c.clone();
        let predict = racing.predict(predict_req(&model, 1));
        let del = app.client.delete(app.url(&format!("/v1/models/{model}")));
        let (_, deleted) = tokio::join!(predict, del.send());
        assert!(deleted.unwrap().status().is_success());
        let e = c.predict(predict_req(&model, 1)).await.unwrap_err();
        assert_eq!(e.code(), Code::NotFound, "trial {trial}: {e:?}");
    }

    // A second process (its own App and cache) over the same database.
    let model = trained(&app, "W-B").await;
    let other = App::new(store, Settings::default());
    let x = || Array::new(&[1, 4], vec![0.1; 4]);
    let u = || Array::new(&[1, 2], vec![1.0; 2]);
    other
        .predict(&model, x(), u(), Default::default(), None)
        .await
        .unwrap();
    let del = app.client.delete(app.url(&format!("/v1/models/{model}")));
    assert!(del.send().await.unwrap().status().is_success());
    let sweep = graybox::app::inference::CACHE_SWEEP;
    tokio::time::sleep(sweep).await;
    // The service's sweep runs in its own task; this process runs its sweep as `serve` does.
    other.sweep_model_cache().await.unwrap();
    let e = other
        .predict(&model, x(), u(), Default::default(), None)
        .await
        .err()
        .unwrap();
    assert!(
        matches!(e, graybox::error::Error::NotFound(_)),
        "still served: {e}"
    );
    app.stop().await;
}

/// Finding 11: two processes opening a new database at once both migrate it.
#[tokio::test]
async fn concurrent_first_opens_both_succeed() {
    for trial in 0..14 {
        let dir = tempfile::tempdir().unwrap();
        let db = fresh_db(dir.path()).await;
        let (a, b) = tokio::join!(Store::open(&db), Store::open(&db));
        assert!(
            a.is_ok() && b.is_ok(),
            "trial {trial}: {:?} {:?}",
            a.err(),
            b.err()
        );
    }
}

/// Finding 2 (crash loop): a job whose worker dies holding it is counted at each reclaim and
/// fails after `max_attempts`; cancel of a job whose lease expired takes effect at once.
#[tokio::test]
async fn dead_workers_are_counted_and_expired_jobs_cancel_at_once() {
    let app = spawn_app(0).await;
    let store = app.open_store().await;
    let ds = app.upload(&dataset(8, 9)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "MVF", 1)).await;
    let id = job["id"].as_str().unwrap().to_string();
    // Each claim with a 1 ms lease stands for a worker that dies right after claiming.
    for attempt in 1..=3 {
        let c = store.claim_job("dying", 1, 3).await.unwrap().unwrap();
        assert_eq!(c.job.id, id);
        assert_eq!(c.attempt, attempt);
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    assert!(store.claim_job("next", 1, 3).await.unwrap().is_none());
    let (_, failed) = app.get(&format!("/v1/jobs/{id}")).await;
    assert_eq!(failed["state"], "failed", "{failed}");
    assert_eq!(failed["error"], "the worker died 3 times running this job");

    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "MVF", 1)).await;
    let id = job["id"].as_str().unwrap().to_string();
    store.claim_job("dying", 1, 3).await.unwrap().unwrap();
    tokio::time::sleep(Duration::from_millis(5)).await;
    let (status, v) = app.post(&format!("/v1/jobs/{id}/cancel"), &json!({})).await;
    assert_eq!(status, 200, "{v}");
    assert_eq!(v["state"], "cancelled", "{v}");
    assert!(store.claim_job("next", 1, 3).await.unwrap().is_none());
    assert_eq!(
        store.get_job(&id).await.unwrap().unwrap().state,
        JobState::Cancelled
    );
    app.stop().await;
}

/// Finding 12: a checkpoint whose epoch is past the job's epochs (valid checksum) is corrupt:
/// the job fails instead of "succeeding" without training.
#[tokio::test]
async fn a_checkpoint_past_the_last_epoch_is_corrupt() {
    let app = spawn_app(0).await;
    let store = app.open_store().await;
    let ds = app.upload(&dataset(8, 9)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "MVF", 2)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let c = store.claim_job("forger", 60_000, 3).await.unwrap().unwrap();
    assert!(store.save_checkpoint(&c, 99, b"{}").await.unwrap());
    assert!(store.release_job(&c).await.unwrap());
    let worker = spawn_app_on(&app, 1).await;
    let done = app.wait_job(&id, 60, final_state).await;
    assert_eq!(done["state"], "failed", "{done}");
    assert!(
        done["error"]
            .as_str()
            .unwrap()
            .contains("corrupt checkpoint"),
        "{done}"
    );
    worker.stop().await;
    app.stop().await;
}

/// Finding 12: every event subscriber of a job shares one store poller.
#[tokio::test]
async fn event_subscribers_share_one_poller() {
    let app = spawn_app(0).await;
    let ds = app.upload(&dataset(8, 9)).await;
    let (_, job) = app.post("/v1/jobs", &job_body(&ds, "MVF", 1)).await;
    let id = job["id"].as_str().unwrap().to_string();
    let polls = || async {
        let text = app
            .client
            .get(app.url("/metrics"))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        text.lines()
            .find_map(|l| l.strip_prefix("graybox_job_polls_total "))
            .unwrap()
            .parse::<u64>()
            .unwrap()
    };
    let window = Duration::from_millis(1000);
    let mut streams = vec![];
    for _ in 0..50 {
        let r = app
            .client
            .get(app.url(&format!("/v1/jobs/{id}/events")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
        streams.push(r);
    }
    let before = polls().await;
    tokio::time::sleep(window).await;
    let during = polls().await - before;
    // One poller reads every POLL; 50 pollers would read 50 times as often.
    let one = (window.as_millis() / graybox::app::events::POLL.as_millis()) as u64;
    assert!(during >= 1, "nobody polled");
    assert!(
        during <= 2 * one + 2,
        "{during} store reads in {window:?} for one job"
    );
    drop(streams);
    app.stop().await;
}

/// Finding 9: a model file is never written with a non-finite number (JSON would store it as
/// null and the file would not load back).
#[test]
fn model_files_with_non_finite_numbers_are_not_written() {
    use graybox::model::ModelConfig;
    use graybox::model::file::ModelFile;
    use graybox::model::params_io::NamedArray;
    use graybox::model::spec::ModelSpec;
    use graybox::physics::scaling::Scaling;
    let config = ModelConfig {
        spec: ModelSpec::named("naive", None).unwrap(),
        space: graybox::physics::space::Space::flat(1, &[]),
        m: 1,
        dt: 0.01,
        integrator: Default::default(),
        lambda: 1.0,
        scaling: Scaling::identity(1, 1, 1),
    };
    let array = |v: f64| NamedArray {
        name: "naive.layers.0.bias".into(),
        shape: vec![1],
        values: vec![v],
    };
    let good = ModelFile::new(config.clone(), vec![array(0.5)], None);
    assert!(good.to_bytes().is_ok());
    let bad = ModelFile::new(config.clone(), vec![array(f64::NAN)], None);
    let e = bad.to_bytes().unwrap_err().to_string();
    assert!(e.contains("naive.layers.0.bias"), "{e}");
    let mut scaled = config;
    scaled.scaling.q_std[0] = f64::NAN;
    assert!(
        ModelFile::new(scaled, vec![array(0.5)], None)
            .to_bytes()
            .is_err()
    );
}
