//! gRPC `Dynamics` end to end: trained models served over a real channel.

use graybox::api::grpc::pb::dynamics_client::DynamicsClient;
use graybox::api::grpc::pb::{self, rollout_request::Inputs};
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

fn arr(shape: &[u64], data: Vec<f64>) -> Option<pb::Array> {
    Some(pb::Array {
        shape: shape.to_vec(),
        data,
    })
}

async fn trained(app: &TestApp, model: &str, epochs: usize) -> (String, Value) {
    let ds = app.upload(&dataset(256, 31)).await;
    let body = json!({"dataset_id": ds, "model": model, "template": "double_pendulum",
                      "training": {"epochs": epochs, "batch_size": 64, "lr": 0.01}});
    let (_, job) = app.post("/v1/jobs", &body).await;
    let done = app
        .wait_job(job["id"].as_str().unwrap(), 120, final_state)
        .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let mid = done["model_id"].as_str().unwrap().to_string();
    let (_, info) = app.get(&format!("/v1/models/{mid}")).await;
    (mid, info)
}

/// The paper's double pendulum written out in the test (common::double_pendulum_accel) and
/// an RK4 of its own: a W-B Rollout must follow it to rounding.
fn reference_rollout(p: &[f64; 9], x0: &[f64], us: &[Vec<f64>], dt: f64) -> Vec<Vec<f64>> {
    let f = |x: &[f64], u: &[f64]| -> Vec<f64> {
        let a = super::common_dp(p, &x[..2], &x[2..], u);
        vec![x[2], x[3], a[0], a[1]]
    };
    let mut xs = vec![x0.to_vec()];
    for u in us {
        let x = xs.last().unwrap().clone();
        let k1 = f(&x, u);
        let at = |k: &[f64], h: f64| x.iter().zip(k).map(|(a, b)| a + h * b).collect::<Vec<_>>();
        let k2 = f(&at(&k1, dt / 2.0), u);
        let k3 = f(&at(&k2, dt / 2.0), u);
        let k4 = f(&at(&k3, dt), u);
        xs.push(
            (0..4)
                .map(|i| x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
                .collect(),
        );
    }
    xs
}

#[tokio::test]
async fn dynamics_rpcs_against_independent_references() {
    let app = spawn_app(1).await;
    let (wb, info) = trained(&app, "W-B", 2).await;
    let (mvf, _) = trained(&app, "MVF", 1).await;
    let addr = format!("http://{}", app.running.as_ref().unwrap().grpc_addr);
    let mut c = DynamicsClient::connect(addr.clone()).await.unwrap();

    // Rollout of the white-box model vs the closed form with its learned parameters.
    let pp = &info["physical_parameters"];
    let names = ["m1", "m2", "l1", "l2", "g", "b1", "b2", "eta1", "eta2"];
    let p: [f64; 9] = std::array::from_fn(|i| pp[names[i]].as_f64().unwrap());
    let steps = 120;
    let us: Vec<Vec<f64>> = (0..steps)
        .map(|t| vec![20.0 * (t as f64 * 0.1).sin(), -10.0])
        .collect();
    let x0 = vec![0.4, -0.2, 1.0, 0.5];
    let req = pb::RolloutRequest {
        id: "r1".into(),
        model_id: wb.clone(),
        x0: x0.clone(),
        inputs: Some(Inputs::U(pb::Array {
            shape: vec![steps as u64, 2],
            data: us.concat(),
        })),
        chunk: 50,
        particles: None,
        dt: None,
    };
    let mut stream = c.rollout(req).await.unwrap().into_inner();
    let mut got: Vec<f64> = vec![];
    let mut chunks = 0;
    while let Some(ch) = stream.message().await.unwrap() {
        assert_eq!(ch.id, "r1");
        assert_eq!(ch.start as usize, got.len() / 4);
        got.extend(ch.x.unwrap().data);
        chunks += 1;
    }
    assert!(chunks >= 3);
    let want = reference_rollout(&p, &x0, &us, 0.01).concat();
    assert_eq!(got.len(), want.len());
    assert!(
        super::common_rel(&got, &want) < 1e-9,
        "rollout differs: {:e}",
        super::common_rel(&got, &want)
    );

    // Linearize vs central differences of Predict (h = 1e-6).
    for model in [&wb, &mvf] {
        let x = vec![0.3, -0.6, 2.0, -1.0];
        let u = vec![15.0, -40.0];
        let lin = c
            .linearize(pb::LinearizeRequest {
                id: "l".into(),
                model_id: model.clone(),
                x: arr(&[1, 4], x.clone()),
                u: arr(&[1, 2], u.clone()),
            })
            .await
            .unwrap()
            .into_inner();
        let (a, b) = (lin.a.unwrap(), lin.b.unwrap());
        assert_eq!(
            (a.shape.clone(), b.shape.clone()),
            (vec![1, 4, 4], vec![1, 4, 2])
        );
        let h = 1e-6;
        let mut fd = vec![0.0; 4 * 6];
        for k in 0..6 {
            let (mut xp, mut xm, mut up, mut um) = (x.clone(), x.clone(), u.clone(), u.clone());
            if k < 4 {
                xp[k] += h;
                xm[k] -= h
            } else {
                up[k - 4] += h;
                um[k - 4] -= h
            }
            let pred = |xx: Vec<f64>, uu: Vec<f64>| {
                let mut c = c.clone();
                async move {
                    let r = pb::PredictRequest {
                        id: "p".into(),
                        model_id: model.clone(),
                        x: arr(&[1, 4], xx),
                        u: arr(&[1, 2], uu),
                        want_accel: false,
                        members: false,
                        dt: None,
                    };
                    c.predict(r)
                        .await
                        .unwrap()
                        .into_inner()
                        .x_next
                        .unwrap()
                        .data
                }
            };
            let (fp, fm) = (pred(xp, up).await, pred(xm, um).await);
            for r in 0..4 {
                fd[r * 6 + k] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        let ours: Vec<f64> = (0..4)
            .flat_map(|r| (0..6).map(move |k| (r, k)))
            .map(|(r, k)| {
                if k < 4 {
                    a.data[r * 4 + k]
                } else {
                    b.data[r * 2 + k - 4]
                }
            })
            .collect();
        assert!(
            super::common_rel(&ours, &fd) < 1e-6,
            "linearization vs FD: {:e}",
            super::common_rel(&ours, &fd)
        );
    }

    // TVLQR vs a Riccati recursion on the service's own Linearize output.
    let t = 20usize;
    let xbar: Vec<f64> = (0..=t)
        .flat_map(|i| vec![0.1 * i as f64, -0.05 * i as f64, 0.3, -0.2])
        .collect();
    let ubar: Vec<f64> = (0..t).flat_map(|i| vec![5.0 + i as f64, -3.0]).collect();
    let eye = |n: usize, s: f64| {
        (0..n * n)
            .map(|k| if k / n == k % n { s } else { 0.0 })
            .collect::<Vec<f64>>()
    };
    let resp = c
        .tvlqr(pb::TvlqrRequest {
            id: "t".into(),
            model_id: mvf.clone(),
            x_bar: arr(&[t as u64 + 1, 4], xbar.clone()),
            u_bar: arr(&[t as u64, 2], ubar.clone()),
            q: arr(&[4, 4], eye(4, 1.0)),
            r: arr(&[2, 2], eye(2, 0.01)),
            qf: arr(&[4, 4], eye(4, 10.0)),
        })
        .await
        .unwrap()
        .into_inner();
    let lin = c
        .linearize(pb::LinearizeRequest {
            id: "l".into(),
            model_id: mvf.clone(),
            x: arr(&[t as u64, 4], xbar[..4 * t].to_vec()),
            u: arr(&[t as u64, 2], ubar.clone()),
        })
        .await
        .unwrap()
        .into_inner();
    let (ad, bd) = (lin.a.unwrap().data, lin.b.unwrap().data);
    let k_ref = super::riccati(
        &ad,
        &bd,
        t,
        4,
        2,
        &eye(4, 1.0),
        &eye(2, 0.01),
        &eye(4, 10.0),
    );
    let k = resp.k.unwrap();
    assert_eq!(k.shape, vec![t as u64, 2, 4]);
    assert!(
        super::common_rel(&k.data, &k_ref) < 1e-8,
        "{:e}",
        super::common_rel(&k.data, &k_ref)
    );

    // Status codes.
    let bad = |model: &str, x: Vec<f64>, shape: &[u64]| pb::PredictRequest {
        id: "b".into(),
        model_id: model.into(),
        x: arr(shape, x),
        u: arr(&[1, 2], vec![0.0, 0.0]),
        want_accel: false,
        members: false,
        dt: None,
    };
    let code =
        |r: Result<tonic::Response<pb::PredictResponse>, tonic::Status>| r.unwrap_err().code();
    assert_eq!(
        code(c.predict(bad("mdl_nope", vec![0.0; 4], &[1, 4])).await),
        Code::NotFound
    );
    let wrong_width = c
        .predict(bad(&wb, vec![0.0; 3], &[1, 3]))
        .await
        .unwrap_err();
    assert_eq!(wrong_width.code(), Code::InvalidArgument);
    // The message says what a row of x is, not only its width.
    assert!(
        wrong_width.message().contains("x = [q, v]: nq + nv"),
        "{}",
        wrong_width.message()
    );
    assert_eq!(
        code(
            c.predict(bad(&wb, vec![0.0, f64::NAN, 0.0, 0.0], &[1, 4]))
                .await
        ),
        Code::InvalidArgument
    );
    assert_eq!(
        code(c.predict(bad(&wb, vec![0.0; 8], &[2, 4])).await),
        Code::InvalidArgument,
        "x and u row counts differ"
    );
    let ds = app.upload(&dataset(32, 77)).await;
    let (_, queued) = app
        .post(
            "/v1/jobs",
            &json!({"dataset_id": ds, "model": "MVF", "training": {"epochs": 100000}}),
        )
        .await;
    assert_eq!(
        code(
            c.predict(bad(queued["id"].as_str().unwrap(), vec![0.0; 4], &[1, 4]))
                .await
        ),
        Code::FailedPrecondition
    );
    let long = pb::RolloutRequest {
        id: "x".into(),
        model_id: wb.clone(),
        x0: x0.clone(),
        inputs: Some(Inputs::U(pb::Array {
            shape: vec![200_001, 2],
            data: vec![0.0; 400_002],
        })),
        chunk: 0,
        particles: None,
        dt: None,
    };
    assert_eq!(
        c.rollout(long).await.unwrap_err().code(),
        Code::ResourceExhausted
    );
    let tv = pb::TvlqrRequest {
        id: "t".into(),
        model_id: wb.clone(),
        x_bar: arr(&[2, 4], vec![0.0; 8]),
        u_bar: arr(&[1, 2], vec![0.0; 2]),
        q: arr(&[4, 4], eye(4, 1.0)),
        r: arr(&[2, 2], eye(2, -1.0)),
        qf: arr(&[4, 4], eye(4, 1.0)),
    };
    assert_eq!(
        c.tvlqr(tv.clone()).await.unwrap_err().code(),
        Code::InvalidArgument,
        "R not positive definite"
    );
    let small_q = pb::TvlqrRequest {
        q: arr(&[2, 4], vec![0.0; 8]),
        ..tv
    };
    let err = c.tvlqr(small_q).await.unwrap_err();
    assert!(err.message().contains("2nv × 2nv"), "{}", err.message());
    let info = c
        .get_model(pb::GetModelRequest {
            model_id: wb.clone(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        (info.n, info.nq, info.nv, info.m, info.name.as_str()),
        (2, 2, 2, 2, "W-B")
    );
    assert!(
        c.list_models(pb::ListModelsRequest::default())
            .await
            .unwrap()
            .into_inner()
            .models
            .len()
            >= 2
    );

    // Health answers SERVING.
    let channel = tonic::transport::Endpoint::from_shared(addr)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let mut h = tonic_health::pb::health_client::HealthClient::new(channel);
    let s = h
        .check(tonic_health::pb::HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        s.status,
        tonic_health::pb::health_check_response::ServingStatus::Serving as i32
    );
    app.post(
        &format!("/v1/jobs/{}/cancel", queued["id"].as_str().unwrap()),
        &json!({}),
    )
    .await;
    app.stop().await;
}

/// A model that was never trained: `graybox model`'s file uploaded over REST (201, then 200
/// for the same file), served over gRPC exactly as the file's own evaluator computes it, and
/// refused with a 422 naming the body when it is not a usable model file.
#[tokio::test]
async fn uploaded_models_are_served_like_trained_ones() {
    use graybox::infer::Evaluator;
    use graybox::model::file::ModelFile;
    use graybox::physics::integrator::Integrator;
    use graybox::physics::templates::Template;

    let app = spawn_app(0).await;
    let t = Template::DoublePendulum;
    let file = ModelFile::from_template(&t, &t.defaults(), 0.05, Integrator::Rk4).unwrap();
    let bytes = file.to_bytes().unwrap();
    let post = |body: Vec<u8>| {
        app.client
            .post(app.url("/v1/models?name=true-dp"))
            .header("content-type", "application/octet-stream")
            .body(body)
            .send()
    };
    let r = post(bytes.clone()).await.unwrap();
    assert_eq!(r.status().as_u16(), 201);
    let model: Value = r.json().await.unwrap();
    assert_eq!(
        (model["origin"].as_str(), &model["job_id"]),
        (Some("uploaded"), &Value::Null)
    );
    assert_eq!(model["name"], "true-dp");
    assert_eq!(model["physical_parameters"]["m1"], 10.0, "{model}");
    assert_eq!(
        model["metrics"]["made"]["template"], "double_pendulum",
        "{model}"
    );
    assert_eq!(
        model["metrics"]["epochs"],
        Value::Null,
        "no training, no losses"
    );
    let again = post(bytes.clone()).await.unwrap();
    assert_eq!(again.status().as_u16(), 200);
    let same: Value = again.json().await.unwrap();
    assert_eq!(same["id"], model["id"]);
    // The stored file is the uploaded file.
    let id = model["id"].as_str().unwrap();
    assert_eq!(app.model_file(id).await, bytes);

    let addr = format!("http://{}", app.running.as_ref().unwrap().grpc_addr);
    let mut c = DynamicsClient::connect(addr).await.unwrap();
    let x = vec![0.3, -0.2, 0.5, 1.0, 1.0, 2.0, -1.0, 0.0];
    let u = vec![10.0, -5.0, 0.0, 20.0];
    let got = c
        .predict(pb::PredictRequest {
            model_id: id.into(),
            x: Some(pb::Array {
                shape: vec![2, 4],
                data: x.clone(),
            }),
            u: Some(pb::Array {
                shape: vec![2, 2],
                data: u.clone(),
            }),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let want = Evaluator::from_file(&file)
        .unwrap()
        .predict(&x, &u, false)
        .0;
    assert_eq!(got.x_next.unwrap().data, want);

    // Edits of the file without its checksum (as a file from before checksums is): the checks
    // of what it holds refuse them, where the checksum would refuse any edit first.
    let mut unchecked: Value = serde_json::from_slice(&bytes).unwrap();
    unchecked.as_object_mut().unwrap().remove("checksum");
    let bytes = serde_json::to_vec(&unchecked).unwrap();
    for (bad, says) in [
        (b"not json".to_vec(), "model file"),
        (
            String::from_utf8(bytes.clone())
                .unwrap()
                .replace("\"physical_values\"", "\"physics\"")
                .into_bytes(),
            "physical",
        ),
        (
            String::from_utf8(bytes.clone())
                .unwrap()
                .replace("\"dt\":0.05", "\"dt\":-1")
                .into_bytes(),
            "dt",
        ),
        (
            String::from_utf8(bytes.clone())
                .unwrap()
                .replace("\"q_std\":[1.0,1.0]", "\"q_std\":[0.0,1.0]")
                .into_bytes(),
            "scaling",
        ),
    ] {
        let r = post(bad).await.unwrap();
        assert_eq!(r.status().as_u16(), 422);
        let e: Value = r.json().await.unwrap();
        assert_eq!(e["error"]["field"], "body", "{e}");
        assert!(
            e["error"]["message"].as_str().unwrap().contains(says),
            "{e}"
        );
    }
    app.stop().await;
}
