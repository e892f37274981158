//! graybox's trained models inside a Python process, with no server: `graybox_native.load`
//! reads a model file (every format the service loads, ensembles included) and the model
//! answers Predict, Rollout (an ensemble's particles too), Linearize, TVLQR, Plan and Energy
//! from NumPy arrays, with the gRPC client's arguments and return conventions, computed by
//! the inference core (`graybox-core`) the service runs, so the answers are the service's,
//! bit for bit. Every computation runs with the GIL released: threads sharing one model run in
//! parallel. A call is admitted under the module's memory budget before it computes, and a
//! long one hears Ctrl-C (`guard`).

mod convert;
mod energy;
mod guard;
mod plan;
mod rollout;

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyFloat, PyType};

use convert::{ArrayIn, OrPy, array, inputs, rows, shaped};
use graybox_core::error::Error;
use graybox_core::infer::{Evaluator, finite_rows};
use graybox_core::model::file::ModelFile;
use guard::{Interrupt, admit};

/// `graybox_native.Info`, looked up once.
static INFO: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// A loaded model: immutable, shareable across threads.
#[pyclass(frozen, module = "graybox_native")]
struct Model {
    eval: Evaluator,
    /// The coordinates' and inputs' names.
    names: (Vec<String>, Vec<String>),
}

