//! A model whose configuration is not its velocities (the planar body: nq = 4, nv = 3) through
//! the service: its info says nq and nv on REST and gRPC (`n`, deprecated, is nv), Predict
//! and Rollout take states of nq + nv values and refuse others naming the field and the
//! widths, Linearize and Tvlqr answer in the 2nv-wide tangent space, and a job whose data does
//! not fit the configuration space is refused naming what it takes.

use graybox::api::grpc::pb;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use serde_json::Value;
use tonic::Code;

use crate::helpers::*;

/// The planar body made from its equations, uploaded; its id.
async fn planar_body(app: &TestApp) -> String {
    let t = Template::PlanarBody;
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
    let r = (app.client.post(app.url("/v1/models")))
        .body(file.to_bytes().unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    let body: Value = r.json().await.unwrap();
    body["id"].as_str().unwrap().to_string()
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

    // Plans are made for models whose joints are each one number, and say so.
    let e = c
        .plan(pb::PlanRequest {
            model_id: id.clone(),
            x0: states(1),
            goal: states(1),
            horizon: 5,
            q: eye(6, 1.0),
            r: eye(3, 1.0),
            qf: eye(6, 1.0),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("nq = 4 ≠ nv = 3"), "{e:?}");
    app.stop().await;
}
