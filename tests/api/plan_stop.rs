//! Issue 25: a Plan that never stopped. With no iterations (where the solver used to check
//! the caller's deadline) and 2³² − 1 restarts, two such calls held both heavy permits for
//! good: every later Predict or Plan was DEADLINE_EXCEEDED. Restarts are bounded now and
//! every pass checks the deadline at each time step; large Predict, Linearize and Tvlqr
//! calls check it between chunks.

use std::time::Duration;

use graybox::api::grpc::pb;
use graybox::control::plan::MAX_RESTARTS;
use tonic::Code;

use crate::helpers::*;

fn plan_req(model: &str, horizon: u64, max_iterations: u32, restarts: u32) -> pb::PlanRequest {
    pb::PlanRequest {
        id: String::new(),
        model_id: model.into(),
        x0: vec![0.0; 4],
        goal: vec![std::f64::consts::PI, 0.0, 0.0, 0.0],
        horizon,
        q: eye(4, 1.0),
        r: eye(2, 1e-4),
        qf: eye(4, 1000.0),
        u_min: vec![-120.0; 2],
        u_max: vec![120.0; 2],
        u_init: None,
        max_iterations: Some(max_iterations),
        tolerance: None,
        restarts,
        seed: 0,
        time_limit_ms: 0,
        ..Default::default()
    }
}

fn within<T>(message: T, secs: u64) -> tonic::Request<T> {
    let mut r = tonic::Request::new(message);
    r.set_timeout(Duration::from_secs(secs));
    r
}

/// Two of `req` at once, each with a 2 s deadline: their codes.
async fn twice(app: &TestApp, req: pb::PlanRequest) -> Vec<Code> {
    let calls = (0..2).map(|_| {
        let req = req.clone();
        async move {
            let mut c = client(app).await;
            c.plan(within(req, 2)).await.map(|_| ()).unwrap_err().code()
        }
    });
    futures_util::future::join_all(calls).await
}

fn linearize_req(model: &str, rows: u64) -> pb::LinearizeRequest {
    let rows_of = |width: u64, v: f64| arr(&[rows, width], vec![v; (rows * width) as usize]);
    pb::LinearizeRequest {
        id: String::new(),
        model_id: model.into(),
        x: rows_of(4, 0.1),
        u: rows_of(2, 1.0),
    }
}

/// Gains along the nominal at rest, `t` steps.
fn tvlqr_req(model: &str, t: u64) -> pb::TvlqrRequest {
    pb::TvlqrRequest {
        id: String::new(),
        model_id: model.into(),
        x_bar: arr(&[t + 1, 4], vec![0.0; 4 * (t as usize + 1)]),
        u_bar: arr(&[t, 2], vec![0.0; 2 * t as usize]),
        q: eye(4, 1.0),
        r: eye(2, 1.0),
        qf: eye(4, 1.0),
    }
}

/// Small calls right after: each within its 2 s deadline, so no permit is still held.
async fn small_calls_succeed(app: &TestApp, model: &str) {
    let mut c = client(app).await;
    let p = c.predict(within(predict_req(model, 64), 2)).await;
    assert!(p.is_ok(), "a 64-row Predict afterwards: {p:?}");
    let l = c.linearize(within(linearize_req(model, 64), 2)).await;
    assert!(l.is_ok(), "a 64-row Linearize afterwards: {l:?}");
    let p = c.plan(within(plan_req(model, 10, 20, 0), 2)).await;
    assert!(p.is_ok(), "a 10-step Plan afterwards: {p:?}");
}

#[tokio::test]
async fn plans_without_iterations_or_with_many_restarts_end_at_their_deadline() {
    let app = spawn_app(1).await;
    let model = trained(&app, "MVF").await;

    // The call: refused before it computes, naming the field and its limit.
    let mut c = client(&app).await;
    let e = c
        .plan(within(plan_req(&model, 100, 0, u32::MAX), 2))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message().contains("restarts") && e.message().contains(&MAX_RESTARTS.to_string()),
        "{e:?}"
    );
    let codes = twice(&app, plan_req(&model, 100, 0, u32::MAX)).await;
    assert_eq!(codes, [Code::InvalidArgument; 2]);
    small_calls_succeed(&app, &model).await;

    // Within the limits but far longer than the deadline (a thousand 10⁴-step rollouts; and
    // iLQR passes over 10⁴ steps): the deadline ends them and frees their permits.
    for iterations in [0, 200] {
        let codes = twice(&app, plan_req(&model, 10_000, iterations, 1000)).await;
        assert_eq!(
            codes,
            [Code::DeadlineExceeded; 2],
            "{iterations} iterations"
        );
        small_calls_succeed(&app, &model).await;
    }
    // Direct collocation spends its time inside QP solves, which hear the deadline too.
    let dircol = pb::PlanRequest {
        method: "dircol".into(),
        ..plan_req(&model, 2000, 200, 1000)
    };
    assert_eq!(twice(&app, dircol).await, [Code::DeadlineExceeded; 2]);
    small_calls_succeed(&app, &model).await;
    app.stop().await;
}

