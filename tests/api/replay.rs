//! A dataset's trajectories and a model's replay of one (the dashboard's "rollout vs data"):
//! boundaries kept from trajectory-form uploads, chains found in flat ones, and the true
//! pendulum's replay equal to the recording.

use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::sim::TemplateSystem;
use graybox::sim::true_step;
use serde_json::{Value, json};

use crate::helpers::*;

const DT: f64 = 0.01;

/// A transition (x, u, x′) of the pendulum.
type Row = ([f64; 2], f64, [f64; 2]);

/// States of the true pendulum from `x0` under `u`, by the simulator's f64 RK4 (not the
/// evaluator the service replays with).
fn recording(x0: [f64; 2], u: &[f64]) -> Vec<[f64; 2]> {
    let t = Template::Pendulum;
    let sys = TemplateSystem::new(t.clone(), t.defaults());
    let mut xs = vec![x0];
    for &ui in u {
        let x = xs.last().unwrap();
        let next = true_step(&sys, x, &[ui], DT, Integrator::Rk4);
        xs.push([next[0], next[1]]);
    }
    xs
}

fn trajectory(xs: &[[f64; 2]], u: &[f64]) -> Value {
    json!({"q": xs.iter().map(|x| [x[0]]).collect::<Vec<_>>(),
           "qdot": xs.iter().map(|x| [x[1]]).collect::<Vec<_>>(),
           "u": u.iter().map(|v| [v]).collect::<Vec<_>>()})
}

async fn pendulum_model(app: &TestApp) -> String {
    let t = Template::Pendulum;
    let file = ModelFile::from_template(&t, &t.defaults(), DT, Integrator::Rk4).unwrap();
    let r = app
        .client
        .post(app.url("/v1/models?name=true-pendulum"))
        .body(file.to_bytes().unwrap())
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success());
    r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string()
}

#[tokio::test]
async fn trajectories_keep_their_boundaries_and_replay_as_recorded() {
    let app = spawn_app(0).await;
    let u1: Vec<f64> = (0..40).map(|k| (k as f64 * 0.3).sin()).collect();
    let first = recording([0.4, 0.0], &u1);
    // The second starts where the first ended: only the stored boundary tells them apart.
    let u2 = vec![-0.5; 25];
    let second = recording(*first.last().unwrap(), &u2);
    let body =
        json!({"dt": DT, "trajectories": [trajectory(&first, &u1), trajectory(&second, &u2)]});
    let ds = app.upload(&body).await;

    let (status, list) = app.get(&format!("/v1/datasets/{ds}/trajectories")).await;
    assert_eq!(status, 200, "{list}");
    assert_eq!(list["source"], "uploaded");
    assert_eq!(
        list["items"],
        json!([{"index": 0, "start": 0, "length": 40}, {"index": 1, "start": 40, "length": 25}])
    );
    // Paging: one a page, then the rest.
    let (_, page) = app
        .get(&format!("/v1/datasets/{ds}/trajectories?page_size=1"))
        .await;
    assert_eq!(page["items"].as_array().unwrap().len(), 1);
    let token = page["next_page_token"].as_str().unwrap();
    let (_, rest) = app
        .get(&format!(
            "/v1/datasets/{ds}/trajectories?page_size=1&page_token={token}"
        ))
        .await;
    assert_eq!(rest["items"][0]["index"], 1);
    assert!(rest["next_page_token"].is_null());

    let model = pendulum_model(&app).await;
    let (status, r) = app
        .get(&format!(
            "/v1/models/{model}/rollout?dataset_id={ds}&index=1"
        ))
        .await;
    assert_eq!(status, 200, "{r}");
    let col = |v: &Value, k: usize| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|row| row[k].as_f64().unwrap())
            .collect()
    };
    assert_eq!(r["t"].as_array().unwrap().len(), 26);
    assert!((r["t"][25].as_f64().unwrap() - 25.0 * DT).abs() < 1e-12);
    let recorded_q = col(&r["recorded"]["q"], 0);
    let expected: Vec<f64> = second.iter().map(|x| x[0]).collect();
    assert_eq!(recorded_q, expected, "the recording as uploaded");
    // The evaluator's RK4 of the model and the simulator's of the template are different
    // code for the same map: only rounding separates them (~1e-15 a step over 25 steps).
    for key in ["q", "qdot"] {
        let (a, b) = (col(&r["recorded"][key], 0), col(&r["predicted"][key], 0));
        assert_eq!(a.len(), b.len());
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-9,
            "{key}: predicted differs from recorded by {worst:e}"
        );
    }
    // A model that is not the truth does not replay it: the check can fail.
    let t = Template::Pendulum;
    let mut heavy = t.defaults();
    heavy[0] *= 3.0; // mass: the input accelerates it a third as much
    let file = ModelFile::from_template(&t, &heavy, DT, Integrator::Rk4).unwrap();
    let r2 = app
        .client
        .post(app.url("/v1/models"))
        .body(file.to_bytes().unwrap())
        .send()
        .await
        .unwrap();
    let other = r2.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let (_, r) = app
        .get(&format!(
            "/v1/models/{other}/rollout?dataset_id={ds}&index=0"
        ))
        .await;
    let (a, b) = (col(&r["recorded"]["q"], 0), col(&r["predicted"]["q"], 0));
    assert!(a.iter().zip(&b).any(|(x, y)| (x - y).abs() > 1e-3));
}

