//! Compatibility: model files and a database written by an earlier graybox
//! (tests/fixtures/compat, made by scripts/compat_fixtures.sh) keep working: the models load
//! and predict bit for bit as they did, and a job killed while running resumes and finishes.
//! Each format version has its files: graybox.model/1 and /2 (mvf, wb, naive) and an
//! ensemble's graybox.model/3 (wb-x3).

use std::path::{Path, PathBuf};
use std::time::Duration;

use graybox::infer::Evaluator;
use graybox::model::Model;
use graybox::model::file::ModelFile;
use graybox::records::JobState;
use serde_json::{Value, json};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/compat")
}

/// Fixed points inside and outside the training data's range.
fn points(k: usize, width: usize, seed: u64) -> Vec<f64> {
    (0..k * width)
        .map(|i| ((i as u64 * 2654435761 + seed) % 1000) as f64 / 125.0 - 4.0)
        .collect()
}

const MODELS: [&str; 4] = ["mvf", "wb", "naive", "wb-x3"];

/// Predict (with q̈) at 5 points and Linearize at 3, as JSON; an ensemble's members' spread
/// of x' too.
fn outputs(file: &ModelFile) -> Value {
    let eval = Evaluator::from_file(file).unwrap();
    let (nx, m) = (file.config.nx(), file.config.m);
    let (x, u) = (points(5, nx, 1), points(5, m, 2));
    let (next, accel) = eval.predict(&x, &u, true);
    let (a, b) = eval.linearize_batch(&x[..3 * nx], &u[..3 * m]);
    let mut out = json!({"x_next": next, "accel": accel, "a": a, "b": b});
    if eval.member_count() > 1 {
        let p = eval
            .predict_members_until(&x, &u, eval.config.dt, false, &|| false)
            .unwrap();
        out["x_next_std"] = json!(p.std);
    }
    out
}

#[test]
fn models_predict_as_they_did() {
    let dir = fixtures();
    let mut got = serde_json::Map::new();
    for name in MODELS {
        let file = ModelFile::load(&dir.join(format!("{name}.gbx"))).unwrap();
        got.insert(name.into(), outputs(&file));
    }
    let path = dir.join("expected.json");
    let mut expected: Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    if std::env::var_os("GRAYBOX_WRITE_COMPAT").is_some() {
        // Only a new version's files get outputs: the earlier ones' stay what they were.
        for (name, outs) in got {
            let known = expected.as_object_mut().unwrap();
            known.entry(name).or_insert(outs);
        }
        std::fs::write(&path, serde_json::to_string_pretty(&expected).unwrap()).unwrap();
        return;
    }
    for (name, outs) in &got {
        let keys = |v: &Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        assert_eq!(
            keys(outs),
            keys(&expected[name]),
            "{name}: the same outputs"
        );
        for (what, values) in outs.as_object().unwrap() {
            let (g, e) = (
                values.as_array().unwrap(),
                expected[name][what].as_array().unwrap(),
            );
            assert_eq!(g.len(), e.len(), "{name} {what}");
            for (i, (g, e)) in g.iter().zip(e).enumerate() {
                // Bit for bit: the JSON round trip of an f64 is exact (float_roundtrip).
                let (g, e) = (g.as_f64().unwrap(), e.as_f64().unwrap());
                assert_eq!(g.to_bits(), e.to_bits(), "{name} {what}[{i}]: {g} vs {e}");
            }
        }
    }
}

/// Files written today name and order their values as the earlier files do (the names are
/// the file format; a checkpoint's optimizer state follows the order), and the earlier files
/// load into today's models.
#[test]
fn files_keep_their_value_names_and_order() {
    use graybox::backend::{Backend, Precision};
    let device = graybox::backend::device(Backend::Flex, Precision::F32).unwrap();
    for name in MODELS {
        let file = ModelFile::load(&fixtures().join(format!("{name}.gbx"))).unwrap();
        let old = file.member(file.member_count() - 1);
        let fresh = graybox::model::Model::init(old.config.clone(), None, 7, &device).unwrap();
        let layout =
            |arrays: &[graybox::model::params_io::NamedArray]| -> Vec<(String, Vec<usize>)> {
                arrays
                    .iter()
                    .map(|a| (a.name.clone(), a.shape.clone()))
                    .collect()
            };
        assert_eq!(
            layout(&fresh.params.export()),
            layout(&old.params),
            "{name}"
        );
        let loaded = Model::from_file(&old, &device).unwrap();
        assert_eq!(
            loaded.params.export(),
            old.params,
            "{name}: values round trip"
        );
    }
}

#[tokio::test]
async fn a_job_killed_while_running_resumes_and_finishes() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("running.db");
    std::fs::copy(fixtures().join("running.db"), &db).unwrap();
    let job = std::fs::read_to_string(fixtures().join("running.job")).unwrap();
    let job = job.trim();
    let cfg = graybox::app::Settings {
        http: "127.0.0.1:0".into(),
        grpc: "127.0.0.1:0".into(),
        worker: graybox::app::WorkerSettings {
            db: db.to_string_lossy().into_owned(),
            ..Default::default()
        },
        ..Default::default()
    };
    // The job as the killed process left it, read before a worker can reclaim it.
    let store = graybox::store::Store::open(&cfg.worker.db).await.unwrap();
    let before = store.get_job(job).await.unwrap().unwrap();
    drop(store);
    let running = graybox::service::start(cfg).await.unwrap();
    assert_eq!(before.state, JobState::Running);
    assert!(before.checkpoint_epoch >= 2, "{before:?}");
    let deadline = tokio::time::Instant::now() + Duration::from_secs(300);
    let done = loop {
        let j = running.app.job(job).await.unwrap();
        if j.state.is_final() {
            break j;
        }
        assert!(tokio::time::Instant::now() < deadline, "{j:?}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(done.state, JobState::Succeeded, "{done:?}");
    assert_eq!(done.attempt, before.attempt + 1);
    let epochs: Vec<i64> = running
        .app
        .job_metrics(job)
        .await
        .unwrap()
        .iter()
        .map(|m| m.epoch)
        .collect();
    assert_eq!(epochs, (1..=done.epochs).collect::<Vec<_>>());
    let model = running
        .app
        .evaluator(done.model_id.as_deref().unwrap())
        .await;
    assert!(model.is_ok());
    running.shutdown().await;
}