/// Batches that take seconds (10⁶ states ≈ 12 s here, a 3·10⁵-step Tvlqr ≈ 6 s), two at
/// once with a 2 s deadline (the Tvlqr 1 s): they give up at their next chunk after it instead
/// of holding both permits to the end. The Tvlqr's horizon is three times the default limit
/// (and within the default memory and message budgets) because a 10⁵-step one finishes in
/// 1.9 s here since Linearize got faster.
#[tokio::test]
async fn large_batches_past_their_deadline_free_their_permits() {
    let (b, t) = (1_000_000u64, 300_000u64);
    let mut settings = test_settings();
    settings.worker.workers = 1;
    settings.max_rollout_steps = t as usize;
    let app = spawn_configured(settings).await;
    let model = trained(&app, "MVF").await;
    let (lin, tv) = (linearize_req(&model, b / 4), tvlqr_req(&model, t));
    for call in ["predict", "linearize", "tvlqr"] {
        let calls = (0..2).map(|_| {
            let (app, model, lin, tv) = (&app, &model, lin.clone(), tv.clone());
            async move {
                // No decoding limit: a call that finished in time is Ok and fails below as
                // such, not as the 4 MB limit's OUT_OF_RANGE.
                let mut c = client(app).await.max_decoding_message_size(usize::MAX);
                let r = match call {
                    "predict" => c
                        .predict(within(predict_req(model, b as usize), 2))
                        .await
                        .map(|_| ()),
                    "linearize" => c.linearize(within(lin, 2)).await.map(|_| ()),
                    _ => c.tvlqr(within(tv, 1)).await.map(|_| ()),
                };
                r.unwrap_err().code()
            }
        });
        for code in futures_util::future::join_all(calls).await {
            // DEADLINE_EXCEEDED, or tonic's CANCELLED when its timer fires first (the handler's
            // clock starts after a 48 MB request is decoded).
            assert!(
                matches!(code, Code::DeadlineExceeded | Code::Cancelled),
                "{call}: {code:?}"
            );
        }
        small_calls_succeed(&app, &model).await;
    }
    app.stop().await;
}

/// `max_iterations = 0` is honoured: the initial guess's rollout with its gains.
#[tokio::test]
async fn zero_iterations_return_the_initial_guess_with_its_gains() {
    let app = spawn_app(1).await;
    let model = trained(&app, "MVF").await;
    let mut c = client(&app).await;
    let p = c
        .plan(within(plan_req(&model, 20, 0, 0), 30))
        .await
        .unwrap()
        .into_inner();
    assert_eq!((p.iterations, p.costs.len(), p.converged), (0, 1, false));
    assert_eq!(p.costs[0], p.cost);
    assert!(p.u.unwrap().data.iter().all(|u| *u == 0.0));
    assert_eq!(p.k.unwrap().shape, vec![20, 2, 4]);
    assert_eq!(p.x.unwrap().shape, vec![21, 4]);
    app.stop().await;
}

/// Issue 72: plans held both heavy permits for their whole solve, and every Predict of 5 or
/// more states waited behind them until its deadline. Short calls have a class of their own
/// now: while two long collocation plans hold the long class, a controller's 16-state
/// Predict, Linearize and a 50-step Tvlqr answer within their deadline.
#[tokio::test]
async fn short_calls_answer_while_plans_hold_the_long_class() {
    let app = spawn_app(1).await;
    let model = trained(&app, "MVF").await;
    let long = app.running.as_ref().unwrap().app.long_calls.clone();
    let dircol = pb::PlanRequest {
        method: "dircol".into(),
        ..plan_req(&model, 2000, 200, 1000)
    };
    let mut plans = Vec::new();
    for _ in 0..2 {
        let (mut c, req) = (client(&app).await, dircol.clone());
        plans.push(tokio::spawn(async move { c.plan(within(req, 60)).await }));
    }
    while long.busy() < 2 {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let mut c = client(&app).await;
    let p = c.predict(within(predict_req(&model, 16), 10)).await;
    assert!(p.is_ok(), "a 16-state Predict beside two plans: {p:?}");
    let l = c.linearize(within(linearize_req(&model, 16), 10)).await;
    assert!(l.is_ok(), "a 16-state Linearize beside two plans: {l:?}");
    let g = c.tvlqr(within(tvlqr_req(&model, 50), 10)).await;
    assert!(g.is_ok(), "a 50-step Tvlqr beside two plans: {g:?}");
    // The plans were still computing: the short calls did not wait for them to end.
    assert_eq!(long.busy(), 2);
    for plan in plans {
        plan.abort();
    }
    app.stop().await;
}
