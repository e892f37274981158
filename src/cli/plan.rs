//! `graybox plan`: trajectory optimisation on a model file (`control::plan`), written as JSON
//! with the fields of the gRPC `Plan` response.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde_json::json;

use crate::control::dircol::straight_line;
use crate::control::linalg::Mat;
use crate::control::plan::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_MAX_PLAN_HORIZON, DEFAULT_TOLERANCE, EnsembleCost, Method,
    PlanRequest, check_horizon, time_limit_in,
};
use crate::error::{Error, Result};
use crate::infer::Evaluator;
use crate::model::file::write_atomic;

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// A model file (.gbx) that `train` or `model` wrote, or the service served.
    #[arg(long)]
    pub model: PathBuf,
    /// The start state, nq + nv comma-separated values (q then v).
    #[arg(long, allow_hyphen_values = true)]
    pub x0: String,
    /// The goal state, nq + nv values.
    #[arg(long, allow_hyphen_values = true)]
    pub goal: String,
    /// Steps T (the plan lasts T·Δt, Δt the model's), at most --max-plan-horizon.
    #[arg(long)]
    pub horizon: u64,
    /// The longest horizon accepted (the service's limit of the same name).
    #[arg(long, default_value_t = DEFAULT_MAX_PLAN_HORIZON)]
    pub max_plan_horizon: usize,
    /// Lower input bounds, m values (default, with no --u-max either: −effort for a URDF
    /// joint with a `<limit effort>`, else unbounded).
    #[arg(long, allow_hyphen_values = true)]
    pub u_min: Option<String>,
    /// Upper input bounds, m values (default, with no --u-min either: the URDF's effort limit,
    /// else unbounded).
    #[arg(long, allow_hyphen_values = true)]
    pub u_max: Option<String>,
    /// Diagonal of Q, 2nv values weighing x ⊖ goal (default: 1 for each configuration
    /// direction, 0.1 for each velocity).
    #[arg(long, allow_hyphen_values = true)]
    pub q_diag: Option<String>,
    /// Diagonal of R, m values (default: 1e-4 each).
    #[arg(long, allow_hyphen_values = true)]
    pub r_diag: Option<String>,
    /// Diagonal of Q_f, 2nv values (default: 1000 × Q's).
    #[arg(long, allow_hyphen_values = true)]
    pub qf_diag: Option<String>,
    /// Extra randomised starts, at most 1000 (`control::plan::MAX_RESTARTS`).
    #[arg(long, default_value_t = 0)]
    pub restarts: usize,
    /// 0: no iteration, the best start's rollout and its gains.
    #[arg(long, default_value_t = DEFAULT_MAX_ITERATIONS)]
    pub max_iterations: usize,
    #[arg(long, default_value_t = DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Return the best plan so far after this many milliseconds (0: no limit).
    #[arg(long, default_value_t = 0)]
    pub time_limit_ms: u64,
    /// ilqr (single shooting on the model's one-step map) or dircol (direct collocation on
    /// its continuous dynamics); docs/control.md says when to pick which.
    #[arg(long, default_value = "ilqr")]
    pub method: String,
    /// On an ensemble: mean_dynamics (plan on the members' average next state) or mean
    /// (minimize the members' average cost); README "Ensembles and uncertainty".
    #[arg(long, default_value = "mean_dynamics")]
    pub ensemble_cost: String,
    /// dircol's initial states: `line` (straight from x0 to the goal) or a JSON file of T+1
    /// rows of nq + nv values (default: the rollout of zero inputs).
    #[arg(long)]
    pub x_init: Option<String>,
    /// dircol's lower state bounds, nq + nv values (`inf`/`-inf`: none on that coordinate), on
    /// every state after x0.
    #[arg(long, allow_hyphen_values = true)]
    pub x_min: Option<String>,
    /// dircol's upper state bounds, nq + nv values.
    #[arg(long, allow_hyphen_values = true)]
    pub x_max: Option<String>,
    /// Where to write the plan (JSON: x, u, K, costs, goal_error; a summary goes to stdout).
    #[arg(long)]
    pub out: PathBuf,
}

/// "1,2,3" → [1, 2, 3], `len` values.
fn values(field: &str, text: &str, len: usize) -> Result<Vec<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| {
            s.trim()
                .parse()
                .map_err(|_| Error::invalid(field, format!("'{}' is not a number", s.trim())))
        })
        .collect::<Result<_>>()?;
    if v.len() != len {
        return Err(Error::invalid(
            field,
            format!("expected {len} values, got {}", v.len()),
        ));
    }
    Ok(v)
}

