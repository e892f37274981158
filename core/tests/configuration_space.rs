//! A model whose configuration is not its velocities (nq ≠ nv): the built-in planar body,
//! its heading a unit complex number (nq = 4, nv = 3), against the same body written with its
//! heading as an angle θ (a formula template, nq = nv = 3). For SO(2), integrate(z, φ) = z·e^{iφ}
//! is θ + φ on the angle, so RK4 on the manifold and RK4 on θ take the same stages: the two
//! models' steps, rollouts and tangent-space Jacobians agree to rounding. The Jacobians are also
//! checked against central differences through integrate and difference.

use graybox_core::control::linalg::Mat;
use graybox_core::control::plan::{Method, PlanRequest};
use graybox_core::infer::Evaluator;
use graybox_core::model::file::ModelFile;
use graybox_core::physics::formula_template::FormulaTemplate;
use graybox_core::physics::integrator::Integrator;
use graybox_core::physics::templates::Template;

/// The planar body with its heading an angle θ: the same M, V and F as the built-in.
const ON_THETA: &str = r#"{
  "kind": "formula", "name": "planar_body_theta",
  "coordinates": ["x", "y", "th"], "inputs": ["u1", "u2", "u3"],
  "parameters": {"m": {"value": 1.0, "positive": true}, "I": {"value": 0.1, "positive": true},
                 "d": {"value": 0.2}, "g": {"value": 9.81, "positive": true},
                 "eta_xy": {"value": -0.1}, "eta_th": {"value": -0.05}},
  "mass": [["m", "0", "-m*d*sin(th)"], ["0", "m", "m*d*cos(th)"],
           ["-m*d*sin(th)", "m*d*cos(th)", "I + m*d^2"]],
  "potential": "m*g*(y + d*sin(th))",
  "forces": ["cos(th)*u1 - sin(th)*u2 + eta_xy*x_dot", "sin(th)*u1 + cos(th)*u2 + eta_xy*y_dot",
             "u3 + eta_th*th_dot"]
}"#;

/// The values both models take, by name: not the defaults, so that every term matters.
const VALUES: [(&str, f64); 6] = [
    ("m", 1.3),
    ("I", 0.07),
    ("d", 0.25),
    ("g", 9.81),
    ("eta_xy", -0.2),
    ("eta_th", -0.03),
];

/// `VALUES` in the template's order of its parameters.
fn values(t: &Template) -> Vec<f64> {
    let of = |name: &str| VALUES.iter().find(|(n, _)| *n == name).unwrap().1;
    t.params().iter().map(|p| of(&p.name)).collect()
}

fn made(t: &Template) -> ModelFile {
    ModelFile::from_template(t, &values(t), 0.01, Integrator::Rk4).unwrap()
}

fn models() -> (Evaluator, Evaluator) {
    let body = made(&Template::PlanarBody);
    let theta = Template::Formula(FormulaTemplate::parse(ON_THETA).unwrap().into());
    let flat = made(&theta);
    // Through the file's bytes: what a loaded model answers.
    let reload = |f: ModelFile| {
        let f = ModelFile::from_bytes(&f.to_bytes().unwrap()).unwrap();
        Evaluator::from_file(&f).unwrap()
    };
    (reload(body), reload(flat))
}

/// [x, y, cos θ, sin θ, ẋ, ẏ, ω] from [x, y, θ, ẋ, ẏ, ω].
fn on_circle(x: &[f64]) -> Vec<f64> {
    vec![x[0], x[1], x[2].cos(), x[2].sin(), x[3], x[4], x[5]]
}

fn states() -> Vec<[f64; 6]> {
    vec![
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.3, -1.2, 2.9, 1.5, -0.4, 3.0],
        [-2.0, 0.5, -3.1, -0.7, 2.2, -6.0],
    ]
}

const U: [f64; 3] = [4.0, -2.5, 0.8];

