//! `Plan` figures: the paper's swing-up of the double pendulum (the true system as a model,
//! Δt = 0.1 s, |u| ≤ 120) over horizons of 21 and 200 steps, by iLQR and by direct
//! collocation, in process and over gRPC.

use serde_json::json;

use super::{summary, time_calls};
use graybox::api::grpc::pb::{self, dynamics_client::DynamicsClient};
use graybox::control::linalg::Mat;
use graybox::control::make_plan;
use graybox::control::plan::{Method, PlanRequest};
use graybox::error::{Error, Result};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;

pub(super) const HORIZONS: [usize; 2] = [21, 200];
const CALLS: usize = 10;

/// The true double pendulum as a model file.
pub(super) fn true_double_pendulum() -> ModelFile {
    let t = Template::DoublePendulum;
    ModelFile::from_template(&t, &t.defaults(), 0.1, Integrator::Rk4).expect("valid template model")
}

const Q: [f64; 4] = [1.0, 1.0, 0.1, 0.1];

fn swing_up(horizon: usize) -> PlanRequest {
    let weights = [
        Mat::diag(&Q),
        Mat::diag(&[1e-4; 2]),
        Mat::diag(&Q.map(|v| 1000.0 * v)),
    ];
    let goal = vec![std::f64::consts::PI, 0.0, 0.0, 0.0];
    PlanRequest {
        u_min: Some(vec![-120.0; 2]),
        u_max: Some(vec![120.0; 2]),
        ..PlanRequest::new(vec![0.0; 4], goal, horizon, weights)
    }
}

/// iLQR's figures keep their names; collocation's add `_dircol`.
fn name(prefix: &str, method: Method, h: usize) -> String {
    match method {
        Method::Ilqr => format!("{prefix}_plan_swing_up_{h}"),
        Method::Dircol => format!("{prefix}_plan_swing_up_{h}_dircol"),
    }
}

pub(super) fn in_process() -> Result<()> {
    let eval = Evaluator::from_file(&true_double_pendulum())?;
    for h in HORIZONS {
        for method in [Method::Ilqr, Method::Dircol] {
            let req = PlanRequest {
                method,
                ..swing_up(h)
            };
            let p = make_plan(&eval, &req, &|| false)?;
            let times = time_calls(CALLS, || {
                std::hint::black_box(make_plan(&eval, &req, &|| false).expect("plans"));
            });
            let extra = json!({"iterations": p.iterations, "converged": p.converged,
                               "goal_error": p.goal_error, "cost": p.cost,
                               "constraint_violation": p.constraint_violation,
                               "rollout_deviation": p.rollout_deviation});
            println!("{}", summary(&name("evaluator", method, h), times, extra));
        }
    }
    Ok(())
}

pub(super) async fn over_grpc(url: &str, model: &str) -> Result<()> {
    let mut c = DynamicsClient::connect(url.to_string())
        .await
        .map_err(|e| Error::Internal(format!("benchmark connect: {e}")))?;
    let arr = |shape: &[u64], data: Vec<f64>| {
        Some(pb::Array {
            shape: shape.to_vec(),
            data,
        })
    };
    for (h, method) in HORIZONS
        .into_iter()
        .flat_map(|h| [(h, Method::Ilqr), (h, Method::Dircol)])
    {
        let r = swing_up(h);
        let req = pb::PlanRequest {
            method: method.name().into(),
            model_id: model.into(),
            x0: r.x0,
            goal: r.goal,
            horizon: h as u64,
            q: arr(&[4, 4], r.q.data),
            r: arr(&[2, 2], r.r.data),
            qf: arr(&[4, 4], r.qf.data),
            u_min: r.u_min.unwrap_or_default(),
            u_max: r.u_max.unwrap_or_default(),
            ..Default::default()
        };
        let mut times = vec![];
        let mut last = None;
        for _ in 0..=CALLS {
            let t = std::time::Instant::now();
            let resp = c
                .plan(req.clone())
                .await
                .map_err(|s| Error::Internal(format!("benchmark plan: {s}")))?
                .into_inner();
            times.push(t.elapsed().as_secs_f64() * 1e6);
            last = Some(resp);
        }
        times.remove(0); // warm-up: the model's first load
        let p = last.expect("calls ran");
        let extra = json!({"iterations": p.iterations, "converged": p.converged,
                           "goal_error": p.goal_error,
                           "transport": "gRPC round trip on loopback, one client"});
        println!("{}", summary(&name("grpc", method, h), times, extra));
    }
    Ok(())
}
