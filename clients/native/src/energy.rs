//! Energy and power at a batch of states, as the service's Energy computes them (the core's
//! `energy_until`, its estimate and its finiteness check), answered as the gRPC client's
//! `energy` answers: a dict of floats (or [B]) and arrays ([n] or [B, n]); and inverse
//! dynamics, as the service's InverseDynamics.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{ArrayIn, OrPy, array, inputs, rows, shaped};
use crate::guard::{Interrupt, admit};
use graybox_core::error::Error;
use graybox_core::infer::Evaluator;

pub fn energy<'py>(
    py: Python<'py>,
    eval: &Evaluator,
    x: ArrayIn<'py>,
    u: Option<ArrayIn<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (n, m) = (eval.config.nv(), eval.config.m);
    // A naive model is refused before its arguments are read, as the service refuses it.
    eval.check_energy().or_py(py)?;
    let xs = rows("x", Some(&x), eval.config.nx()).or_py(py)?;
    let us = inputs(&xs, rows("u", u.as_ref(), m).or_py(py)?, m).or_py(py)?;
    let (b, single) = (xs.rows, xs.single);
    admit(py, &eval.energy_cost(b))?;
    let interrupt = Interrupt::new();
    let out = py.detach(|| -> Result<_, Error> {
        let Some(e) = eval.energy_until(&xs.data, &us, &|| interrupt.stop())? else {
            return Ok(None);
        };
        e.check_finite("x", n)?;
        Ok(Some(e))
    });
    let e = interrupt.answer(py, out)?;
    let d = PyDict::new(py);
    let per_state = [
        ("kinetic", e.kinetic),
        ("potential", e.potential),
        ("total", e.total),
        ("power", e.power),
    ];
    for (key, v) in per_state {
        if single {
            d.set_item(key, v[0])?;
        } else {
            d.set_item(key, array(py, v, &[b])?)?;
        }
    }
    let per_coordinate = [
        ("inertial", e.inertial),
        ("coriolis", e.coriolis),
        ("gravity", e.gravity),
        ("applied", e.applied),
    ];
    let shape = shaped(single, b, &[n]);
    for (key, v) in per_coordinate {
        d.set_item(key, array(py, v, &shape)?)?;
    }
    let parts = PyDict::new(py);
    let damping = PyList::empty(py);
    for p in e.parts {
        if p.dissipation {
            damping.append(p.name)?;
        }
        parts.set_item(p.name, array(py, p.values, &shape)?)?;
    }
    d.set_item("parts", parts)?;
    d.set_item("damping", damping)?;
    Ok(d)
}

pub fn inverse<'py>(
    py: Python<'py>,
    eval: &Evaluator,
    x: ArrayIn<'py>,
    qdd: ArrayIn<'py>,
) -> PyResult<Bound<'py, PyDict>> {
    let n = eval.config.nv();
    eval.check_energy().or_py(py)?;
    let xs = rows("x", Some(&x), eval.config.nx()).or_py(py)?;
    let qs = rows("qdd", Some(&qdd), n).or_py(py)?;
    if qs.rows != xs.rows {
        let e = Error::invalid("qdd", format!("has {} rows but x has {}", qs.rows, xs.rows));
        return Err(e).or_py(py);
    }
    let (b, single) = (xs.rows, xs.single);
    admit(py, &eval.energy_cost(b))?;
    let interrupt = Interrupt::new();
    let out = py.detach(|| -> Result<_, Error> {
        let stop = || interrupt.stop();
        let Some(inv) = eval.inverse_dynamics_until(&xs.data, &qs.data, &stop)? else {
            return Ok(None);
        };
        inv.terms.check_finite("x", n)?;
        Ok(Some(inv))
    });
    let inv = interrupt.answer(py, out)?;
    let shape = shaped(single, b, &[n]);
    let d = PyDict::new(py);
    let e = inv.terms;
    let terms = [
        ("tau", inv.tau),
        ("inertial", e.inertial),
        ("coriolis", e.coriolis),
        ("gravity", e.gravity),
        ("passive", e.applied),
    ];
    for (key, v) in terms {
        d.set_item(key, array(py, v, &shape)?)?;
    }
    let parts = PyDict::new(py);
    for p in e.parts {
        parts.set_item(p.name, array(py, p.values, &shape)?)?;
    }
    d.set_item("parts", parts)?;
    Ok(d)
}
