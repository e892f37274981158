//! Pinocchio's C++ beside graybox in one sitting (`graybox-lab bench multibody`): the figures
//! of `scripts/pinocchio_cpp/bench.cpp` (built by `scripts/pinocchio_cpp/build.sh`) for the
//! same URDF, and graybox's counterparts: Predict and Linearize of one state of the robot's
//! white-box model (an RK4 step of Δt = 0.01 under τ = u − damping q̇ − friction tanh(q̇/ε),
//! what the C++ `rk4_step` and `rk4_jacobian` compute), then their ratios.

use std::path::Path;
use std::process::Command;
use std::sync::Arc;

use serde_json::{Value, json};

use graybox::error::{Error, Result};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;
use graybox::rng::Rng;

/// The C++ benchmark's figures for `urdf` (its JSON lines, printed as they come), or `None`
/// with a line saying how to build it when `bin` is not there.
pub(super) fn cpp_figures(bin: &Path, urdf: &Path, calls: usize) -> Result<Option<Vec<Value>>> {
    if !bin.exists() {
        println!(
            "{}",
            json!({"bench": "pinocchio_cpp", "skipped": format!(
                "{} is not built: scripts/pinocchio_cpp/build.sh builds it", bin.display())})
        );
        return Ok(None);
    }
    let out = Command::new(bin)
        .arg(urdf)
        .arg(calls.to_string())
        .output()
        .map_err(|e| Error::invalid("pinocchio_bench", format!("{}: {e}", bin.display())))?;
    if !out.status.success() {
        return Err(Error::invalid(
            "pinocchio_bench",
            format!(
                "{} failed: {}",
                bin.display(),
                String::from_utf8_lossy(&out.stderr)
            ),
        ));
    }
    let lines: Vec<Value> = (String::from_utf8_lossy(&out.stdout).lines())
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    for l in &lines {
        println!("{l}");
    }
    Ok(Some(lines))
}

/// The median of the C++ figure `name`.
fn cpp_p50(lines: &[Value], name: &str) -> Option<f64> {
    (lines.iter())
        .find(|l| l["bench"] == name)
        .and_then(|l| l["p50_us"].as_f64())
}

/// A timed figure: its name, calls, and the call of state k (the median returned).
pub(super) type Figure<'a> = &'a dyn Fn(&str, usize, &mut dyn FnMut(usize)) -> f64;

/// Predict and Linearize of one state of `t`'s white-box model, as the figures `figure` gives
/// (their medians returned).
pub(super) fn model_figures(
    t: &UrdfTemplate,
    calls: usize,
    figure: Figure<'_>,
) -> Result<(f64, f64)> {
    let template = Template::Urdf(Arc::new(t.clone()));
    let defaults: Vec<f64> = t.params().iter().map(|p| p.default).collect();
    let file = ModelFile::from_template(&template, &defaults, 0.01, Integrator::Rk4)?;
    let eval = Evaluator::from_file(&file)?;
    let (n, m) = (eval.config.nv(), eval.config.m);
    let mut rng = Rng::new(0);
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..super::multibody::STATES)
        .map(|_| {
            let mut draw = |k: usize| (0..k).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
            (draw(2 * n), draw(m))
        })
        .collect();
    let predict = figure("graybox_predict_1", calls, &mut |k| {
        let (x, u) = &states[k];
        std::hint::black_box(eval.predict(x, u, false));
    });
    let linearize = figure("graybox_linearize_1", calls, &mut |k| {
        let (x, u) = &states[k];
        std::hint::black_box(eval.linearize_batch(x, u));
    });
    Ok((predict, linearize))
}

/// graybox's medians over the C++ ones.
pub(super) fn ratios(robot: &str, predict: f64, linearize: f64, cpp: &[Value]) {
    let (Some(step), Some(jac), Some(der)) = (
        cpp_p50(cpp, "pinocchio_cpp_rk4_step"),
        cpp_p50(cpp, "pinocchio_cpp_rk4_jacobian"),
        cpp_p50(cpp, "pinocchio_cpp_aba_derivatives"),
    ) else {
        return;
    };
    println!(
        "{}",
        json!({"bench": "graybox_over_pinocchio_cpp", "robot": robot,
               "predict_over_rk4_step": predict / step,
               "linearize_over_rk4_jacobian": linearize / jac,
               "linearize_over_4_aba_derivatives": linearize / (4.0 * der)})
    );
}
