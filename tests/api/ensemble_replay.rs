//! An ensemble's replay with particles: the members' spread along a recorded trajectory,
//! as Rollout streams it (the dashboard draws it as a band).

use graybox::api::grpc::pb::{self, rollout_request::Inputs};
use serde_json::{Value, json};

use crate::ensemble::upload_fixture;
use crate::helpers::*;

/// A replay with particles of an ensemble (the wb-x3 fixture, a double pendulum) carries the
/// particles' mean and spread that a gRPC Rollout with as many particles streams from the
/// same first state under the same inputs; a single model's spread is zero, and a count out
/// of range is refused naming `particles`.
#[tokio::test]
async fn a_replay_with_particles_has_the_spread_rollout_streams() {
    let mut settings = test_settings();
    settings.worker.workers = 0;
    let app = spawn_configured(settings).await;
    let (ensemble, single) = (
        upload_fixture(&app, "wb-x3").await,
        upload_fixture(&app, "wb").await,
    );
    let steps = 30;
    let row = |k: usize, a: f64| vec![a * (k as f64 * 0.2).sin(), a * (k as f64 * 0.3).cos()];
    let q: Vec<Vec<f64>> = (0..=steps).map(|k| row(k, 0.5)).collect();
    let qdot: Vec<Vec<f64>> = (0..=steps).map(|k| row(k, 2.0)).collect();
    let u: Vec<Vec<f64>> = (0..steps).map(|k| row(k, 10.0)).collect();
    let ds = app
        .upload(&json!({"dt": 0.01, "trajectories": [{"q": q, "qdot": qdot, "u": u}]}))
        .await;
    let replay = async |model: &str, particles: &str| {
        let path = format!("/v1/models/{model}/rollout?dataset_id={ds}&index=0{particles}");
        app.get(&path).await
    };
    let (status, r) = replay(&ensemble, "&particles=3").await;
    assert_eq!(status, 200, "{r}");
    let p = &r["particles"];
    assert_eq!(p["count"], 3, "{r}");
    let rows = |s: &Value| -> Vec<f64> {
        let part = |k: &str| s[k].as_array().unwrap().clone();
        (part("q").iter().zip(part("qdot")))
            .flat_map(|(q, v)| [q.as_array().unwrap().clone(), v.as_array().unwrap().clone()])
            .flatten()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let (mean, std) = (rows(&p["mean"]), rows(&p["std"]));
    assert_eq!(mean.len(), 4 * (steps + 1));
    assert!(std.iter().skip(4).all(|&s| s > 0.0), "the members differ");

    let mut c = client(&app).await;
    let req = pb::RolloutRequest {
        id: "p".into(),
        model_id: ensemble.clone(),
        x0: [q[0].clone(), qdot[0].clone()].concat(),
        inputs: Some(Inputs::U(pb::Array {
            shape: vec![steps as u64, 2],
            data: u.concat(),
        })),
        chunk: 0,
        particles: Some(3),
        dt: None,
    };
    let mut stream = c.rollout(req).await.unwrap().into_inner();
    let (mut want_mean, mut want_std) = (vec![], vec![]);
    while let Some(ch) = stream.message().await.unwrap() {
        want_mean.extend(ch.x.unwrap().data);
        want_std.extend(ch.x_std.unwrap().data);
    }
    assert!(crate::common_rel(&mean, &want_mean) < 1e-12, "{mean:?}");
    assert!(crate::common_rel(&std, &want_std) < 1e-12, "{std:?}");

    let (status, r) = replay(&single, "&particles=4").await;
    assert_eq!(status, 200, "{r}");
    // Zero but for the rounding of a mean of equal values.
    assert!(
        rows(&r["particles"]["std"]).iter().all(|&s| s < 1e-12),
        "{r}"
    );
    let (status, r) = replay(&ensemble, "").await;
    assert_eq!(status, 200, "{r}");
    assert!(r.get("particles").is_none(), "{r}");
    for bad in ["0", "1025", "-1"] {
        let (status, r) = replay(&ensemble, &format!("&particles={bad}")).await;
        assert_eq!(status, 400, "{bad}: {r}");
        assert_eq!(r["error"]["field"], "particles", "{bad}: {r}");
    }
    app.stop().await;
}
