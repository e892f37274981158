//! The control calls: a rollout's inputs (given or a TVLQR policy), TVLQR gains and plans,
//! checked as the service checks them, then solved by the core with the GIL released.

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyType};

use crate::convert::{ArrayIn, OrPy, array, matrix, py_error_at, values, whole};
use crate::guard::{Interrupt, admit};
use graybox_core::array::finite;
use graybox_core::control::linalg::Mat;
use graybox_core::control::plan::{
    DEFAULT_MAX_PLAN_HORIZON, EnsembleCost, Method, PlanRequest, check_horizon, time_limit_in,
    validate,
};
use graybox_core::control::policy::Policy;
use graybox_core::error::{Error, Result};
use graybox_core::infer::Evaluator;
use graybox_core::infer::limits::Cost;
use graybox_core::physics::space::Space;

/// The input at step t in state x.
pub type Inputs = Box<dyn Fn(usize, &[f64]) -> Vec<f64> + Send + Sync>;

/// A rollout's length and its inputs: the rows of `u`, or a policy's.
pub fn rollout_inputs(
    u: Option<&ArrayIn<'_>>,
    policy: Option<&(ArrayIn<'_>, ArrayIn<'_>, ArrayIn<'_>)>,
    space: &Space,
    m: usize,
) -> Result<(usize, Inputs)> {
    let (nx, ndx) = (space.nq() + space.nv(), 2 * space.nv());
    match (u, policy) {
        (Some(_), Some(_)) => Err(Error::invalid("policy", "give u or policy, not both")),
        (None, None) => Err(Error::invalid("u", "give u [T, m] or a policy")),
        (Some(u), None) => {
            let (u, shape) = values(u);
            let steps = match shape[..] {
                [t, w] if w == m => t,
                _ => {
                    return Err(Error::invalid(
                        "u",
                        format!("expected shape [T, {m}], got {shape:?}"),
                    ));
                }
            };
            finite("u", &u, m)?;
            Ok((steps, Box::new(move |t, _| u[t * m..(t + 1) * m].to_vec())))
        }
        (None, Some((xbar, ubar, k))) => {
            let ((xbar, xs), (ubar, us), (k, ks)) = (values(xbar), values(ubar), values(k));
            let steps = match us[..] {
                [t, w] if w == m => t,
                _ => {
                    return Err(Error::invalid(
                        "policy.u_bar",
                        format!("expected shape [T, {m}], got {us:?}"),
                    ));
                }
            };
            if !(xs == [steps + 1, nx] || xs == [steps, nx]) {
                return Err(Error::invalid(
                    "policy.x_bar",
                    format!(
                        "expected shape [{}, {nx}] or [{steps}, {nx}], got {xs:?}",
                        steps + 1
                    ),
                ));
            }
            if ks != [steps, m, ndx] {
                return Err(Error::invalid(
                    "policy.K",
                    format!("expected shape [{steps}, {m}, {ndx}], got {ks:?}"),
                ));
            }
            finite("policy.x_bar", &xbar, nx)?;
            finite("policy.u_bar", &ubar, m)?;
            finite("policy.K", &k, m * ndx)?;
            let p = Policy {
                xbar,
                ubar,
                k,
                space: space.clone(),
                m,
            };
            Ok((steps, Box::new(move |t, x| p.input(t, x))))
        }
    }
}

/// K [T, m, 2nv] and S [T+1, 2nv, 2nv] along (x̄, ū), on tangent-space deviations.
pub fn tvlqr<'py>(
    py: Python<'py>,
    eval: &Evaluator,
    (xbar, ubar): (ArrayIn<'py>, ArrayIn<'py>),
    [q, r, qf]: [ArrayIn<'py>; 3],
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
    let checked = || -> Result<_> {
        let ((xbar, xs), (ubar, us)) = (values(&xbar), values(&ubar));
        let t = match us[..] {
            [t, w] if w == m && t > 0 => t,
            _ => {
                return Err(Error::invalid(
                    "ubar",
                    format!("expected shape [T, {m}] with T ≥ 1, got {us:?}"),
                ));
            }
        };
        if xs != [t + 1, nx] {
            return Err(Error::invalid(
                "xbar",
                format!(
                    "needs T+1 = {} states of {nx} for T = {t} inputs, got {xs:?}",
                    t + 1
                ),
            ));
        }
        finite("xbar", &xbar, nx)?;
        finite("ubar", &ubar, m)?;
        let weights = [
            matrix("Q", &q, ndx, ndx)?,
            matrix("R", &r, m, m)?,
            matrix("Qf", &qf, ndx, ndx)?,
        ];
        Ok((xbar, ubar, weights, t))
    };
    let (xbar, ubar, [q, r, qf], t) = checked().or_py(py)?;
    let cost = eval.tvlqr_cost(t);
    admit(
        py,
        &Cost {
            field: "ubar",
            ..cost
        },
    )?;
    let interrupt = Interrupt::new();
    let stop = || interrupt.stop();
    let gains = py.detach(|| {
        eval.tvlqr_until(&xbar, &ubar, [&q, &r, &qf], &stop)
            .map(Some)
    });
    let gains = interrupt.answer(py, gains)?;
    let flat = |mats: Vec<Mat>| mats.into_iter().flat_map(|m| m.data).collect::<Vec<_>>();
    Ok((
        array(py, flat(gains.k), &[t, m, ndx])?,
        array(py, flat(gains.s), &[t + 1, ndx, ndx])?,
    ))
}

/// A plan call's arguments, as the service's Plan message has them.
pub struct PlanArgs<'py, 'a> {
    pub x0: ArrayIn<'py>,
    pub goal: ArrayIn<'py>,
    pub horizon: i128,
    pub weights: [ArrayIn<'py>; 3],
    pub u_bounds: [Option<ArrayIn<'py>>; 2],
    pub u_init: Option<ArrayIn<'py>>,
    pub x_init: Option<ArrayIn<'py>>,
    pub x_bounds: [Option<ArrayIn<'py>>; 2],
    pub max_iterations: i128,
    pub tolerance: f64,
    pub restarts: i128,
    pub seed: i128,
    pub time_limit_ms: i128,
    pub method: &'a str,
    pub ensemble_cost: &'a str,
}

/// The horizon, as the service's limit has it: too long is RESOURCE_EXHAUSTED, so the field
/// is named here.
fn horizon(py: Python<'_>, horizon: i128) -> PyResult<usize> {
    whole("horizon", horizon, u64::MAX)
        .and_then(|h| check_horizon(h, DEFAULT_MAX_PLAN_HORIZON))
        .map_err(|e| py_error_at(py, e, "horizon"))
}

/// The core's request from the arguments, checked against the model as the service does.
fn request(eval: &Evaluator, a: &PlanArgs<'_, '_>, horizon: usize) -> Result<PlanRequest> {
    let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
    let count = |field: &str, v: i128| whole(field, v, usize::MAX as u64).map(|v| v as usize);
    let flat = |v: &Option<ArrayIn<'_>>| v.as_ref().map(|v| values(v).0);
    let rows = |name: &str, v: &Option<ArrayIn<'_>>, width: usize| -> Result<Option<Mat>> {
        let Some(v) = v else { return Ok(None) };
        let r = values(v).1.first().copied().unwrap_or(0);
        matrix(name, v, r, width).map(Some)
    };
    let [q, r, qf] = &a.weights;
    let req = PlanRequest {
        x0: values(&a.x0).0,
        goal: values(&a.goal).0,
        horizon,
        q: matrix("Q", q, ndx, ndx)?,
        r: matrix("R", r, m, m)?,
        qf: matrix("Qf", qf, ndx, ndx)?,
        u_min: flat(&a.u_bounds[0]),
        u_max: flat(&a.u_bounds[1]),
        u_init: rows("u_init", &a.u_init, m)?,
        x_init: rows("x_init", &a.x_init, nx)?,
        x_min: flat(&a.x_bounds[0]),
        x_max: flat(&a.x_bounds[1]),
        method: Method::parse(a.method)?,
        ensemble_cost: EnsembleCost::parse(a.ensemble_cost)?,
        max_iterations: count("max_iterations", a.max_iterations)?,
        tolerance: a.tolerance,
        restarts: count("restarts", a.restarts)?,
        seed: whole("seed", a.seed, u64::MAX)?,
        time_limit: time_limit_in(whole("time_limit_ms", a.time_limit_ms, u64::MAX)?),
    };
    let req = req.with_effort_limits(&eval.effort_limits());
    validate(&req, (nx, ndx), m)?;
    Ok(req)
}

static PLAN_RESULT: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The plan as `graybox_native.PlanResult` (the fields of the client's).
pub fn plan<'py>(
    py: Python<'py>,
    eval: &Evaluator,
    a: PlanArgs<'py, '_>,
) -> PyResult<Bound<'py, PyAny>> {
    let horizon = horizon(py, a.horizon)?;
    let req = request(eval, &a, horizon).or_py(py)?;
    admit(py, &eval.plan_cost(&req))?;
    let interrupt = Interrupt::new();
    let p = py.detach(|| eval.plan(&req, &|| interrupt.stop()).map(Some));
    let p = interrupt.answer(py, p)?;
    let c = &eval.config;
    let (nx, ndx, m, t) = (c.nx(), c.ndx(), c.m, req.horizon);
    let d = PyDict::new(py);
    d.set_item("x", array(py, p.x, &[t + 1, nx])?)?;
    d.set_item("u", array(py, p.u, &[t, m])?)?;
    let k: Vec<f64> = p.gains.k.into_iter().flat_map(|k| k.data).collect();
    d.set_item("K", array(py, k, &[t, m, ndx])?)?;
    d.set_item("cost", p.cost)?;
    d.set_item("costs", array(py, p.costs.clone(), &[p.costs.len()])?)?;
    d.set_item("iterations", p.iterations)?;
    d.set_item("converged", p.converged)?;
    d.set_item("goal_error", p.goal_error)?;
    d.set_item("method", p.method.name())?;
    d.set_item("constraint_violation", p.constraint_violation)?;
    d.set_item("rollout_deviation", p.rollout_deviation)?;
    let x_std = p.x_std.map(|s| array(py, s, &[t + 1, nx])).transpose()?;
    d.set_item("x_std", x_std)?;
    let class = PLAN_RESULT.import(py, "graybox_native", "PlanResult")?;
    class.call((), Some(&d))
}
