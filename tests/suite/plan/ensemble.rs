//! Plans on an ensemble (`control::ensemble`) against references computed here from the
//! members' own one-step maps: the members' average cost of a plan's inputs, its gradient by
//! finite differences, and the members' rollouts.

use graybox::control::plan::{EnsembleCost, Method, Plan, PlanRequest};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;

use crate::common::plans::{linear_file, linear_model, linear_request};

/// Linear members that differ in stiffness (1 and 2.5 times linear_model's).
fn two_members() -> (Evaluator, Vec<Evaluator>) {
    let files = vec![linear_file(0.1, 1.0), linear_file(0.1, 2.5)];
    let members = files
        .iter()
        .map(|f| Evaluator::from_file(f).unwrap())
        .collect();
    let ensemble = Evaluator::from_file(&ModelFile::ensemble(files, None)).unwrap();
    (ensemble, members)
}

fn mean_cost(req: &PlanRequest) -> PlanRequest {
    PlanRequest {
        ensemble_cost: EnsembleCost::Mean,
        ..req.clone()
    }
}

/// Each member's open-loop rollout of `u` from x0, `[T+1, nx]` each.
fn rollouts(members: &[Evaluator], x0: &[f64], u: &[f64]) -> Vec<Vec<f64>> {
    (members.iter())
        .map(|s| {
            let mut x = x0.to_vec();
            let mut at = x0.to_vec();
            for ut in u.chunks(2) {
                at = s.step(&at, ut);
                x.extend_from_slice(&at);
            }
            x
        })
        .collect()
}

/// J of one trajectory as the request weighs it, written out here.
fn cost(req: &PlanRequest, x: &[f64], u: &[f64]) -> f64 {
    let quad = |w: &graybox::control::linalg::Mat, d: &[f64]| -> f64 {
        (0..d.len())
            .map(|i| (0..d.len()).map(|j| d[i] * w.at(i, j) * d[j]).sum::<f64>())
            .sum()
    };
    let t = req.horizon;
    let dev = |s: usize| -> Vec<f64> { (0..4).map(|i| x[s * 4 + i] - req.goal[i]).collect() };
    (0..t)
        .map(|s| quad(&req.q, &dev(s)) + quad(&req.r, &u[s * 2..s * 2 + 2]))
        .sum::<f64>()
        + quad(&req.qf, &dev(t))
}

fn average_cost(members: &[Evaluator], req: &PlanRequest, u: &[f64]) -> f64 {
    let xs = rollouts(members, &req.x0, u);
    xs.iter().map(|x| cost(req, x, u)).sum::<f64>() / members.len() as f64
}

fn plan(sys: &Evaluator, req: &PlanRequest) -> Plan {
    sys.plan(req, &|| false).unwrap()
}

#[test]
fn the_mean_cost_plan_minimizes_the_members_average_cost() {
    let (ensemble, members) = two_members();
    let req = linear_request(20);
    let p = plan(&ensemble, &mean_cost(&req));
    assert!(p.converged, "{:?}", p.costs);
    // Its cost is the members' average cost of its inputs, each rolled out on its own
    // (relative 1e-9: the same sums in another order).
    let j = average_cost(&members, &req, &p.u);
    assert!((p.cost - j).abs() <= 1e-9 * j, "{} vs {j}", p.cost);
    // A minimum: every input's central difference of the average cost is ~0. Step 1e-4 on
    // inputs of order 1 leaves an O(h²) error of ~1e-8 on a quadratic (exactly 0) plus
    // round-off of 1e-16·J/h ≈ 1e-11; the cost's scale is J ≈ 10, so 1e-6 of it catches a
    // plan that is not the optimum (moving u by 1e-3 off it changes J by more).
    let h = 1e-4;
    for i in 0..p.u.len() {
        let at = |d: f64| {
            let mut u = p.u.clone();
            u[i] += d;
            average_cost(&members, &req, &u)
        };
        let g = (at(h) - at(-h)) / (2.0 * h);
        assert!(g.abs() <= 1e-6 * j, "∂J̄/∂u[{i}] = {g}");
    }
    // The mean dynamics' plan is a different problem's optimum: on the average cost it is
    // no better (the members differ by 2.5× in stiffness, so strictly worse here).
    let on_mean = plan(&ensemble, &req);
    assert!(average_cost(&members, &req, &on_mean.u) > j * (1.0 + 1e-6));
}