/// The request from the flags: states nx wide, the state weights' diagonals ndx wide.
fn request(a: &PlanArgs, (nx, ndx): (usize, usize), m: usize) -> Result<PlanRequest> {
    let q = match &a.q_diag {
        Some(s) => values("q_diag", s, ndx)?,
        None => (0..ndx)
            .map(|i| if i < ndx / 2 { 1.0 } else { 0.1 })
            .collect(),
    };
    let r = match &a.r_diag {
        Some(s) => values("r_diag", s, m)?,
        None => vec![1e-4; m],
    };
    let qf = match &a.qf_diag {
        Some(s) => values("qf_diag", s, ndx)?,
        None => q.iter().map(|v| 1000.0 * v).collect(),
    };
    let bound =
        |name: &str, v: &Option<String>| v.as_deref().map(|s| values(name, s, m)).transpose();
    Ok(PlanRequest {
        x0: values("x0", &a.x0, nx)?,
        goal: values("goal", &a.goal, nx)?,
        horizon: check_horizon(a.horizon, a.max_plan_horizon)?,
        q: Mat::diag(&q),
        r: Mat::diag(&r),
        qf: Mat::diag(&qf),
        u_min: bound("u_min", &a.u_min)?,
        u_max: bound("u_max", &a.u_max)?,
        u_init: None,
        x_init: a
            .x_init
            .as_deref()
            .map(|s| initial_states(s, a, nx))
            .transpose()?,
        x_min: (a.x_min.as_deref())
            .map(|s| values("x_min", s, nx))
            .transpose()?,
        x_max: (a.x_max.as_deref())
            .map(|s| values("x_max", s, nx))
            .transpose()?,
        method: Method::parse(&a.method)?,
        ensemble_cost: EnsembleCost::parse(&a.ensemble_cost)?,
        max_iterations: a.max_iterations,
        tolerance: a.tolerance,
        restarts: a.restarts,
        seed: a.seed,
        time_limit: time_limit_in(a.time_limit_ms),
    })
}

/// `--x-init`: `line`, or a JSON file's `[[…nq + nv values], …]` rows.
fn initial_states(text: &str, a: &PlanArgs, nx: usize) -> Result<Mat> {
    let rows = usize::try_from(a.horizon)
        .unwrap_or(usize::MAX)
        .saturating_add(1);
    if text == "line" {
        let (x0, goal) = (values("x0", &a.x0, nx)?, values("goal", &a.goal, nx)?);
        return Ok(Mat::new(rows, nx, straight_line(&x0, &goal, rows - 1)));
    }
    let bytes = std::fs::read(text)
        .map_err(|e| Error::invalid("x_init", format!("cannot read {text}: {e}")))?;
    let parsed: Vec<Vec<f64>> = serde_json::from_slice(&bytes).map_err(|e| {
        Error::invalid(
            "x_init",
            format!("{text} is not a JSON list of rows of numbers: {e}"),
        )
    })?;
    let cols = parsed.first().map_or(0, Vec::len);
    if let Some(i) = parsed.iter().position(|r| r.len() != cols) {
        return Err(Error::invalid(
            "x_init",
            format!("row {i} has {} values, row 0 has {cols}", parsed[i].len()),
        ));
    }
    Ok(Mat::new(parsed.len(), cols, parsed.concat()))
}

pub(super) fn run(a: PlanArgs) -> Result<()> {
    let file = super::model::read(&a.model)?;
    let eval = Evaluator::from_file(&file)?;
    let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
    let req = request(&a, (nx, ndx), m)?.with_effort_limits(&eval.effort_limits());
    // Looked at the start's and the goal's configurations besides q = 0.
    let q = |x: &[f64]| x[..eval.config.nq()].to_vec();
    if let Some(w) = file.stiffness_warning(&[q(&req.x0), q(&req.goal)]) {
        eprintln!("warning: {}", w.message);
    }
    let started = Instant::now();
    let p = eval.plan(&req, &|| false)?;
    let seconds = started.elapsed().as_secs_f64();
    let rows =
        |v: &[f64], w: usize| -> Vec<Vec<f64>> { v.chunks(w).map(<[f64]>::to_vec).collect() };
    let k: Vec<Vec<Vec<f64>>> = p.gains.k.iter().map(|k| rows(&k.data, k.cols)).collect();
    let mut out = json!({
        "x": rows(&p.x, nx), "u": rows(&p.u, m), "K": k, "cost": p.cost, "costs": p.costs,
        "iterations": p.iterations, "converged": p.converged, "goal_error": p.goal_error,
        "dt": eval.config.dt, "u_min": req.u_min, "u_max": req.u_max, "seconds": seconds,
        "method": p.method.name(), "constraint_violation": p.constraint_violation,
        "rollout_deviation": p.rollout_deviation,
    });
    if let Some(std) = &p.x_std {
        out["x_std"] = json!(rows(std, nx));
        out["ensemble_cost"] = json!(req.ensemble_cost.name());
    }
    write_atomic(
        &a.out,
        serde_json::to_string_pretty(&out).expect("json").as_bytes(),
    )?;
    super::say(
        json!({"out": a.out, "method": p.method.name(), "cost": p.cost,
               "iterations": p.iterations, "converged": p.converged, "goal_error": p.goal_error,
               "constraint_violation": p.constraint_violation, "seconds": seconds}),
    )?;
    Ok(())
}
