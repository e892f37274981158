//! Energy and power for a batch of states (`infer::energy`): T, V, E, the power of F and the
//! split M q̈ + c + ∇V = F with F's named parts. gRPC `Energy` and `POST
//! /v1/models/{id}/energy` call it; admitted like Predict (the response and the call's
//! memory, B states' worth, before it computes) and stopped at its deadline.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::{Class, INLINE_ROWS, check_batch};
use crate::app::App;
use crate::app::requests::deadline;
use crate::array::Array;
use crate::error::{Error, Result};
use crate::infer::Energies;

/// How long a REST energy, predict or simulate call may compute unless it says otherwise, and at most.
pub(super) const DEFAULT_SECONDS: f64 = 30.0;
pub(super) const MAX_SECONDS: f64 = 300.0;

/// A batch's energies, with the model's n.
pub struct Energy {
    pub n: usize,
    pub energies: Energies,
}

/// `POST /v1/models/{id}/energy`'s body.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EnergyRequest {
    /// States [q, v], one row of nq + nv values each.
    pub x: Vec<Vec<f64>>,
    /// Inputs, one row of m values per state.
    pub u: Vec<Vec<f64>>,
    /// Seconds the call may compute (default 30, at most 300): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

/// The energies of a batch, one entry (or row of n) per state.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct EnergyView {
    /// T = ½ q̇ᵀM(q)q̇.
    pub kinetic: Vec<f64>,
    /// V(q), up to the constant a potential always has.
    pub potential: Vec<f64>,
    /// E = T + V.
    pub total: Vec<f64>,
    /// q̇ᵀF(q, q̇, u): the rate at which the generalized forces do work.
    pub power: Vec<f64>,
    /// M(q) q̈; inertial + coriolis + gravity = applied.
    pub inertial: Vec<Vec<f64>>,
    /// c(q, q̇), the Coriolis and centrifugal term.
    pub coriolis: Vec<Vec<f64>>,
    /// ∇V(q).
    pub gravity: Vec<Vec<f64>>,
    /// F(q, q̇, u), the sum of `parts`.
    pub applied: Vec<Vec<f64>>,
    /// F's parts as the model's spec names them.
    pub parts: Vec<ForcePartView>,
}

#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct ForcePartView {
    /// `input` (B u), `damping`, `friction`, `unforced`, `residual` or `network`.
    pub name: String,
    /// Named damping or friction by the spec: switched off in the report's drift rollouts.
    pub damping: bool,
    pub values: Vec<Vec<f64>>,
}

/// JSON rows as an array; ragged rows are named.
pub(super) fn rows_array(field: &str, rows: Vec<Vec<f64>>) -> Result<Array> {
    let width = rows.first().map_or(0, Vec::len);
    if let Some(k) = rows.iter().position(|r| r.len() != width) {
        return Err(Error::invalid(
            field,
            format!(
                "row {k} has {} values but row 0 has {width}: every row is one state of the same width",
                rows[k].len()
            ),
        ));
    }
    let b = rows.len();
    Ok(Array::new(&[b, width], rows.concat()))
}

impl App {
    /// The energies of a batch of states `[B, nq + nv]` under inputs `[B, m]`.
    pub async fn energy(
        &self,
        id: &str,
        x: Array,
        u: Array,
        deadline: Option<Instant>,
    ) -> Result<Energy> {
        let eval = self.evaluator(id).await?;
        eval.check_energy()?;
        let b = check_batch(&eval, &x, &u)?;
        let (n, k) = (eval.config.nv(), eval.member_count());
        // The core's estimate, which the in-process callers are admitted under too.
        self.admit_call(&eval.energy_cost(b))?;
        let (x, u) = (x.data, u.data);
        let class = Class::of(b * k <= INLINE_ROWS, b * k);
        let energies = self
            .compute(class, "energy", deadline, move |stop| {
                eval.energy_until(&x, &u, stop).transpose()
            })
            .await??;
        energies.check_finite("x", n)?;
        Ok(Energy { n, energies })
    }

    /// [`App::energy`] for a JSON body.
    pub async fn energy_json(&self, id: &str, req: EnergyRequest) -> Result<EnergyView> {
        let deadline = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let (x, u) = (rows_array("x", req.x)?, rows_array("u", req.u)?);
        let Energy { n, energies: e } = self.energy(id, x, u, Some(deadline)).await?;
        let rows = |v: Vec<f64>| v.chunks(n).map(<[f64]>::to_vec).collect::<Vec<_>>();
        Ok(EnergyView {
            kinetic: e.kinetic,
            potential: e.potential,
            total: e.total,
            power: e.power,
            inertial: rows(e.inertial),
            coriolis: rows(e.coriolis),
            gravity: rows(e.gravity),
            applied: rows(e.applied),
            parts: (e.parts.into_iter())
                .map(|p| ForcePartView {
                    name: p.name.to_string(),
                    damping: p.dissipation,
                    values: rows(p.values),
                })
                .collect(),
        })
    }
}
