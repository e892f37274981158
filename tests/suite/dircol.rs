//! Direct collocation (`control::dircol`) against independent references: the collocated QP
//! of a linear model assembled and solved densely here, the RK4 model's discrete LQ optimum,
//! and the paper's swing-up tracked on a closed-form RK4.

use crate::common;

use std::time::{Duration, Instant};

use graybox::control::dircol::{Continuous, DEFECT_TOLERANCE};
use graybox::control::linalg::Mat;
use graybox::control::make_plan;
use graybox::control::plan::{Dynamics, Method, Plan, PlanRequest, plan};
use graybox::error::Error;

use common::gauss_solve;
use common::plans::{
    batch_least_squares, linear_model, linear_request, swing_up, track_swing_up,
    true_double_pendulum,
};

fn dircol(req: PlanRequest) -> PlanRequest {
    PlanRequest {
        method: Method::Dircol,
        ..req
    }
}

fn run(sys: &(impl Dynamics + Continuous), req: &PlanRequest) -> Plan {
    make_plan(sys, req, &|| false).unwrap()
}

/// ‖a − b‖ / ‖b‖.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    norm(&mut a.iter().zip(b).map(|(x, y)| x - y)) / norm(&mut b.iter().copied())
}

/// The collocated QP of a linear system ẋ = A x + B u + c written out densely, in an order of
/// its own (states, then inputs, then midpoints), and solved through its KKT system: the
/// knot states `[T+1, nx]` and inputs `[T, m]` of its minimizer.
fn collocated_qp(sys: &impl Continuous, req: &PlanRequest) -> (Vec<f64>, Vec<f64>) {
    let (nx, m, t, h) = (4, 2, req.horizon, sys.dt());
    // A, B and c from f at the origin and unit vectors: exact for a linear f.
    let f0 = sys.derivative(&[0.0; 4], &[0.0; 2]);
    let column = |x: &[f64], u: &[f64]| -> Vec<f64> {
        let f = sys.derivative(x, u);
        f.iter().zip(&f0).map(|(a, b)| a - b).collect()
    };
    let unit =
        |n: usize, i: usize| -> Vec<f64> { (0..n).map(|j| f64::from(u8::from(i == j))).collect() };
    let a: Vec<Vec<f64>> = (0..nx).map(|j| column(&unit(nx, j), &[0.0; 2])).collect();
    let b: Vec<Vec<f64>> = (0..m).map(|j| column(&[0.0; 4], &unit(m, j))).collect();
    let (xi, ui, ci) = (
        |k: usize, i: usize| k * nx + i,
        |k: usize, i: usize| (t + 1) * nx + k * m + i,
        |k: usize, i: usize| (t + 1) * nx + t * m + k * nx + i,
    );
    let n = (t + 1) * nx + t * m + t * nx;
    // Rows of E z = e: x_0 = x0, then Simpson's and Hermite's defects per interval, with
    // f(x, u) = A x + B u + c at (x_k, u_k), (x_c, u_k) and (x_{k+1}, u_k).
    let (mut rows, mut rhs) = (vec![], vec![]);
    for i in 0..nx {
        let mut r = vec![0.0; n];
        r[xi(0, i)] = 1.0;
        rows.push(r);
        rhs.push(req.x0[i]);
    }
    for k in 0..t {
        for (weights, mid) in [
            ([-h / 6.0, -4.0 * h / 6.0, -h / 6.0], false),
            ([-h / 8.0, 0.0, h / 8.0], true),
        ] {
            for i in 0..nx {
                let mut r = vec![0.0; n];
                let (ws, wc, we) = (weights[0], weights[1], weights[2]);
                if mid {
                    r[ci(k, i)] += 1.0;
                    r[xi(k, i)] -= 0.5;
                    r[xi(k + 1, i)] -= 0.5;
                } else {
                    r[xi(k + 1, i)] += 1.0;
                    r[xi(k, i)] -= 1.0;
                }
                for j in 0..nx {
                    r[xi(k, j)] += ws * a[j][i];
                    r[ci(k, j)] += wc * a[j][i];
                    r[xi(k + 1, j)] += we * a[j][i];
                }
                for j in 0..m {
                    r[ui(k, j)] += (ws + wc + we) * b[j][i];
                }
                rows.push(r);
                rhs.push(-(ws + wc + we) * f0[i]);
            }
        }
    }
    // KKT: [2W Eᵀ; E 0] [z; λ] = [2W ḡ; e], ḡ the goal at the knots' states, 0 elsewhere.
    let dim = n + rows.len();
    let mut kkt = vec![vec![0.0; dim]; dim];
    let mut r = vec![0.0; dim];
    for k in 0..=t {
        let w = if k == t { &req.qf } else { &req.q };
        for i in 0..nx {
            for j in 0..nx {
                kkt[xi(k, i)][xi(k, j)] = 2.0 * w.at(i, j);
                r[xi(k, i)] += 2.0 * w.at(i, j) * req.goal[j];
            }
        }
    }
    for k in 0..t {
        for i in 0..m {
            for j in 0..m {
                kkt[ui(k, i)][ui(k, j)] = 2.0 * req.r.at(i, j);
            }
        }
    }
    for (c, (row, e)) in rows.iter().zip(&rhs).enumerate() {
        for (j, v) in row.iter().enumerate() {
            kkt[n + c][j] = *v;
            kkt[j][n + c] = *v;
        }
        r[n + c] = *e;
    }
    let z = gauss_solve(kkt, r);
    (
        z[..(t + 1) * nx].to_vec(),
        z[(t + 1) * nx..(t + 1) * nx + t * m].to_vec(),
    )
}