#[test]
fn the_plan_reports_the_members_mean_states_and_spread() {
    let (ensemble, members) = two_members();
    let req = linear_request(15);
    for r in [req.clone(), mean_cost(&req)] {
        let p = plan(&ensemble, &r);
        let xs = rollouts(&members, &req.x0, &p.u);
        let std = p.x_std.as_ref().expect("an ensemble's plan has a spread");
        assert_eq!(std.len(), p.x.len());
        for i in 0..p.x.len() {
            let (a, b) = (xs[0][i], xs[1][i]);
            // Two members: σ = |a − b| / √2 (divisor K − 1).
            let want = (a - b).abs() / 2f64.sqrt();
            assert!((std[i] - want).abs() <= 1e-9 * (1.0 + want), "σ[{i}]");
            if r.ensemble_cost == EnsembleCost::Mean {
                // Its states are the members' mean along its inputs.
                assert!(
                    (p.x[i] - 0.5 * (a + b)).abs() <= 1e-9 * (1.0 + a.abs()),
                    "x[{i}]"
                );
            }
        }
        let end = &p.x[p.x.len() - 4..];
        let goal_error = end.iter().zip(&req.goal).map(|(a, g)| (a - g).powi(2));
        assert!((p.goal_error - goal_error.sum::<f64>().sqrt()).abs() < 1e-12);
    }
}

#[test]
fn identical_members_plan_as_one_model() {
    // Two copies of one model: the stacked problem is the single one's, and the gains for a
    // deviation both members share are the single model's gains.
    let files = vec![linear_file(0.1, 1.0), linear_file(0.1, 1.0)];
    let ensemble = Evaluator::from_file(&ModelFile::ensemble(files, None)).unwrap();
    let single = linear_model(0.1);
    let req = linear_request(20);
    let one = plan(&single, &req);
    assert!(one.x_std.is_none(), "a single model has no spread");
    for method in [Method::Ilqr, Method::Dircol] {
        let r = PlanRequest {
            method,
            ..req.clone()
        };
        let (one, two) = (plan(&single, &r), plan(&ensemble, &mean_cost(&r)));
        // Both solve the same quadratic problem to the request's tolerance (1e-9 relative),
        // through matrices of twice the size: 1e-6 absolute on inputs and gains of order 1.
        let close = |a: &[f64], b: &[f64], what: &str| {
            let worst = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-6, "{method:?} {what}: {worst}");
        };
        close(&one.u, &two.u, "u");
        close(&one.x, &two.x, "x");
        for (a, b) in one.gains.k.iter().zip(&two.gains.k) {
            assert_eq!((a.rows, a.cols), (b.rows, b.cols));
            close(&a.data, &b.data, "K");
        }
        assert!((one.cost - two.cost).abs() < 1e-6 * one.cost);
        // Collocation's states are variables of the QP, each member's its own: equal to its
        // tolerance, not to the bit.
        assert!(two.x_std.unwrap().iter().all(|s| *s < 1e-6));
    }
}

#[test]
fn a_single_model_plans_as_itself_whatever_the_ensemble_cost() {
    let single = linear_model(0.1);
    let req = linear_request(10);
    let (a, b) = (plan(&single, &req), plan(&single, &mean_cost(&req)));
    assert_eq!(a.u, b.u);
    assert_eq!(a.cost, b.cost);
    assert!(b.x_std.is_none());
}