#[tokio::test]
async fn flat_transitions_chain_into_trajectories() {
    let app = spawn_app(0).await;
    let u: Vec<f64> = vec![0.2; 10];
    let xs = recording([0.1, 0.3], &u);
    // Rows 0..10 of the recording in order, then one unrelated transition.
    let rows = |k: usize| (xs[k], u[k], xs[k + 1]);
    let mut all: Vec<Row> = (0..10).map(rows).collect();
    all.push(([2.0, 0.0], 0.0, [2.0, -0.05]));
    let field = |f: &dyn Fn(&Row) -> f64| all.iter().map(|r| [f(r)]).collect::<Vec<_>>();
    let body = json!({"dt": DT, "q": field(&|r| r.0[0]), "qdot": field(&|r| r.0[1]),
                      "u": field(&|r| r.1), "q_next": field(&|r| r.2[0]),
                      "qdot_next": field(&|r| r.2[1])});
    let ds = app.upload(&body).await;
    let (status, list) = app.get(&format!("/v1/datasets/{ds}/trajectories")).await;
    assert_eq!(status, 200, "{list}");
    assert_eq!(list["source"], "chained");
    assert_eq!(
        list["items"],
        json!([{"index": 0, "start": 0, "length": 10}, {"index": 1, "start": 10, "length": 1}])
    );
}

#[tokio::test]
async fn bad_replay_requests_name_the_field() {
    let app = spawn_app(0).await;
    let model = pendulum_model(&app).await;
    let ds = app.upload(&dataset(8, 1)).await; // n = 2: not the pendulum's
    let pendulum = app
        .upload(&json!({"dt": DT, "trajectories": [trajectory(&recording([0.0, 0.0], &[0.1]), &[0.1])]}))
        .await;
    for (path, status, field) in [
        (
            format!("/v1/models/{model}/rollout?index=0"),
            400,
            "dataset_id",
        ),
        (
            format!("/v1/models/{model}/rollout?dataset_id={pendulum}"),
            400,
            "index",
        ),
        (
            format!("/v1/models/{model}/rollout?dataset_id={pendulum}&index=-1"),
            400,
            "index",
        ),
        (
            format!("/v1/models/{model}/rollout?dataset_id={pendulum}&index=1"),
            400,
            "index",
        ),
        (
            format!("/v1/models/{model}/rollout?dataset_id={ds}&index=0"),
            400,
            "dataset_id",
        ),
        (
            format!("/v1/models/{model}/rollout?dataset_id=ds_nope&index=0"),
            404,
            "",
        ),
        (
            format!("/v1/models/mdl_nope/rollout?dataset_id={pendulum}&index=0"),
            404,
            "",
        ),
        ("/v1/datasets/ds_nope/trajectories".to_string(), 404, ""),
        (
            format!("/v1/datasets/{ds}/trajectories?page_token=zzz"),
            400,
            "page_token",
        ),
    ] {
        let (s, body) = app.get(&path).await;
        assert_eq!(s, status, "{path}: {body}");
        if !field.is_empty() {
            assert_eq!(body["error"]["field"], field, "{path}: {body}");
        }
    }
}

/// An empty trajectory (one state, no input) is refused at upload, naming it, wherever it
/// stands: first, it made a replay of index 0 wrap its index arithmetic (a 500); in the middle,
/// it replayed the trajectory before it as "recorded".
#[tokio::test]
async fn empty_trajectories_are_refused_naming_them() {
    let app = spawn_app(0).await;
    let full = trajectory(&[[0.1, 0.0], [0.1, -0.1]], &[0.0]);
    let empty = trajectory(&[[0.3, 0.0]], &[]);
    for (trajectories, field) in [
        (vec![empty.clone(), full.clone()], "trajectories[0]"),
        (
            vec![full.clone(), empty.clone(), full.clone()],
            "trajectories[1]",
        ),
    ] {
        let body = json!({"dt": DT, "trajectories": trajectories});
        let (status, refused) = app.post("/v1/datasets", &body).await;
        assert_eq!(status, 422, "{refused}");
        assert_eq!(refused["error"]["field"], field, "{refused}");
    }
    app.stop().await;
}

/// A replay is checked before its dataset's rows are read: with the rows' object gone (so
/// that reading them fails), an index out of range is still refused naming `index`; only a
/// replay that passes its checks reads them (and meets the missing object). Before, every
/// replay loaded the whole dataset first, so a hundred of them at once held a hundred copies.
#[tokio::test]
async fn a_replay_is_checked_before_its_rows_are_read() {
    let blobs = tempfile::tempdir().unwrap();
    let mut settings = test_settings();
    settings.worker.workers = 0;
    settings.worker.blobs = Some(format!("file://{}", blobs.path().display()));
    let app = spawn_configured(settings).await;
    let u = vec![0.2; 10];
    let xs = recording([0.3, 0.0], &u);
    let ds = app
        .upload(&json!({"dt": DT, "trajectories": [trajectory(&xs, &u)]}))
        .await;
    let model = pendulum_model(&app).await;
    for object in std::fs::read_dir(blobs.path().join("datasets")).unwrap() {
        std::fs::remove_file(object.unwrap().path()).unwrap();
    }
    let rollout =
        |index: usize| format!("/v1/models/{model}/rollout?dataset_id={ds}&index={index}");
    let (status, refused) = app.get(&rollout(1)).await;
    assert_eq!(
        (status, &refused["error"]["field"]),
        (400, &json!("index")),
        "{refused}"
    );
    let (status, failed) = app.get(&rollout(0)).await;
    assert_eq!(status, 500, "the read meets the missing object: {failed}");
    app.stop().await;
}