/// On a linear model collocation is a QP, so the SQP's answer is its minimizer; and at a
/// small step the collocated optimum's cost is the RK4 model's discrete LQ optimum's.
#[test]
fn a_linear_system_gives_the_collocated_qp_and_the_discrete_optimum() {
    let eval = linear_model(0.05);
    let req = dircol(PlanRequest {
        tolerance: 1e-12,
        ..linear_request(12)
    });
    let p = run(&eval, &req);
    assert!(
        p.converged && p.iterations <= 3,
        "{} iterations",
        p.iterations
    );
    assert_eq!(p.method, Method::Dircol);
    let (x, u) = collocated_qp(&eval, &req);
    // 1e-8 normwise, the bound: the dense elimination and the SQP's last step each
    // leave rounding of ~1e-13 relative on a system of a few hundred equations.
    assert!(relative(&p.x, &x) < 1e-8, "states {:e}", relative(&p.x, &x));
    assert!(relative(&p.u, &u) < 1e-8, "inputs {:e}", relative(&p.u, &u));

    let eval = linear_model(0.01);
    let req = dircol(linear_request(100));
    let p = run(&eval, &req);
    let best = batch_least_squares(&eval, &req);
    let mut rolled = req.x0.clone();
    for k in 0..100 {
        let next = eval.step(&rolled[k * 4..], &best[k * 2..(k + 1) * 2]);
        rolled.extend(next);
    }
    let discrete = cost(&req, &rolled, &best);
    // Hermite–Simpson and RK4 are both fourth order: at Δt = 0.01 the two optima differ by
    // ~1e-8 relative; 1e-3 is the bound.
    let gap = (p.cost - discrete).abs() / discrete;
    assert!(gap < 1e-3, "collocated {} vs discrete {discrete}", p.cost);
    assert!(p.rollout_deviation < 1e-6, "{}", p.rollout_deviation);
}

fn cost(req: &PlanRequest, x: &[f64], u: &[f64]) -> f64 {
    let quad = |w: &Mat, d: &[f64]| -> f64 {
        (0..d.len())
            .map(|i| (0..d.len()).map(|j| d[i] * w.at(i, j) * d[j]).sum::<f64>())
            .sum()
    };
    let t = req.horizon;
    let dx = |k: usize| -> Vec<f64> { (0..4).map(|i| x[k * 4 + i] - req.goal[i]).collect() };
    (0..t)
        .map(|k| quad(&req.q, &dx(k)) + quad(&req.r, &u[k * 2..(k + 1) * 2]))
        .sum::<f64>()
        + quad(&req.qf, &dx(t))
}

/// The paper's swing-up from hanging still, planned from u = 0: every defect met, every input
/// within its bounds, and the plan tracked by its own TVLQR gains on the closed-form RK4
/// ends upright (the 0.05 rad and 0.2 rad/s).
#[test]
fn the_swing_up_converges_and_its_gains_track_it_on_the_true_system() {
    let eval = true_double_pendulum();
    let req = dircol(swing_up(21));
    let p = run(&eval, &req);
    assert!(p.converged, "{} iterations", p.iterations);
    assert!(
        p.constraint_violation < 1e-6,
        "{:e}",
        p.constraint_violation
    );
    assert!(p.constraint_violation <= DEFECT_TOLERANCE);
    assert!(
        p.u.iter().all(|u| u.abs() <= 120.0),
        "an input leaves its bounds"
    );
    let x = track_swing_up(&p, &req.x0);
    for i in 0..2 {
        assert!((x[i] - req.goal[i]).abs() < 0.05, "tracked end {x:?}");
        assert!(x[2 + i].abs() < 0.2, "tracked end {x:?}");
    }
    // The open-loop rollout of the plan's inputs strays (the upright pendulum amplifies the
    // integrators' difference); the answer says by how much.
    let rollout = plan(
        &eval,
        &PlanRequest {
            max_iterations: 0,
            u_init: Some(Mat::new(21, 2, p.u.clone())),
            ..swing_up(21)
        },
        &|| false,
    )
    .unwrap();
    let strayed = rollout
        .x
        .iter()
        .zip(&p.x)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert_eq!(p.rollout_deviation, strayed);
}

