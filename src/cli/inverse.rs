//! `graybox inverse-dynamics`: the generalized force τ a model file says produces given
//! accelerations at given states (docs/energy.md, "Inverse dynamics"), with its terms.

use std::path::PathBuf;

use clap::Args;
use serde::Deserialize;
use serde_json::json;

use crate::error::{Error, Result};
use crate::infer::Evaluator;

#[derive(Args, Debug)]
pub struct InverseArgs {
    /// A model file (.gbx) that `train` or `model` wrote, or the service served.
    #[arg(long)]
    pub model: PathBuf,
    /// A JSON file of states and accelerations: {"q": [[…]], "qdot": [[…]], "qddot": [[…]]},
    /// one row per state (nq, nv and nv wide).
    #[arg(long)]
    pub states: PathBuf,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct States {
    q: Vec<Vec<f64>>,
    qdot: Vec<Vec<f64>>,
    qddot: Vec<Vec<f64>>,
}

pub(super) fn inverse(a: InverseArgs) -> Result<()> {
    let eval = Evaluator::from_file(&super::model::read(&a.model)?)?;
    eval.check_energy()?;
    let text = std::fs::read_to_string(&a.states).map_err(|e| {
        Error::invalid("states", format!("cannot read {}: {e}", a.states.display()))
    })?;
    let s: States = serde_json::from_str(&text)
        .map_err(|e| Error::invalid("states", format!("{}: {e}", a.states.display())))?;
    let (nq, nv) = (eval.config.nq(), eval.config.nv());
    let rows = s.q.len();
    let mut x = Vec::with_capacity(rows * (nq + nv));
    let mut qdd = Vec::with_capacity(rows * nv);
    for (field, list, width) in [
        ("q", &s.q, nq),
        ("qdot", &s.qdot, nv),
        ("qddot", &s.qddot, nv),
    ] {
        if list.len() != rows {
            return Err(Error::invalid(
                field,
                format!("{} rows for {rows} of q", list.len()),
            ));
        }
        if let Some(k) = list.iter().position(|r| r.len() != width) {
            return Err(Error::invalid(
                field,
                format!(
                    "row {k} has {} values, the model's {field} {width}",
                    list[k].len()
                ),
            ));
        }
    }
    for k in 0..rows {
        x.extend(&s.q[k]);
        x.extend(&s.qdot[k]);
        qdd.extend(&s.qddot[k]);
    }
    let inv = eval
        .inverse_dynamics_until(&x, &qdd, &|| false)?
        .expect("never stopped");
    let e = &inv.terms;
    e.check_finite("states", nv)?;
    let row = |v: &[f64], k: usize| v[k * nv..(k + 1) * nv].to_vec();
    for k in 0..rows {
        let parts: serde_json::Map<String, serde_json::Value> = (e.parts.iter())
            .map(|p| (p.name.to_string(), json!(row(&p.values, k))))
            .collect();
        super::say(json!({
            "tau": row(&inv.tau, k), "inertial": row(&e.inertial, k),
            "coriolis": row(&e.coriolis, k), "gravity": row(&e.gravity, k),
            "passive": row(&e.applied, k), "parts": parts,
        }))?;
    }
    Ok(())
}
