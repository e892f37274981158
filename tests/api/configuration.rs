//! A model whose configuration is not its velocities (the planar body: nq = 4, nv = 3) through
//! the service: its info says nq and nv on REST and gRPC (`n`, deprecated, is nv), Predict
//! and Rollout take states of nq + nv values and refuse others naming the field and the
//! widths, Linearize, Tvlqr and Plan answer in the 2nv-wide tangent space, its data trains a
//! white-box model of it, and a job whose data does not fit the configuration space is refused
//! naming what it takes.

use graybox::api::grpc::pb;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

/// The planar body made from its equations, uploaded; its id.
async fn planar_body(app: &TestApp) -> String {
    let t = Template::PlanarBody;
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
    app.upload_model(&file).await
}

/// [x, y, cos θ, sin θ, ẋ, ẏ, ω] for b states.
fn states(b: usize) -> Vec<f64> {
    (0..b)
        .flat_map(|k| {
            let th = 0.4 * k as f64;
            [0.1, -0.2, th.cos(), th.sin(), 0.5, 0.0, 1.0]
        })
        .collect()
}

#[tokio::test]
async fn a_model_of_nq_4_and_nv_3_answers_in_its_widths() {
    let app = spawn_app(0).await;
    let id = planar_body(&app).await;
    let (status, info) = app.get(&format!("/v1/models/{id}")).await;
    assert_eq!(status, 200, "{info}");
    assert_eq!(
        (&info["nq"], &info["nv"], &info["n"]),
        (&4.into(), &3.into(), &3.into())
    );
    let mut c = client(&app).await;
    let got = c
        .get_model(pb::GetModelRequest {
            model_id: id.clone(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!((got.nq, got.nv, got.n, got.m), (4, 3, 3, 3));

    // Predict: states of 7, accelerations of 3; 6 values a row is refused naming both.
    let p = c
        .predict(pb::PredictRequest {
            model_id: id.clone(),
            x: arr(&[2, 7], states(2)),
            u: arr(&[2, 3], vec![1.0; 6]),
            want_accel: true,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(p.x_next.as_ref().unwrap().shape, vec![2, 7]);
    assert_eq!(p.accel.unwrap().shape, vec![2, 3]);
    let next = p.x_next.unwrap().data;
    for row in next.chunks(7) {
        // A heading stays a unit complex number through a step.
        assert!((row[2].hypot(row[3]) - 1.0).abs() < 1e-12, "{row:?}");
    }
    let e = c
        .predict(pb::PredictRequest {
            model_id: id.clone(),
            x: arr(&[1, 6], vec![0.0; 6]),
            u: arr(&[1, 3], vec![0.0; 3]),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(
        e.message().starts_with("x:") && e.message().contains("nq + nv"),
        "{e:?}"
    );

    // Linearize and Tvlqr in the tangent space: 6 × 6 and 6 × 3; K is 3 × 6.
    let l = c
        .linearize(pb::LinearizeRequest {
            model_id: id.clone(),
            x: arr(&[2, 7], states(2)),
            u: arr(&[2, 3], vec![1.0; 6]),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(l.a.unwrap().shape, vec![2, 6, 6]);
    assert_eq!(l.b.unwrap().shape, vec![2, 6, 3]);
    let t = 5;
    let g = c
        .tvlqr(pb::TvlqrRequest {
            model_id: id.clone(),
            x_bar: arr(&[t + 1, 7], states(t as usize + 1)),
            u_bar: arr(&[t, 3], vec![0.0; 3 * t as usize]),
            q: eye(6, 1.0),
            r: eye(3, 1.0),
            qf: eye(6, 1.0),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(g.k.unwrap().shape, vec![t, 3, 6]);
    assert_eq!(g.s.unwrap().shape, vec![t + 1, 6, 6]);

    // Plans by either method: states of 7, gains on the 6-wide tangent; a Q of the state's
    // width is refused naming Q and the tangent's.
    let plan = |method: &str, q: usize| pb::PlanRequest {
        model_id: id.clone(),
        x0: states(1),
        goal: states(2)[7..].to_vec(),
        horizon: 5,
        q: eye(q, 1.0),
        r: eye(3, 1.0),
        qf: eye(q, 1.0),
        method: method.into(),
        ..Default::default()
    };
    for method in ["ilqr", "dircol"] {
        let p = c.plan(plan(method, 6)).await.unwrap().into_inner();
        assert_eq!(p.x.as_ref().unwrap().shape, vec![6, 7], "{method}");
        assert_eq!(p.k.unwrap().shape, vec![5, 3, 6], "{method}");
        for row in p.x.unwrap().data.chunks(7) {
            assert!(
                (row[2].hypot(row[3]) - 1.0).abs() < 1e-9,
                "{method}: {row:?}"
            );
        }
    }
    let e = c.plan(plan("ilqr", 7)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message().starts_with("Q:") && e.message().contains("6×6"),
        "{e:?}"
    );
    app.stop().await;
}

/// Data of the planar body (simulated: q 4 wide, qdot 3) trains a white-box model of it;
/// a dataset whose rows disagree is refused naming the field, and data of another space
/// (the double pendulum's) naming what the planar body takes.
#[tokio::test]
async fn the_planar_body_trains_from_data_of_its_widths() {
    let app = spawn_app(1).await;
    let t = Template::PlanarBody;
    let sim = SimConfig {
        count: 128,
        seed: 7,
        ..SimConfig::default()
    };
    let data = simulate(&t, t.defaults(), &sim).unwrap();
    let body: Value = serde_json::from_str(&data.to_json()).unwrap();
    let ds = app.upload(&body).await;
    let (_, info) = app.get(&format!("/v1/datasets/{ds}")).await;
    assert_eq!((&info["nq"], &info["nv"]), (&4.into(), &3.into()), "{info}");
    let job = |dataset: &str| {
        json!({"dataset_id": dataset, "model": "W-B", "template": "planar_body",
               "training": {"epochs": 1, "batch_size": 64}})
    };
    let (_, submitted) = app.post("/v1/jobs", &job(&ds)).await;
    let done = app
        .wait_job(submitted["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let (_, model) = app
        .get(&format!(
            "/v1/models/{}",
            done["model_id"].as_str().unwrap()
        ))
        .await;
    assert_eq!(
        (&model["nq"], &model["nv"]),
        (&4.into(), &3.into()),
        "{model}"
    );

    // q_next one value short of q in every row.
    let mut short = body.clone();
    for row in short["q_next"].as_array_mut().unwrap() {
        row.as_array_mut().unwrap().pop();
    }
    let (s, e) = app.post("/v1/datasets", &short).await;
    assert_eq!(
        (s, e["error"]["field"].as_str()),
        (400, Some("q_next")),
        "{e}"
    );

    let pendulum = app.upload(&dataset(64, 1)).await;
    let (s, e) = app.post("/v1/jobs", &job(&pendulum)).await;
    assert_eq!(
        (s, e["error"]["field"].as_str()),
        (422, Some("dataset_id")),
        "{e}"
    );
    let message = e["error"]["message"].as_str().unwrap();
    assert!(message.contains("nq = 4, nv = 3"), "{message}");
    app.stop().await;
}