/// Tight bounds hold at every knot, and so (the inputs are held) over every interval.
#[test]
fn bounds_hold_at_every_knot() {
    let eval = true_double_pendulum();
    let req = dircol(PlanRequest {
        u_min: Some(vec![-3.0, -1.0]),
        u_max: Some(vec![2.0, 1.5]),
        ..swing_up(30)
    });
    let p = run(&eval, &req);
    for (k, u) in p.u.chunks(2).enumerate() {
        assert!(
            (-3.0..=2.0).contains(&u[0]) && (-1.0..=1.5).contains(&u[1]),
            "u_{k} = {u:?}"
        );
    }
    // The bounds bind (a swing-up wants far more than 3 N·m), so the check above has teeth.
    let at_bound = |u: f64| [-3.0, 2.0, -1.0, 1.5].iter().any(|b| (u - b).abs() < 1e-6);
    assert!(p.u.iter().any(|u| at_bound(*u)), "{:?}", p.u);
}

/// Without `method`, `make_plan` is iLQR's plan to the bit; x_init belongs to collocation.
#[test]
fn the_default_method_is_ilqr_bit_for_bit() {
    let eval = true_double_pendulum();
    let req = swing_up(21);
    assert_eq!(req.method, Method::Ilqr);
    let (a, b) = (run(&eval, &req), plan(&eval, &req, &|| false).unwrap());
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.x), bits(&b.x));
    assert_eq!(bits(&a.u), bits(&b.u));
    assert_eq!(
        (a.method, a.constraint_violation, a.rollout_deviation),
        (Method::Ilqr, 0.0, 0.0)
    );
}

fn refused(result: graybox::error::Result<Plan>) -> (String, String) {
    match result {
        Err(Error::Invalid { field, message }) => (field, message),
        other => panic!("expected a refusal, got {:?}", other.map(|p| p.cost)),
    }
}

#[test]
fn bad_inputs_name_their_field() {
    let eval = true_double_pendulum();
    assert_eq!(
        refused(Method::parse("shooting").map(|_| unreachable!())).0,
        "method"
    );
    let with = |x: Mat, method| PlanRequest {
        x_init: Some(x),
        method,
        ..swing_up(10)
    };
    let bounded = |x_min: Vec<f64>, x_max: Vec<f64>, method| PlanRequest {
        x_min: Some(x_min),
        x_max: Some(x_max),
        method,
        ..swing_up(10)
    };
    for (req, field, says) in [
        (
            bounded(vec![-1.0; 4], vec![1.0; 4], Method::Ilqr),
            "x_min",
            "dircol",
        ),
        (
            bounded(vec![-1.0; 3], vec![1.0; 4], Method::Dircol),
            "x_min",
            "4 values",
        ),
        (
            bounded(vec![1.0; 4], vec![0.5; 4], Method::Dircol),
            "x_min",
            "above",
        ),
        (
            bounded(vec![0.5; 4], vec![1.0; 4], Method::Dircol),
            "x0",
            "outside",
        ),
    ] {
        let (got, message) = refused(make_plan(&eval, &req, &|| false));
        assert_eq!(got, field, "{message}");
        assert!(message.contains(says), "{message}");
    }
    for (x, method, says) in [
        (Mat::zeros(10, 4), Method::Dircol, "[11, 4]"),
        (Mat::zeros(11, 3), Method::Dircol, "[11, 4]"),
        (
            Mat::new(11, 4, vec![f64::NAN; 44]),
            Method::Dircol,
            "not finite",
        ),
        (Mat::zeros(11, 4), Method::Ilqr, "dircol"),
    ] {
        let (field, message) = refused(make_plan(&eval, &with(x, method), &|| false));
        assert_eq!(field, "x_init", "{message}");
        assert!(message.contains(says), "{message}");
    }
}

