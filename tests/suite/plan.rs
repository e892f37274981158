//! Trajectory optimisation (`control::plan`) against independent references: the paper's
//! double-pendulum swing-up tracked on a closed-form RK4 written here, and a linear-quadratic
//! problem solved by batch least squares.

use crate::common;
#[path = "plan/ensemble.rs"]
mod ensemble;
#[path = "plan/x_init.rs"]
mod x_init;

use graybox::control::linalg::Mat;
use graybox::control::plan::{Dynamics, Plan, PlanRequest, plan};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;

use common::plans::{
    batch_least_squares, diag, linear_model, linear_request, swing_up, track_swing_up,
    true_double_pendulum,
};

fn assert_costs_never_increase(p: &Plan) {
    for w in p.costs.windows(2) {
        assert!(w[1] <= w[0], "costs increased: {:?}", p.costs);
    }
    assert_eq!(*p.costs.last().unwrap(), p.cost);
}

#[test]
fn swing_up_reaches_the_top_and_its_gains_track_the_true_system() {
    let eval = true_double_pendulum();
    let req = swing_up(21);
    let p = plan(&eval, &req, &|| false).unwrap();
    let end = &p.x[21 * 4..];
    // The bounds: within 0.05 rad and 0.2 rad/s of (π, 0, 0, 0) on the model.
    for i in 0..2 {
        assert!(
            (end[i] - req.goal[i]).abs() < 0.05,
            "end {end:?}, {} iterations",
            p.iterations
        );
        assert!(end[2 + i].abs() < 0.2, "end {end:?}");
    }
    assert_costs_never_increase(&p);
    assert!(
        p.u.iter().all(|u| u.abs() <= 120.0),
        "an input leaves the bounds"
    );
    assert!(
        (p.goal_error
            - end
                .iter()
                .zip(&req.goal)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt())
        .abs()
            < 1e-12
    );

    // Tracking with the plan's own gains on the reference system from a perturbed start.
    let start: Vec<f64> = p.x[..4].iter().map(|v| v + 0.01).collect();
    let x = track_swing_up(&p, &start);
    for i in 0..2 {
        assert!((x[i] - req.goal[i]).abs() < 0.1, "tracked end {x:?}");
        assert!(x[2 + i].abs() < 0.5, "tracked end {x:?}");
    }
}

/// A model whose RK4 map is linear (constant M, quadratic V, constant-affine F: no Coriolis
/// term): iLQR must equal the batch least-squares optimum and converge at once.
#[test]
fn linear_quadratic_plan_equals_batch_least_squares() {
    let eval = linear_model(0.05);
    let req = linear_request(12);
    let p = plan(&eval, &req, &|| false).unwrap();
    assert!(
        p.converged && p.iterations <= 2,
        "{} iterations",
        p.iterations
    );
    let u = batch_least_squares(&eval, &req);
    let scale = u.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    for (got, want) in p.u.iter().zip(&u) {
        // 1e-8 of the inputs' scale: the two solutions differ by rounding in ~10³ operations.
        assert!((got - want).abs() <= 1e-8 * scale, "{got} vs {want}");
    }
}

#[test]
fn a_time_limit_returns_the_best_so_far() {
    let eval = true_double_pendulum();
    let mut req = swing_up(200);
    req.restarts = 3;
    req.time_limit = Some(std::time::Instant::now());
    let p = plan(&eval, &req, &|| false).unwrap();
    assert!(!p.converged);
    assert!(p.x.iter().chain(&p.u).all(|v| v.is_finite()));
    assert_eq!(p.x.len(), 201 * 4);
}

#[test]
fn bad_requests_name_their_field() {
    let eval = true_double_pendulum();
    let field = |f: &dyn Fn(&mut PlanRequest)| {
        let mut req = swing_up(5);
        f(&mut req);
        match plan(&eval, &req, &|| false) {
            Err(graybox::error::Error::Invalid { field, .. }) => field,
            other => panic!("expected an invalid-argument error, got {other:?}"),
        }
    };
    assert_eq!(field(&|r| r.x0 = vec![0.0; 3]), "x0");
    assert_eq!(field(&|r| r.goal[1] = f64::NAN), "goal");
    assert_eq!(field(&|r| r.horizon = 0), "horizon");
    assert_eq!(field(&|r| r.q.data[0] = -1.0), "Q");
    assert_eq!(field(&|r| r.r.data[3] = 0.0), "R");
    assert_eq!(field(&|r| r.u_min = Some(vec![200.0, 0.0])), "u_min");
    assert_eq!(field(&|r| r.u_init = Some(Mat::zeros(1, 3))), "u_init");
    // The right number of values in the wrong shape is refused too (not read as [T, m]).
    assert_eq!(field(&|r| r.u_init = Some(Mat::zeros(2, 5))), "u_init");
    let mut nan = Mat::zeros(5, 2);
    nan.data[3] = f64::NAN;
    assert_eq!(field(&|r| r.u_init = Some(nan.clone())), "u_init");
}

