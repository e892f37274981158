//! `bench infer --model FILE`: Predict (1 and 1024 states), Rollout (500 steps), Linearize
//! and Plan latency of any model file (a URDF robot's, a formula template's), in process; one
//! state's Predict and Linearize also through the C library (`--c-library`) and as gRPC round
//! trips; for a URDF model also Predict and Linearize on the template's assembly, the path it
//! replaced. The double pendulum figures stay the reference the targets were set against;
//! these say what a bigger model costs.

use std::path::Path;

use serde_json::json;

use super::{summary, time_calls};
use graybox::control::linalg::Mat;
use graybox::control::make_plan;
use graybox::control::plan::{Method, PlanRequest};
use graybox::error::Result;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::rng::Rng;

/// Plan steps: 1 s at Δt = 0.01.
const HORIZON: usize = 100;
/// States in a batch Predict, and steps of a rollout (under a constant input).
const BATCH: usize = 1024;
const ROLLOUT: usize = 500;

pub(super) fn figures(a: &super::BenchInferArgs, path: &Path) -> Result<()> {
    let calls = a.calls;
    let eval = Evaluator::from_file(&ModelFile::load(path)?)?;
    // The benchmarks' models are flat (nq = nv = n): states are drawn as numbers.
    let (n, m) = (eval.config.nv(), eval.config.m);
    let mut rng = Rng::new(0);
    let batch = |rows: usize, width: usize, rng: &mut Rng| -> Vec<f64> {
        (0..rows * width)
            .map(|_| rng.uniform_in(-1.0, 1.0))
            .collect()
    };
    let (xs, us) = (batch(BATCH, 2 * n, &mut rng), batch(BATCH, m, &mut rng));
    let (x1, u1) = (&xs[..2 * n], &us[..m]);
    let few = (calls / 10).max(20);
    let about = json!({"model": path.display().to_string(), "n": n, "m": m,
                       "multibody": eval.is_multibody()});
    let with = |extra: serde_json::Value| {
        let mut v = about.clone();
        v.as_object_mut()
            .expect("an object")
            .extend(extra.as_object().cloned().unwrap_or_default());
        v
    };
    let print = |name: &str, times: Vec<f64>| println!("{}", summary(name, times, with(json!({}))));
    // One state in process, through the C library and in Python, round by round.
    super::native::one_state(a, &eval, path, (x1, u1), &with)?;
    if !a.in_process_only {
        for v in super::grpc::model_round_trips(path, x1, u1, calls)? {
            println!("{}", with(v));
        }
    }
    print(
        "model_predict_1024",
        time_calls(few, || {
            std::hint::black_box(eval.predict(&xs, &us, false));
        }),
    );
    print(
        "model_rollout_500",
        time_calls(few, || {
            eval.rollout(
                x1,
                (ROLLOUT, eval.config.dt),
                |_, _| u1.to_vec(),
                |x, _| {
                    std::hint::black_box(x);
                    true
                },
            );
        }),
    );
    if eval.is_multibody() {
        // The same model on the template's assembly: what a URDF model cost before.
        let assembled = eval.clone().assembled();
        print(
            "model_predict_1_assembled",
            time_calls(few, || {
                std::hint::black_box(assembled.predict(x1, u1, false));
            }),
        );
        print(
            "model_linearize_1_assembled",
            time_calls(few.min(50), || {
                std::hint::black_box(assembled.linearize_batch(x1, u1));
            }),
        );
    }
    // From rest to every coordinate 0.5 away within the model's effort limits: a reach.
    let diag = |pos: f64, vel: f64| {
        Mat::diag(
            &(0..2 * n)
                .map(|i| if i < n { pos } else { vel })
                .collect::<Vec<_>>(),
        )
    };
    let goal = (0..2 * n).map(|i| if i < n { 0.5 } else { 0.0 }).collect();
    let weights = [diag(1.0, 0.1), Mat::diag(&vec![1e-4; m]), diag(1e3, 1e2)];
    let req = PlanRequest::new(vec![0.0; 2 * n], goal, HORIZON, weights)
        .with_effort_limits(&eval.effort_limits());
    // A model that diverges under the plan's first guess (a stiff robot at too long a step)
    // still has its other figures: the plan's is its error.
    for method in [Method::Ilqr, Method::Dircol] {
        let req = PlanRequest {
            method,
            ..req.clone()
        };
        let bench = match method {
            Method::Ilqr => "model_plan_reach_100",
            Method::Dircol => "model_plan_reach_100_dircol",
        };
        let p = match make_plan(&eval, &req, &|| false) {
            Ok(p) => p,
            Err(e) => {
                let error = json!({"bench": bench, "horizon": HORIZON, "error": e.to_string()});
                println!("{}", with(error));
                continue;
            }
        };
        let times = time_calls(10, || {
            std::hint::black_box(make_plan(&eval, &req, &|| false).expect("plans"));
        });
        let extra = json!({"horizon": HORIZON, "iterations": p.iterations,
                           "converged": p.converged, "goal_error": p.goal_error,
                           "cost": p.cost, "constraint_violation": p.constraint_violation});
        println!("{}", summary(bench, times, with(extra)));
    }
    Ok(())
}