/// A straight line in state space is a start too, and reaches the same swing-up.
#[test]
fn a_straight_line_start_converges() {
    let eval = true_double_pendulum();
    let line: Vec<f64> = (0..=21)
        .flat_map(|k| [std::f64::consts::PI * k as f64 / 21.0, 0.0, 0.0, 0.0])
        .collect();
    let req = dircol(PlanRequest {
        x_init: Some(Mat::new(22, 4, line)),
        ..swing_up(21)
    });
    let p = run(&eval, &req);
    assert!(
        p.converged && p.constraint_violation < 1e-6,
        "{:e}",
        p.constraint_violation
    );
    assert!(p.goal_error < 0.05, "{}", p.goal_error);
}

/// State bounds hold at every knot: the swing-up with its joint speeds capped at 3 rad/s
/// (uncapped, it spins faster).
#[test]
fn state_bounds_hold_at_every_knot() {
    let eval = true_double_pendulum();
    let free = run(&eval, &dircol(swing_up(21)));
    let fastest = |p: &Plan| (p.x.chunks(4)).fold(0.0f64, |m, x| m.max(x[2].abs()).max(x[3].abs()));
    assert!(fastest(&free) > 4.0, "{}", fastest(&free));
    let inf = f64::INFINITY;
    let req = dircol(PlanRequest {
        x_min: Some(vec![-inf, -inf, -3.0, -3.0]),
        x_max: Some(vec![inf, inf, 3.0, 3.0]),
        ..swing_up(21)
    });
    let p = run(&eval, &req);
    assert!(
        p.converged && p.constraint_violation <= DEFECT_TOLERANCE,
        "{:e}",
        p.constraint_violation
    );
    // The QP's bounds hold to its tolerance, 1e-8.
    assert!(fastest(&p) <= 3.0 + 1e-8, "{}", fastest(&p));
}

/// A pendulum held still at 1 rad with |u| ≤ 0.1 and |q̇| ≤ 0.01 cannot be: gravity needs
/// ~100 N·m there. Every QP is infeasible, and the answer says so (not converged, its
/// violation) rather than hanging or failing.
#[test]
fn an_infeasible_plan_says_it_is_infeasible() {
    let eval = true_double_pendulum();
    let req = dircol(PlanRequest {
        x0: vec![1.0, 0.0, 0.0, 0.0],
        x_min: Some(vec![-10.0, -10.0, -0.01, -0.01]),
        x_max: Some(vec![10.0, 10.0, 0.01, 0.01]),
        u_min: Some(vec![-0.1; 2]),
        u_max: Some(vec![0.1; 2]),
        ..swing_up(21)
    });
    let p = run(&eval, &req);
    assert!(!p.converged);
    assert!(p.constraint_violation > 0.1, "{:e}", p.constraint_violation);
}

/// Few iterations leave the defects unmet: the answer says so (not converged, its violation)
/// rather than hanging or failing.
#[test]
fn an_unfinished_plan_says_it_is_unfinished() {
    let eval = true_double_pendulum();
    let req = dircol(PlanRequest {
        max_iterations: 2,
        ..swing_up(21)
    });
    let p = run(&eval, &req);
    assert!(!p.converged);
    assert!(
        p.constraint_violation > DEFECT_TOLERANCE,
        "{:e}",
        p.constraint_violation
    );
    assert_eq!(p.iterations, p.costs.len() - 1);
}

/// The request's time limit returns the best plan so far, by the limit plus 0.5 s (the issue's
/// bound: the QP solver hears it at its next interior-point iteration, a few milliseconds at
/// this size, then the answer's gains take ~0.1 s); the caller's stop ends the call as
/// cancelled, inside a QP solve too.
#[test]
fn time_limits_and_stops_are_heard_inside_a_solve() {
    let eval = true_double_pendulum();
    let limit = Duration::from_millis(300);
    let started = Instant::now();
    let req = dircol(PlanRequest {
        time_limit: Some(started + limit),
        restarts: 5,
        ..swing_up(2000)
    });
    let p = run(&eval, &req);
    assert!(
        started.elapsed() < limit + Duration::from_millis(500),
        "{:?}",
        started.elapsed()
    );
    assert!(!p.converged);
    assert!(p.x.iter().chain(&p.u).all(|v| v.is_finite()));

    let started = Instant::now();
    let stop = || started.elapsed() > limit;
    let req = dircol(PlanRequest {
        restarts: 5,
        ..swing_up(2000)
    });
    match make_plan(&eval, &req, &stop) {
        Err(Error::Cancelled) => {}
        other => panic!("expected cancelled, got {:?}", other.map(|p| p.iterations)),
    }
    assert!(
        started.elapsed() < limit + Duration::from_millis(500),
        "{:?}",
        started.elapsed()
    );
}
