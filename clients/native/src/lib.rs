//! graybox's trained models inside a Python process, with no server: `graybox_native.load`
//! reads a model file (every format the service loads, ensembles included) and the model
//! answers Predict, Rollout, Linearize, TVLQR and Plan from NumPy arrays, computed by the
//! inference core (`graybox-core`) the service runs, so the answers are the service's, bit
//! for bit. Every computation runs with the GIL released: threads sharing one model run in
//! parallel. A call is admitted under the module's memory budget before it computes, and a
//! long one hears Ctrl-C (`guard`).

mod convert;
mod guard;
mod plan;

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use convert::{ArrayIn, OrPy, array, inputs, rows, shaped};
use graybox_core::error::Error;
use graybox_core::infer::{Evaluator, finite_rows};
use graybox_core::model::file::ModelFile;
use guard::{Interrupt, admit};

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
            (1..=c.n).map(|i| format!("q{i}")).collect(),
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
    /// n, m, dt, the ensemble's member count, and the coordinates' and inputs' names.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.eval.config;
        let d = PyDict::new(py);
        d.set_item("n", c.n)?;
        d.set_item("m", c.m)?;
        d.set_item("dt", c.dt)?;
        d.set_item("members", self.eval.member_count())?;
        d.set_item("integrator", c.integrator.name())?;
        d.set_item("coordinates", self.names.0.clone())?;
        d.set_item("inputs", self.names.1.clone())?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let c = &self.eval.config;
        format!(
            "graybox_native.Model(n={}, m={}, dt={}, members={})",
            c.n,
            c.m,
            c.dt,
            self.eval.member_count()
        )
    }

    /// x' = f(x, u) for x [2n] and u [m], or a batch x [B, 2n] and u [B, m]; with
    /// `want_accel` also q̈ ([n] or [B, n]). An ensemble answers with its members' mean;
    /// `return_std` adds their standard deviation of x' (zeros for a single model) and
    /// `members` every member's x' ([K, 2n] or [K, B, 2n]), in that order after x' (and q̈).
    #[pyo3(signature = (x, u=None, want_accel=false, return_std=false, members=false))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
        want_accel: bool,
        return_std: bool,
        members: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (n, m) = (self.eval.config.n, self.eval.config.m);
        let nx = 2 * n;
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
                let Some(p) = eval.predict_members_until(&xs.data, &us, want_accel, &stop) else {
                    return Ok(None);
                };
                (p.mean, p.accel, Some(p.std), Some(p.next))
            } else {
                let Some((next, accel)) = eval.predict_until(&xs.data, &us, want_accel, &stop)
                else {
                    return Ok(None);
                };
                (next, accel, None, None)
            };
            finite_rows("x", "next state", &out.0, nx)?;
            Ok(Some(out))
        });
        let (next, accel, std, each) = interrupt.answer(py, out)?;
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
        one_or_tuple(py, items)
    }

    /// One step: x' for x [2n] and u [m] (or batches), as `predict` with no extras.
    #[pyo3(signature = (x, u=None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.predict(py, x, u, false, false, false)
    }

    /// A = ∂f/∂x and B = ∂f/∂u of the one-step map: [2n, 2n] and [2n, m] at one point,
    /// [B, 2n, 2n] and [B, 2n, m] for a batch. An ensemble's are its members' mean.
    #[pyo3(signature = (x, u=None))]
    fn linearize<'py>(
        &self,
        py: Python<'py>,
        x: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let (nx, m) = (2 * self.eval.config.n, self.eval.config.m);
        let xs = rows("x", Some(&x), nx).or_py(py)?;
        let us = inputs(&xs, rows("u", u.as_ref(), m).or_py(py)?, m).or_py(py)?;
        let eval = &self.eval;
        admit(py, &eval.linearize_cost(xs.rows))?;
        let interrupt = Interrupt::new();
        let out = py.detach(|| -> Result<_, Error> {
            let Some((a, b)) = eval.linearize_until(&xs.data, &us, &|| interrupt.stop()) else {
                return Ok(None);
            };
            finite_rows("x", "linearization", &a, nx * nx)?;
            finite_rows("x", "linearization", &b, nx * m)?;
            Ok(Some((a, b)))
        });
        let (a, b) = interrupt.answer(py, out)?;
        let (single, rows) = (xs.single, xs.rows);
        Ok((
            array(py, a, &shaped(single, rows, &[nx, nx]))?,
            array(py, b, &shaped(single, rows, &[nx, m]))?,
        ))
    }

    /// The states x_0..x_T ([T+1, 2n]) from x0 under inputs u [T, m], or under a TVLQR
    /// policy (x_bar [T+1 or T, 2n], u_bar [T, m], K [T, m, 2n]) applying
    /// u_t = ū_t − K_t(x_t − x̄_t). `with_inputs` also returns the applied inputs [T, m].
    #[pyo3(signature = (x0, u=None, policy=None, with_inputs=false))]
    fn rollout<'py>(
        &self,
        py: Python<'py>,
        x0: ArrayIn<'py>,
        u: Option<ArrayIn<'py>>,
        policy: Option<(ArrayIn<'py>, ArrayIn<'py>, ArrayIn<'py>)>,
        with_inputs: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (nx, m) = (2 * self.eval.config.n, self.eval.config.m);
        let x0 = rows("x0", Some(&x0), nx).or_py(py)?;
        if !x0.single {
            return Err(Error::invalid("x0", "is one state [2n], not a batch")).or_py(py);
        }
        let (steps, input) = plan::rollout_inputs(u.as_ref(), policy.as_ref(), nx, m).or_py(py)?;
        let eval = &self.eval;
        admit(py, &eval.rollout_cost(steps, policy.is_some()))?;
        let interrupt = Interrupt::new();
        let out = py.detach(|| -> Result<_, Error> {
            let (mut xs, mut us) = (x0.data.clone(), Vec::with_capacity(steps * m));
            let mut stopped = false;
            eval.rollout(
                &x0.data,
                steps,
                |t, x| input(t, x),
                |x, u| {
                    xs.extend_from_slice(x);
                    us.extend_from_slice(u);
                    stopped = interrupt.stop();
                    !stopped
                },
            );
            if stopped {
                return Ok(None);
            }
            finite_rows("x0", "state", &xs, nx)?;
            Ok(Some((xs, us)))
        });
        let (xs, us) = interrupt.answer(py, out)?;
        let xs = array(py, xs, &[steps + 1, nx])?;
        if !with_inputs {
            return Ok(xs);
        }
        one_or_tuple(py, vec![xs, array(py, us, &[steps, m])?])
    }

    /// TVLQR gains K [T, m, 2n] and cost-to-go S [T+1, 2n, 2n] along x̄ [T+1, 2n], ū [T, m],
    /// for the cost Σ δxᵀQδx + δuᵀRδu + δx_TᵀQf δx_T (no ½).
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