/// A long horizon of an unstable system (20 s of the double pendulum): the backward pass's
/// regularization must keep it solvable (see `control::plan`).
#[test]
fn a_long_swing_up_converges_too() {
    let eval = true_double_pendulum();
    let p = plan(&eval, &swing_up(200), &|| false).unwrap();
    assert!(p.converged, "{} iterations, cost {}", p.iterations, p.cost);
    assert!(p.goal_error < 0.01, "goal error {}", p.goal_error);
    assert_costs_never_increase(&p);
}

/// The true double pendulum, counting the time steps it is asked for.
struct Counting {
    eval: Evaluator,
    steps: std::cell::Cell<usize>,
}

impl Dynamics for Counting {
    fn nx(&self) -> usize {
        self.eval.nx()
    }
    fn m(&self) -> usize {
        self.eval.m()
    }
    fn step(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        self.steps.set(self.steps.get() + 1);
        self.eval.step(x, u)
    }
    fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        self.eval.linearize(x, u)
    }
}

/// Issue 25: `stop` used to be polled once per iteration only, so a request with no
/// iterations and many restarts never heard it. Now it is polled at least once per time step
/// of every pass (rollouts, line searches, restarts), and a plan it stops ends as cancelled.
#[test]
fn stop_is_polled_at_every_time_step_of_every_pass() {
    let sys = Counting {
        eval: true_double_pendulum(),
        steps: Default::default(),
    };
    for (max_iterations, restarts) in [(0, 50), (5, 2)] {
        let req = PlanRequest {
            max_iterations,
            restarts,
            ..swing_up(40)
        };
        sys.steps.set(0);
        let (last, gap) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
        let record = || {
            let steps = sys.steps.get();
            gap.set(gap.get().max(steps - last.get()));
            last.set(steps);
        };
        plan(&sys, &req, &|| {
            record();
            false
        })
        .unwrap();
        record();
        assert!(sys.steps.get() > 40 * restarts);
        assert_eq!(
            gap.get(),
            1,
            "{max_iterations} iterations, {restarts} restarts"
        );

        for stop_at in [1, 2, 41, 300] {
            let polls = std::cell::Cell::new(0);
            let stop = || {
                polls.set(polls.get() + 1);
                polls.get() >= stop_at
            };
            match plan(&sys, &req, &stop) {
                Err(graybox::error::Error::Cancelled) => {}
                other => panic!("stop at poll {stop_at}: {:?}", other.map(|p| p.iterations)),
            }
        }
    }
}

/// No iterations: the plan is the initial guess's rollout with its gains; restarts are
/// bounded and max_iterations 0 with restarts is the best of the random starts.
#[test]
fn zero_iterations_and_the_restarts_limit() {
    let eval = true_double_pendulum();
    let req = PlanRequest {
        max_iterations: 0,
        ..swing_up(30)
    };
    let p = plan(&eval, &req, &|| false).unwrap();
    assert_eq!((p.iterations, p.costs.len(), p.converged), (0, 1, false));
    assert!(p.u.iter().all(|u| *u == 0.0));
    assert_eq!(p.gains.k.len(), 30);
    let shot = plan(
        &eval,
        &PlanRequest {
            restarts: 20,
            ..req.clone()
        },
        &|| false,
    )
    .unwrap();
    assert!(shot.cost <= p.cost && shot.iterations == 0);

    let too_many = PlanRequest {
        restarts: graybox::control::plan::MAX_RESTARTS + 1,
        ..req
    };
    match plan(&eval, &too_many, &|| false) {
        Err(graybox::error::Error::Invalid { field, message }) => {
            assert_eq!(field, "restarts");
            assert!(message.contains("1000"), "{message}");
        }
        other => panic!("expected restarts refused, got {:?}", other.map(|p| p.cost)),
    }
}

/// x′ = 10¹⁰⁰ x + u on the first coordinate: finite Jacobians, states that overflow f64 at
/// step 4 from x0 = (1, 0).
struct Exploding;

impl Dynamics for Exploding {
    fn nx(&self) -> usize {
        2
    }
    fn m(&self) -> usize {
        1
    }
    fn step(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        x.chunks(2)
            .zip(u)
            .flat_map(|(x, u)| [1e100 * x[0] + u, x[1]])
            .collect()
    }
    fn linearize(&self, x: &[f64], _u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        let t = x.len() / 2;
        let a = Mat::new(2, 2, vec![1e100, 0.0, 0.0, 1.0]);
        let b = Mat::new(2, 1, vec![1.0, 0.0]);
        (vec![a; t], vec![b; t])
    }
}