/// The model in a `.gbx` file (a path) or in its bytes.
#[pyfunction]
fn load(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<Model> {
    let file = if let Ok(bytes) = source.cast::<PyBytes>() {
        let bytes = bytes.as_bytes().to_vec();
        py.detach(move || ModelFile::from_bytes(&bytes).map_err(bad_source))
    } else {
        let path: PathBuf = source.extract()?;
        py.detach(move || read(&path))
    };
    let file = file.or_py(py)?;
    warn_unchecked(py, &file)?;
    let eval = py.detach(|| Evaluator::from_file(&file)).or_py(py)?;
    let c = &eval.config;
    let names = match c.template() {
        Some(t) => (t.coordinates(), t.inputs()),
        None => (
            (1..=c.nv()).map(|i| format!("q{i}")).collect(),
            (1..=c.m).map(|i| format!("u{i}")).collect(),
        ),
    };
    Ok(Model { eval, names })
}

/// A model file's contents.
fn read(path: &std::path::Path) -> Result<ModelFile, Error> {
    let bytes = std::fs::read(path)
        .map_err(|e| Error::invalid("source", format!("cannot read {}: {e}", path.display())))?;
    ModelFile::from_bytes(&bytes).map_err(bad_source)
}

/// A file that does not prove it is whole (written before files carried a checksum) loads
/// with `graybox_native.UncheckedModelWarning`, through Python's `warnings`, so that a caller
/// may filter it, log it or make it an error.
fn warn_unchecked(py: Python<'_>, file: &ModelFile) -> PyResult<()> {
    let Some(w) = file.unchecked_warning() else {
        return Ok(());
    };
    let category = py
        .import("graybox_native")?
        .getattr("UncheckedModelWarning")?;
    let message = std::ffi::CString::new(w.message).unwrap_or_default();
    PyErr::warn(py, &category, &message, 1)
}

/// Bytes that are not a model file: the caller's bad input, not the library's fault.
fn bad_source(e: Error) -> Error {
    Error::invalid("source", e.to_string())
}

#[pymethods]
impl Model {
    /// nq and nv (a state is [q, v], nq + nv values; `n`, deprecated, is nv), m, dt, the
    /// ensemble's member count, the integrator, the joints, and the coordinates' and inputs'
    /// names, as a `graybox_native.Info` (attributes, and item access as a dict's).
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let c = &self.eval.config;
        let d = PyDict::new(py);
        d.set_item("nq", c.nq())?;
        d.set_item("nv", c.nv())?;
        d.set_item("n", c.nv())?;
        let joints: Vec<&str> = c.space.joints().iter().map(|j| j.name()).collect();
        d.set_item("joints", joints)?;
        d.set_item("m", c.m)?;
        d.set_item("dt", c.dt)?;
        d.set_item("members", self.eval.member_count())?;
        d.set_item("integrator", c.integrator.name())?;
        d.set_item("coordinates", self.names.0.clone())?;
        d.set_item("inputs", self.names.1.clone())?;
        INFO.import(py, "graybox_native", "Info")?
            .call((), Some(&d))
    }

    fn __repr__(&self) -> String {
        let c = &self.eval.config;
        format!(
            "graybox_native.Model(nq={}, nv={}, m={}, dt={}, members={})",
            c.nq(),
            c.nv(),
            c.m,
            c.dt,
            self.eval.member_count()
        )
    }

    /// x' = f(x, u) for x [nq + nv] and u [m], or a batch x [B, nq + nv] and u [B, m]; with
    /// `want_accel` also v̇ ([nv] or [B, nv]). An ensemble answers with its members' mean;
    /// `return_std` adds their standard deviation of x' (zeros for a single model) and
    /// `members` every member's x' ([K, nq + nv] or [K, B, nq + nv]), in that order after x'
    /// (and v̇);
    /// `return_z` adds max_abs_z last (a float, or [B]): the largest |z-score| of q, q̇ and u
    /// under the training data's statistics (above ~4, treat the answer with doubt).
    /// `dt` is the step in seconds (None: the model's own, `info.dt`): the dynamics are
    /// continuous, so a model trained at one rate predicts at another.
    #[pyo3(signature = (x, u=None, want_accel=false, return_std=false, members=false,
        return_z=false, dt=None))]
    #[allow(clippy::too_many_arguments)]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
        want_accel: bool,
        return_std: bool,
        members: bool,
        return_z: bool,
        dt: Option<f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (n, m) = (self.eval.config.nv(), self.eval.config.m);
        let dt = self.eval.step_seconds(dt).or_py(py)?;
        let nx = self.eval.config.nx();
        let xs = rows("x", Some(&x), nx).or_py(py)?;
        let us = inputs(&xs, rows("u", u.as_ref(), m).or_py(py)?, m).or_py(py)?;
        let (b, single) = (xs.rows, xs.single);
        let eval = &self.eval;
        let spread = return_std || members;
        admit(py, &eval.predict_cost(b, want_accel, members))?;
        let interrupt = Interrupt::new();
        let stop = || interrupt.stop();
        let out = py.detach(|| -> Result<_, Error> {
            let out = if spread {
                let Some(p) = eval.predict_members_until(&xs.data, &us, dt, want_accel, &stop)
                else {
                    return Ok(None);
                };
                (p.mean, p.accel, Some(p.std), Some(p.next))
            } else {
                let Some((next, accel)) = eval.predict_until(&xs.data, &us, dt, want_accel, &stop)
                else {
                    return Ok(None);
                };
                (next, accel, None, None)
            };
            finite_rows("x", "next state", &out.0, nx)?;
            let z = return_z.then(|| eval.max_abs_z(&xs.data, &us));
            Ok(Some((out, z)))
        });
        let ((next, accel, std, each), z) = interrupt.answer(py, out)?;
        let mut items = vec![array(py, next, &shaped(single, b, &[nx]))?];
        if let Some(accel) = accel {
            items.push(array(py, accel, &shaped(single, b, &[n]))?);
        }
        if return_std {
            let std = std.expect("asked for");
            items.push(array(py, std, &shaped(single, b, &[nx]))?);
        }
        if members {
            let each = each.expect("asked for");
            let k = each.len();
            let mut shape = vec![k];
            shape.extend(shaped(single, b, &[nx]));
            items.push(array(py, each.concat(), &shape)?);
        }
        if let Some(z) = z {
            items.push(z_of(py, z, single)?);
        }
        one_or_tuple(py, items)
    }

    /// One step: x' for x [nq + nv] and u [m] (or batches), as `predict` with no extras.
    #[pyo3(signature = (x, u=None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.predict(py, x, u, false, false, false, false, None)
    }

    /// A and B of the one-step map in the tangent space, x' ⊖ x̄' = A (x ⊖ x̄) + B (u − ū):
    /// [2nv, 2nv] and [2nv, m] at one point, [B, 2nv, 2nv] and [B, 2nv, m] for a batch (for
    /// nq = nv, ∂f/∂x and ∂f/∂u). An ensemble's are its members' mean.
    /// `return_z` adds max_abs_z (a float, or [B]) as (A, B, z).
    #[pyo3(signature = (x, u=None, return_z=false))]
    fn linearize<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
        return_z: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let c = &self.eval.config;
        let (nx, ndx, m) = (c.nx(), c.ndx(), c.m);
        let xs = rows("x", Some(&x), nx).or_py(py)?;
        let us = inputs(&xs, rows("u", u.as_ref(), m).or_py(py)?, m).or_py(py)?;
        let eval = &self.eval;
        admit(py, &eval.linearize_cost(xs.rows))?;
        let interrupt = Interrupt::new();
        let out = py.detach(|| -> Result<_, Error> {
            let Some((a, b)) = eval.linearize_until(&xs.data, &us, &|| interrupt.stop()) else {
                return Ok(None);
            };
            finite_rows("x", "linearization", &a, ndx * ndx)?;
            finite_rows("x", "linearization", &b, ndx * m)?;
            let z = return_z.then(|| eval.max_abs_z(&xs.data, &us));
            Ok(Some((a, b, z)))
        });
        let (a, b, z) = interrupt.answer(py, out)?;
        let (single, rows) = (xs.single, xs.rows);
        let mut items = vec![
            array(py, a, &shaped(single, rows, &[ndx, ndx]))?,
            array(py, b, &shaped(single, rows, &[ndx, m]))?,
        ];
        if let Some(z) = z {
            items.push(z_of(py, z, single)?);
        }
        one_or_tuple(py, items)
    }

    /// The states x_0..x_T ([T+1, nq + nv]) from x0 under inputs u [T, m], or under a TVLQR
    /// policy (x_bar [T+1 or T, nq + nv], u_bar [T, m], K [T, m, 2nv]) applying
    /// u_t = ū_t − K_t(x_t ⊖ x̄_t). `with_inputs` also returns the applied inputs [T, m] and
    /// `return_z` max_abs_z [T] of each (x_t, u_t), last: (xs, us, z).
    ///
    /// `particles` P (1..1024) propagates P particles from x0, particle p following ensemble
    /// member p mod K throughout (TS∞), a policy's input computed from its own state: xs is
    /// their mean and their standard deviation [T+1, nq + nv] follows it, (xs, std, …); the
    /// inputs are the particles' mean, z the largest over them. `dt` is the seconds between
    /// states (None: the model's own, as `predict`'s).
    #[pyo3(signature = (x0, u=None, policy=None, with_inputs=false, return_z=false,
        particles=None, dt=None))]
    #[allow(clippy::too_many_arguments)]
    fn rollout<'py>(
        &self,
        py: Python<'py>,
        x0: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
        policy: Option<(ArrayIn<'py>, ArrayIn<'py>, ArrayIn<'py>)>,
        with_inputs: bool,
        return_z: bool,
        particles: Option<i128>,
        dt: Option<f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let want = rollout::Want {
            with_inputs,
            return_z,
            particles,
            dt,
        };
        let items = rollout::rollout(py, &self.eval, x0, u, policy, want)?;
        one_or_tuple(py, items)
    }

    /// TVLQR gains K [T, m, 2nv] and cost-to-go S [T+1, 2nv, 2nv] along x̄ [T+1, nq + nv],
    /// ū [T, m], for the cost Σ δxᵀQδx + δuᵀRδu + δx_TᵀQf δx_T (no ½; δx = x ⊖ x̄, Q and Qf
    /// [2nv, 2nv]).
    #[pyo3(signature = (xbar, ubar, Q, R, Qf))]
    #[allow(non_snake_case)]
    fn tvlqr<'py>(
        &self,
        py: Python<'py>,
        xbar: ArrayIn<'py>,
        ubar: ArrayIn<'py>,
        Q: ArrayIn<'py>,
        R: ArrayIn<'py>,
        Qf: ArrayIn<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        plan::tvlqr(py, &self.eval, (xbar, ubar), [Q, R, Qf])
    }

    /// A trajectory of `horizon` steps from x0 toward `goal`, as the service's Plan (see
    /// `graybox_client.Client.plan`): iLQR or direct collocation, TVLQR gains along it.
    #[pyo3(signature = (x0, goal, horizon, Q, R, Qf, u_min=None, u_max=None, u_init=None,
        max_iterations=200, tolerance=1e-6, restarts=0, seed=0, time_limit_ms=0,
        method="ilqr", x_init=None, x_min=None, x_max=None, ensemble_cost=""))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn plan<'py>(
        &self,
        py: Python<'py>,
        x0: ArrayIn<'py>,
        goal: ArrayIn<'py>,
        horizon: i128,
        Q: ArrayIn<'py>,
        R: ArrayIn<'py>,
        Qf: ArrayIn<'py>,
        u_min: Option<ArrayIn<'py>>,
        u_max: Option<ArrayIn<'py>>,
        u_init: Option<ArrayIn<'py>>,
        max_iterations: i128,
        tolerance: f64,
        restarts: i128,
        seed: i128,
        time_limit_ms: i128,
        method: &str,
        x_init: Option<ArrayIn<'py>>,
        x_min: Option<ArrayIn<'py>>,
        x_max: Option<ArrayIn<'py>>,
        ensemble_cost: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let args = plan::PlanArgs {
            x0,
            goal,
            horizon,
            weights: [Q, R, Qf],
            u_bounds: [u_min, u_max],
            u_init,
            x_init,
            x_bounds: [x_min, x_max],
            max_iterations,
            tolerance,
            restarts,
            seed,
            time_limit_ms,
            method,
            ensemble_cost,
        };
        plan::plan(py, &self.eval, args)
    }

    /// Energy and work at x [2n] under u [m], or a batch x [B, 2n] and u [B, m], as the gRPC
    /// client's `energy`: a dict of `kinetic`, `potential`, `total`, `power` (q̇ᵀF) — floats,
    /// or [B] — and the dynamics M q̈ + c + ∇V = F term by term, `inertial`, `coriolis`,
    /// `gravity`, `applied` ([n] or [B, n]), with `parts`: F's named parts, {name: [n] or
    /// [B, n]}, and `damping`, the names the spec calls damping or friction. An ensemble's
    /// are its members' means; a naive model has none: FAILED_PRECONDITION.
    #[pyo3(signature = (x, u=None))]
    fn energy<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        energy::energy(py, &self.eval, x, u)
    }

    /// The generalized force τ = M q̈ + c + ∇V − F(q, q̇, 0) that produces accelerations
    /// qdd [nv] at x [nq + nv] (or a batch [B, nv] at [B, nq + nv]), as the gRPC client's
    /// `inverse_dynamics`: a dict of `tau`, `inertial`, `coriolis`, `gravity`, `passive`
    /// (F(q, q̇, 0)) and `parts`, F(q, q̇, 0)'s named parts. A naive model has none.
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        qdd: ArrayIn<'py>,
    ) -> PyResult<Bound<'py, PyDict>> {
        energy::inverse(py, &self.eval, x, qdd)
    }
}

/// max_abs_z as the gRPC client returns it: a float for one state, else [B].
fn z_of<'py>(py: Python<'py>, z: Vec<f64>, single: bool) -> PyResult<Bound<'py, PyAny>> {
    if single {
        return Ok(PyFloat::new(py, z[0]).into_any());
    }
    let b = z.len();
    array(py, z, &[b])
}

/// One value alone, several as a tuple (as the gRPC client returns them).
fn one_or_tuple<'py>(
    py: Python<'py>,
    mut items: Vec<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    if items.len() == 1 {
        return Ok(items.pop().expect("one"));
    }
    Ok(pyo3::types::PyTuple::new(py, items)?.into_any())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(guard::set_memory_budget_mb, m)?)?;
    m.add_function(wrap_pyfunction!(guard::memory_budget_mb, m)?)?;
    m.add_class::<Model>()?;
    Ok(())
}
