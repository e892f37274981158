//! Predict and Rollout at a caller's step (`dt`), on gRPC and REST: at the model's own Δt the
//! same answer as without one; at another Δt the answer of the same model stored with that Δt
//! (the dynamics are continuous: only the integrator's step changes); a rollout of steps of
//! Δt/2 the predictions' chain; a Δt outside [1e-5, 10] refused naming `dt`.

use graybox::api::grpc::pb;
use graybox::api::grpc::pb::rollout_request::Inputs;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use serde_json::json;
use tonic::Code;

use crate::helpers::*;

/// The white-box double pendulum stored with Δt = `dt`; its id.
async fn pendulum(app: &TestApp, dt: f64) -> String {
    let t = Template::DoublePendulum;
    let file = ModelFile::from_template(&t, &t.defaults(), dt, Integrator::Rk4).unwrap();
    app.upload_model(&file).await
}

const X: [f64; 8] = [0.3, -0.2, 0.5, 0.1, -1.0, 0.7, 0.0, 0.4];
const U: [f64; 4] = [0.2, -0.1, 0.0, 0.3];

async fn predict(
    c: &mut graybox::api::grpc::pb::dynamics_client::DynamicsClient<tonic::transport::Channel>,
    model: &str,
    dt: Option<f64>,
) -> Result<Vec<f64>, tonic::Status> {
    let mut req = predict_req(model, 2);
    req.x = arr(&[2, 4], X.to_vec());
    req.u = arr(&[2, 2], U.to_vec());
    req.dt = dt;
    let r = c.predict(req).await?.into_inner();
    Ok(r.x_next.unwrap().data)
}

fn bits(a: &[f64]) -> Vec<u64> {
    a.iter().map(|v| v.to_bits()).collect()
}

#[tokio::test]
async fn predict_at_a_callers_step_is_the_model_at_that_step() {
    let app = spawn_app(0).await;
    let (own, other) = (pendulum(&app, 0.01).await, pendulum(&app, 0.004).await);
    let mut c = client(&app).await;
    let plain = predict(&mut c, &own, None).await.unwrap();
    assert_eq!(
        bits(&predict(&mut c, &own, Some(0.01)).await.unwrap()),
        bits(&plain)
    );
    let at = predict(&mut c, &own, Some(0.004)).await.unwrap();
    assert_eq!(
        bits(&at),
        bits(&predict(&mut c, &other, None).await.unwrap())
    );
    assert_ne!(bits(&at), bits(&plain));

    // REST: the same numbers, the step said back.
    let (status, body) = app
        .post(
            &format!("/v1/models/{own}/predict"),
            &json!({"x": [&X[..4], &X[4..]], "u": [&U[..2], &U[2..]], "dt": 0.004}),
        )
        .await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["dt"], 0.004);
    let rest: Vec<f64> = (body["x_next"].as_array().unwrap().iter())
        .flat_map(|r| r.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
        .collect();
    assert_eq!(bits(&rest), bits(&at));

    for bad in [0.0, -0.01, 1e-7, 11.0] {
        let e = predict(&mut c, &own, Some(bad)).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{bad}");
        assert!(e.message().starts_with("dt:"), "{}", e.message());
        let body = json!({"x": [&X[..4]], "u": [&U[..2]], "dt": bad});
        let (status, err) = app.post(&format!("/v1/models/{own}/predict"), &body).await;
        assert_eq!(status, 400, "{err}");
        assert_eq!(err["error"]["field"], "dt", "{err}");
    }
    app.stop().await;
}

#[tokio::test]
async fn a_rollout_at_a_callers_step_chains_its_predictions() {
    let app = spawn_app(0).await;
    let id = pendulum(&app, 0.01).await;
    let mut c = client(&app).await;
    let steps = 6;
    let req = pb::RolloutRequest {
        id: "r".into(),
        model_id: id.clone(),
        x0: X[..4].to_vec(),
        inputs: Some(Inputs::U(pb::Array {
            shape: vec![steps, 2],
            data: U[..2].repeat(steps as usize),
        })),
        chunk: 0,
        particles: None,
        dt: Some(0.005),
    };
    let mut stream = c.rollout(req).await.unwrap().into_inner();
    let mut xs = vec![];
    while let Some(chunk) = stream.message().await.unwrap() {
        xs.extend(chunk.x.unwrap().data);
    }
    assert_eq!(xs.len(), 4 * (steps as usize + 1));
    // Each state the prediction at Δt = 0.005 from the one before.
    for t in 0..steps as usize {
        let mut req = predict_req(&id, 1);
        req.x = arr(&[1, 4], xs[4 * t..4 * t + 4].to_vec());
        req.u = arr(&[1, 2], U[..2].to_vec());
        req.dt = Some(0.005);
        let next = c
            .predict(req)
            .await
            .unwrap()
            .into_inner()
            .x_next
            .unwrap()
            .data;
        assert_eq!(bits(&next), bits(&xs[4 * (t + 1)..4 * t + 8]), "step {t}");
    }

    // REST's simulate: the same states as rows.
    let u: Vec<&[f64]> = (0..steps).map(|_| &U[..2]).collect();
    let body = json!({"x0": &X[..4], "u": u, "dt": 0.005});
    let (status, r) = app.post(&format!("/v1/models/{id}/simulate"), &body).await;
    assert_eq!(status, 200, "{r}");
    let rest: Vec<f64> = (r["x"].as_array().unwrap().iter())
        .flat_map(|r| r.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
        .collect();
    assert_eq!(bits(&rest), bits(&xs));
    assert_eq!(r["max_abs_z"].as_array().unwrap().len(), steps as usize);
    let body = json!({"x0": &X[..4], "u": u, "dt": 1e300});
    let (status, err) = app.post(&format!("/v1/models/{id}/simulate"), &body).await;
    assert_eq!(
        (status, &err["error"]["field"]),
        (400, &json!("dt")),
        "{err}"
    );
    app.stop().await;
}