fn refused(result: graybox::error::Result<Plan>) -> (String, String) {
    match result {
        Err(graybox::error::Error::Invalid { field, message }) => (field, message),
        other => panic!("expected a refusal, got {:?}", other.map(|p| p.cost)),
    }
}

/// Issue 26: a trajectory that went non-finite used to be blamed on R ("R + BᵀSB lost
/// positive definiteness"); the error names x0 and the step where the state overflowed.
#[test]
fn a_diverging_plan_names_the_step_where_the_state_went_non_finite() {
    let req = PlanRequest {
        restarts: 2,
        ..PlanRequest::new(
            vec![1.0, 0.0],
            vec![0.0; 2],
            6,
            [diag(&[1.0, 1.0]), diag(&[1.0]), diag(&[1.0, 1.0])],
        )
    };
    let (field, message) = refused(plan(&Exploding, &req, &|| false));
    assert_eq!(field, "x0", "{message}");
    assert!(message.contains("step 4"), "{message}");
    assert!(!message.contains("R + B"), "{message}");
}

/// Issue 26: x0 = (10³⁰⁰, 0, 0, 0) returned OK with cost = inf (the states stay finite, the
/// cost overflows); a plan whose cost is not finite is refused, naming x0.
#[test]
fn a_plan_whose_cost_overflows_is_refused() {
    let eval = true_double_pendulum();
    let mut req = swing_up(10);
    req.x0[0] = 1e300;
    let (field, message) = refused(plan(&eval, &req, &|| false));
    assert_eq!(field, "x0", "{message}");
    assert!(message.contains("cost"), "{message}");
}

/// Issue 26: at a state that stays finite, gains that overflow along an unstable
/// linearization blamed R too; the error names the horizon.
#[test]
fn gains_that_overflow_name_the_horizon_not_r() {
    let req = PlanRequest {
        max_iterations: 0,
        ..PlanRequest::new(
            vec![0.0; 2],
            vec![0.0; 2],
            6,
            [diag(&[1.0, 1.0]), diag(&[1.0]), diag(&[1.0, 1.0])],
        )
    };
    let (field, message) = refused(plan(&Exploding, &req, &|| false));
    assert_eq!(field, "horizon", "{message}");
    assert!(message.contains("overflows"), "{message}");
}

/// The UR5 of `example-robot-data` (on the multibody algorithms) from q = 0 at rest to
/// q = (0.5, −1, 1, 0, 0.5, 0) at rest in T = 100 steps of 0.01 s: with no bounds given the
/// plan keeps |u| within the URDF's effort limits (150 N·m on the big joints, 28 on the
/// wrist), converges, and ends within 0.05 of the goal (the terminal weight Q_f = 1000 Q
/// leaves a small residual, 0.015 measured); bounds given by the caller replace them.
#[test]
fn a_ur5_reach_converges_within_its_effort_limits() {
    let path = format!(
        "{}/tests/fixtures/urdf/robots/ur5.urdf",
        env!("CARGO_MANIFEST_DIR")
    );
    let t = Template::Urdf(std::sync::Arc::new(
        graybox::physics::urdf::UrdfTemplate::from_urdf(&std::fs::read_to_string(path).unwrap())
            .unwrap(),
    ));
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
    let eval = Evaluator::from_file(&file).unwrap();
    let effort = [150.0, 150.0, 150.0, 28.0, 28.0, 28.0];
    assert_eq!(eval.effort_limits(), effort.map(Some).to_vec());
    let goal = [0.5, -1.0, 1.0, 0.0, 0.5, 0.0];
    let q: Vec<f64> = (0..12).map(|i| if i < 6 { 1.0 } else { 0.1 }).collect();
    let weights = [
        diag(&q),
        diag(&[1e-4; 6]),
        diag(&q.iter().map(|v| 1000.0 * v).collect::<Vec<_>>()),
    ];
    let req = PlanRequest::new(vec![0.0; 12], [goal, [0.0; 6]].concat(), 100, weights);
    let limited = req.clone().with_effort_limits(&eval.effort_limits());
    assert_eq!(limited.u_max, Some(effort.to_vec()));
    let p = plan(&eval, &limited, &|| false).unwrap();
    assert!(p.converged, "{} iterations", p.iterations);
    assert!(p.goal_error < 0.05, "goal error {}", p.goal_error);
    for (k, u) in p.u.iter().enumerate() {
        assert!(u.abs() <= effort[k % 6] + 1e-9, "u[{k}] = {u}");
    }
    assert_costs_never_increase(&p);
    let mut given = req;
    given.u_max = Some(vec![1.0; 6]);
    assert_eq!(
        given
            .clone()
            .with_effort_limits(&eval.effort_limits())
            .u_max,
        given.u_max
    );
    assert_eq!(given.with_effort_limits(&eval.effort_limits()).u_min, None);
}
