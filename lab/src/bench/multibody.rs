//! `graybox-lab bench multibody --urdf FILE`: microseconds per call of a URDF robot's dynamics in
//! f64, the assembled path (the template's M and V over dual numbers, then the Coriolis term
//! from ∂L/∂q and a Cholesky solve: `dynamics::white_box_acceleration`) against the
//! multibody algorithms (`physics::multibody`): ABA, CRBA + Cholesky, and ∂q̈/∂q, ∂q̈/∂q̇ (what
//! Linearize needs) by −M⁻¹ ∂ID analytically and by forward dynamics over dual numbers.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde_json::json;

use graybox::arena::Arena;
use graybox::error::{Error, Result};
use graybox::physics::dynamics::{constants, white_box_acceleration};
use graybox::physics::multibody::adjoint::{forward_dynamics_adjoint, parameter_gradient};
use graybox::physics::multibody::{
    Derivatives, Model, aba, bias, crba, crba_forward, fd_over_dual, forward_dynamics,
    forward_dynamics_derivatives,
};
use graybox::physics::urdf::UrdfTemplate;
use graybox::rng::Rng;

#[derive(Args, Debug)]
pub struct BenchMultibodyArgs {
    /// The robot's URDF file (e.g. tests/fixtures/urdf/robots/ur5.urdf).
    #[arg(long)]
    pub urdf: PathBuf,
    /// Timed calls per figure (after a tenth as many for warm-up).
    #[arg(long, default_value_t = 20_000)]
    pub calls: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Pinocchio's C++ benchmark (scripts/pinocchio_cpp/build.sh builds it), run on the same
    /// URDF in the same sitting when it is there.
    #[arg(long, default_value = "target/pinocchio-bench/bench")]
    pub pinocchio_bench: PathBuf,
}

/// States the calls cycle through, so no figure is of one state's cached branch pattern.
pub(super) const STATES: usize = 64;

/// Mean and median µs per call of `f` over `calls` calls (state k mod `STATES`); returns the
/// median.
fn figure(name: &str, n: usize, calls: usize, f: &mut dyn FnMut(usize)) -> f64 {
    for k in 0..calls.div_ceil(10) {
        f(k % STATES);
    }
    let mut us: Vec<f64> = (0..calls)
        .map(|k| {
            let t = Instant::now();
            f(k % STATES);
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    us.sort_by(f64::total_cmp);
    let mean = us.iter().sum::<f64>() / us.len() as f64;
    println!(
        "{}",
        json!({"bench": name, "n": n, "calls": calls, "mean_us": mean,
               "p50_us": us[us.len() / 2], "p99_us": us[(us.len() - 1) * 99 / 100]})
    );
    us[us.len() / 2]
}

pub fn run(a: BenchMultibodyArgs) -> Result<()> {
    let text = std::fs::read_to_string(&a.urdf)
        .map_err(|e| Error::invalid("urdf", format!("{}: {e}", a.urdf.display())))?;
    let t = UrdfTemplate::from_urdf(&text)?;
    let n = t.n();
    let model = t.tree.multibody(t.doc.gravity);
    let p: Vec<f64> = t.params().iter().map(|p| p.default).collect();
    let pd = constants(&p);
    let space = graybox::physics::space::Space::flat(n, &[]);
    let mut rng = Rng::new(a.seed);
    let mut draw = |s: f64| -> Vec<f64> { (0..n).map(|_| s * rng.normal()).collect() };
    let states: Vec<[Vec<f64>; 3]> = (0..STATES)
        .map(|_| [draw(1.5), draw(1.0), draw(5.0)])
        .collect();
    // The existing path: M(q), V(q) of the template over dual numbers, then the manipulator
    // equation (what `sim` and the f64 evaluator do for a white-box robot).
    let existing = |[q, qd, tau]: &[Vec<f64>; 3]| {
        white_box_acceleration(
            &Arena::new(),
            &space,
            |q| t.mass(&pd, q),
            |q| t.potential(&pd, q),
            tau,
            q,
            qd,
        )
        .to_vec()
    };
    // Both compute the same q̈ (to rounding): say how close, so a figure is of a right answer.
    let worst = states.iter().fold(0.0f64, |w, s| {
        let (x, y) = (existing(s), forward_dynamics(&model, &s[0], &s[1], &s[2]));
        let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        // A NaN must show, not be dropped by `f64::max`.
        (x.iter().zip(&y)).fold(w, |w, (x, y)| {
            let d = (x - y).abs() / scale;
            if d > w || d.is_nan() { d } else { w }
        })
    });
    println!(
        "{}",
        json!({"bench": "multibody_agreement", "robot": t.doc.name, "n": n,
               "bodies": model.bodies.len(), "mimic": model.mimic,
               "max_rel_diff_qdd": worst})
    );
    let calls = a.calls;
    // The comparison first, while the machine is as it was for the C++ figures.
    let (predict, linearize) =
        super::pinocchio::model_figures(&t, calls, &|name, calls, f| figure(name, n, calls, f))?;
    if let Some(cpp) = super::pinocchio::cpp_figures(&a.pinocchio_bench, &a.urdf, calls)? {
        super::pinocchio::ratios(&t.doc.name, predict, linearize, &cpp);
    }
    figure("template_white_box_acceleration_f64", n, calls, &mut |k| {
        black_box(existing(&states[k]));
    });
    if !model.mimic {
        figure("aba_f64", n, calls, &mut |k| {
            let [q, qd, tau] = &states[k];
            black_box(aba(&model, q, qd, tau));
        });
    }
    let mut data = graybox::physics::multibody::Data::new(&model);
    figure("data_forward_dynamics_f64", n, calls, &mut |k| {
        let [q, qd, tau] = &states[k];
        data.forward_dynamics(&model, q, qd, tau);
        black_box(&data.qdd);
    });
    figure("crba_cholesky_f64", n, calls, &mut |k| {
        let [q, qd, tau] = &states[k];
        black_box(crba_forward(&model, q, qd, tau));
    });
    figure("crba_f64", n, calls, &mut |k| {
        black_box(crba(&model, &states[k][0]));
    });
    figure("rnea_bias_f64", n, calls, &mut |k| {
        black_box(bias(&model, &states[k][0], &states[k][1]));
    });
    figure("fd_derivatives_analytic", n, calls, &mut |k| {
        let [q, qd, tau] = &states[k];
        black_box(forward_dynamics_derivatives(&model, q, qd, tau));
    });
    // Forward dynamics over dual numbers, the reference the analytic route is checked by.
    type OverDual = fn(&Model, &[f64], &[f64], &[f64]) -> Derivatives;
    let over_dual: Option<OverDual> = match 2 * n {
        0..=16 => Some(fd_over_dual::<16>),
        17..=64 => Some(fd_over_dual::<64>),
        _ => None,
    };
    if let Some(over_dual) = over_dual {
        figure("fd_derivatives_fd_over_dual", n, calls, &mut |k| {
            let [q, qd, tau] = &states[k];
            black_box(over_dual(&model, q, qd, tau));
        });
    }
    // A training step's backward pass per state and integrator stage (ḡ = τ's values: any
    // vector does).
    figure("fd_adjoint_q_qd_tau_pi", n, calls, &mut |k| {
        let [q, qd, tau] = &states[k];
        black_box(forward_dynamics_adjoint(&model, q, qd, tau, tau));
    });
    figure("parameter_gradient_only", n, calls, &mut |k| {
        let [q, qd, tau] = &states[k];
        black_box(parameter_gradient(&model, q, qd, qd, tau));
    });
    Ok(())
}