#[test]
fn the_sizes_and_the_file_say_nq_and_nv() {
    let (body, flat) = models();
    let c = &body.config;
    assert_eq!((c.nq(), c.nv(), c.nx(), c.ndx(), c.m), (4, 3, 7, 6, 3));
    assert_eq!((flat.config.nq(), flat.config.nv()), (3, 3));
    let text = String::from_utf8(made(&Template::PlanarBody).to_bytes().unwrap()).unwrap();
    assert!(
        text.contains(r#""joints":["real","real","circle"]"#),
        "{text}"
    );
    // A version before nq and nv refuses the file by its format.
    assert!(text.contains(r#""format":"graybox.model/4""#), "{text}");
    // The stiffness check looks at the origin's configuration, (1, 0) for the heading: a
    // light damping at Δt = 0.01 is far from stiff.
    assert!(made(&Template::PlanarBody).stiffness_warning(&[]).is_none());
}

/// One step from several states: the rotation's (cos, sin) of the angle model's θ′, the rest
/// equal, and the heading stays on the unit circle.
#[test]
fn a_step_is_the_angle_models_step() {
    let (body, flat) = models();
    for x in states() {
        let (next, acc) = body.predict(&on_circle(&x), &U, true);
        let (want, want_acc) = flat.predict(&x, &U, true);
        let want = on_circle(&want);
        for (i, (a, b)) in next.iter().zip(&want).enumerate() {
            // The same stages in other coordinates: rounding of a few hundred operations.
            assert!((a - b).abs() < 1e-12, "x'[{i}] from {x:?}: {a} vs {b}");
        }
        for (a, b) in acc.unwrap().iter().zip(want_acc.unwrap()) {
            assert!((a - b).abs() < 1e-11, "v̇ from {x:?}: {a} vs {b}");
        }
        assert!((next[2].hypot(next[3]) - 1.0).abs() < 1e-15);
    }
}

/// A thousand steps under changing inputs stay with the angle model's and on the circle.
#[test]
fn a_rollout_stays_with_the_angle_model() {
    let (body, flat) = models();
    let steps = 1000;
    let u: Vec<f64> = (0..steps * 3)
        .map(|i| 3.0 * (0.013 * i as f64).sin())
        .collect();
    let x0 = states()[1];
    let (mut xb, mut xf) = (on_circle(&x0), x0.to_vec());
    for t in 0..steps {
        xb = body.predict(&xb, &u[3 * t..3 * t + 3], false).0;
        xf = flat.predict(&xf, &u[3 * t..3 * t + 3], false).0;
    }
    let want = on_circle(&xf);
    for (i, (a, b)) in xb.iter().zip(&want).enumerate() {
        // A thousand steps of a chaotic-free damped body: rounding grows to ~1e-12 per step.
        assert!(
            (a - b).abs() < 1e-9,
            "x[{i}] after {steps} steps: {a} vs {b}"
        );
    }
    assert!((xb[2].hypot(xb[3]) - 1.0).abs() < 1e-12, "{xb:?}");
}

/// A (6 × 6) and B (6 × 3) in the tangent space: the angle model's A and B, and central
/// differences of x′ ⊖ x̄′ along x̄ ⊕ ±h e_k.
#[test]
fn linearize_answers_in_the_tangent_space() {
    let (body, flat) = models();
    let space = &body.config.space;
    for x in states() {
        let xb = on_circle(&x);
        let (a, b) = body.linearize_batch(&xb, &U);
        let (fa, fb) = flat.linearize_batch(&x, &U);
        assert_eq!((a.len(), b.len()), (36, 18));
        for (i, (g, w)) in a.iter().zip(&fa).chain(b.iter().zip(&fb)).enumerate() {
            assert!((g - w).abs() < 1e-10, "entry {i} at {x:?}: {g} vs {w}");
        }
        let next = body.predict(&xb, &U, false).0;
        let h = 1e-6;
        for k in 0..9 {
            let along = |e: f64| {
                let (mut dx, mut u) = (vec![0.0; 6], U.to_vec());
                if k < 6 {
                    dx[k] = e
                } else {
                    u[k - 6] += e
                }
                let moved = space.state_integrate(&xb, &dx);
                space.state_difference(&next, &body.predict(&moved, &u, false).0)
            };
            let (p, m) = (along(h), along(-h));
            for i in 0..6 {
                let fd = (p[i] - m[i]) / (2.0 * h);
                let got = if k < 6 {
                    a[i * 6 + k]
                } else {
                    b[i * 3 + k - 6]
                };
                // Central differences at h = 1e-6 of values of order 1–10: truncation ~h²·10,
                // rounding ~1e-16/h·10; the issue's bound.
                assert!(
                    (got - fd).abs() < 1e-6,
                    "∂x'{i}/∂{k} at {x:?}: {got} vs {fd}"
                );
            }
        }
    }
}

/// A batch answers as its states alone (the packs of states and the units of Linearize), to
/// the bit.
#[test]
fn a_batch_answers_as_its_states_alone() {
    let (body, _) = models();
    let batch: Vec<f64> = (0..70)
        .flat_map(|k| {
            on_circle(&[
                0.1 * k as f64,
                -0.05 * k as f64,
                0.3 * k as f64,
                1.0,
                -1.0,
                0.5,
            ])
        })
        .collect();
    let u: Vec<f64> = (0..70 * 3).map(|i| (0.7 * i as f64).cos()).collect();
    let (next, _) = body.predict(&batch, &u, false);
    let (a, b) = body.linearize_batch(&batch, &u);
    for k in 0..70 {
        let (x1, u1) = (&batch[7 * k..7 * k + 7], &u[3 * k..3 * k + 3]);
        assert_eq!(
            next[7 * k..7 * k + 7],
            body.predict(x1, u1, false).0[..],
            "x' of {k}"
        );
        let (a1, b1) = body.linearize_batch(x1, u1);
        assert_eq!(a[36 * k..36 * k + 36], a1[..], "A of {k}");
        assert_eq!(b[18 * k..18 * k + 18], b1[..], "B of {k}");
    }
}

/// The same reach asked of both models: from `x0` to `goal` (θ-model states) in a second.
fn reach(x0: [f64; 6], goal: [f64; 6], method: Method) -> [PlanRequest; 2] {
    let q = Mat::diag(&[10.0, 10.0, 10.0, 0.1, 0.1, 0.1]);
    let qf = Mat::diag(&[1e3; 6]);
    let r = Mat::diag(&[1e-3; 3]);
    let on_theta = PlanRequest {
        method,
        ..PlanRequest::new(x0.to_vec(), goal.to_vec(), 100, [q, r, qf])
    };
    let on_body = PlanRequest {
        x0: on_circle(&x0),
        goal: on_circle(&goal),
        ..on_theta.clone()
    };
    [on_body, on_theta]
}

/// iLQR and collocation on the body plan what they plan on the angle model, while the
/// heading stays within half a turn of the goal (where x ⊖ g is θ − θ_g): the same inputs,
/// states (the body's the angle model's on the circle), gains and costs.
#[test]
fn plans_are_the_angle_models_plans() {
    let (body, flat) = models();
    // Turning slowly (ω = 1 rad/s): the zero-input rollout, the first guess, stays within
    // half a turn of the goal's heading too.
    let (x0, goal) = (
        [0.3, -1.2, 1.0, 1.5, -0.4, 1.0],
        [1.0, 0.5, 2.0, 0.0, 0.0, 0.0],
    );
    for method in [Method::Ilqr, Method::Dircol] {
        let [on_body, on_theta] = reach(x0, goal, method);
        let p = body.plan(&on_body, &|| false).unwrap();
        let w = flat.plan(&on_theta, &|| false).unwrap();
        assert!(
            w.converged && w.goal_error < 0.05,
            "{method:?}: {}",
            w.goal_error
        );
        assert_eq!(
            (p.iterations, p.x.len(), p.gains.k[0].cols),
            (w.iterations, 101 * 7, 6)
        );
        let want_x: Vec<f64> = w.x.chunks(6).flat_map(on_circle).collect();
        let close = |what: &str, a: &[f64], b: &[f64], tol: f64| {
            for (i, (a, b)) in a.iter().zip(b).enumerate() {
                assert!(
                    (a - b).abs() < tol * b.abs().max(1.0),
                    "{method:?} {what}[{i}]: {a} vs {b}"
                );
            }
        };
        // The same iterations in other coordinates: iLQR's agree to ~1e-11 (each step's
        // rounding through a hundred steps and a few iterations); collocation's sparse QP
        // stops at its own tolerance, and rounding in other coordinates moves that stop by
        // ~1e-9 relative (measured), so its bound is looser.
        let tol = match method {
            Method::Ilqr => 1e-9,
            Method::Dircol => 1e-6,
        };
        close("u", &p.u, &w.u, tol);
        close("x", &p.x, &want_x, tol);
        close("K", &p.gains.k[0].data, &w.gains.k[0].data, tol);
        close("cost", &[p.cost], &[w.cost], tol);
        close("goal error", &[p.goal_error], &[w.goal_error], tol);
    }
}

/// Across θ = ±π the body turns the short way: from θ = −3 to θ = 3 is 0.28 rad through π,
/// which the angle model, measuring θ − θ_g, sees as 6 rad the other way. Both methods; the
/// heading stays on the unit circle.
#[test]
fn plans_turn_the_short_way_round() {
    let (body, _) = models();
    let (x0, goal) = (
        [0.0, 0.0, -3.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 3.0, 0.0, 0.0, 0.0],
    );
    for method in [Method::Ilqr, Method::Dircol] {
        let [req, _] = reach(x0, goal, method);
        let p = body.plan(&req, &|| false).unwrap();
        assert!(
            p.goal_error < 0.05,
            "{method:?}: goal error {}",
            p.goal_error
        );
        let heading: Vec<f64> = p.x.chunks(7).map(|x| x[3].atan2(x[2])).collect();
        // Turning the short way the heading leaves (−π, −3] ∪ [3, π] by little; the long
        // way it would sweep through 0.
        let nearest_zero = heading.iter().fold(f64::INFINITY, |m, h| m.min(h.abs()));
        assert!(
            nearest_zero > 2.5,
            "{method:?} swept through {nearest_zero}: {heading:?}"
        );
        for x in p.x.chunks(7) {
            assert!((x[2].hypot(x[3]) - 1.0).abs() < 1e-9, "{method:?}: {x:?}");
        }
    }
}

/// The plan's sizes on the tangent: Q is 2nv wide, and state bounds (a box on cos θ and
/// sin θ) are refused naming the field.
#[test]
fn plan_requests_speak_in_nq_and_nv() {
    let (body, _) = models();
    let [req, _] = reach(states()[1], [0.0; 6], Method::Ilqr);
    let wide = PlanRequest {
        q: Mat::diag(&[1.0; 7]),
        ..req.clone()
    };
    let err = body.plan(&wide, &|| false).unwrap_err().to_string();
    assert!(err.contains("Q") && err.contains("6×6"), "{err}");
    let bounded = PlanRequest {
        method: Method::Dircol,
        x_min: Some(vec![-10.0; 7]),
        ..req
    };
    let err = body.plan(&bounded, &|| false).unwrap_err().to_string();
    assert!(err.contains("x_min") && err.contains("rotation"), "{err}");
}

/// An ensemble's mean next state keeps a heading on the circle: the members' headings
/// averaged as unit complex numbers and projected back (arg Σ z_k), the rest their average.
#[test]
fn an_ensembles_mean_heading_stays_on_the_circle() {
    let t = Template::PlanarBody;
    let member = |d: f64| {
        let mut v = values(&t);
        let at = t.params().iter().position(|p| p.name == "d").unwrap();
        v[at] = d;
        ModelFile::from_template(&t, &v, 0.01, Integrator::Rk4).unwrap()
    };
    let file = ModelFile::ensemble(vec![member(0.1), member(0.6)], None);
    let file = ModelFile::from_bytes(&file.to_bytes().unwrap()).unwrap();
    let both = Evaluator::from_file(&file).unwrap();
    let x = on_circle(&states()[2]);
    let next = both.predict(&x, &U, false).0;
    let each: Vec<Vec<f64>> = (0..2)
        .map(|k| both.member(k).predict(&x, &U, false).0)
        .collect();
    // The members part (different offsets of the centre of mass), so a plain mean would sit
    // inside the circle.
    let chord = (each[0][2] + each[1][2]).hypot(each[0][3] + each[1][3]) / 2.0;
    assert!(chord < 1.0 - 1e-9, "{each:?}");
    assert!((next[2].hypot(next[3]) - 1.0).abs() < 1e-15, "{next:?}");
    let angle = |x: &[f64]| x[3].atan2(x[2]);
    let halfway = (angle(&each[0]) + angle(&each[1])) / 2.0;
    // Two unit vectors' sum points exactly halfway between them: rounding only.
    assert!(
        (angle(&next) - halfway).abs() < 1e-12,
        "{} vs {halfway}",
        angle(&next)
    );
    for i in [0, 1, 4, 5, 6] {
        assert_eq!(next[i], (each[0][i] + each[1][i]) / 2.0, "x'[{i}]");
    }
}
