//! Inverse dynamics for a batch of states (`infer::inverse`): the generalized force τ =
//! M q̈ + c + ∇V − F(q, q̇, 0) that produces given accelerations, with its terms. gRPC
//! `InverseDynamics` and `POST /v1/models/{id}/inverse-dynamics` call it; admitted like Energy
//! (the same work per state) and stopped at its deadline.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::energy::{DEFAULT_SECONDS, ForcePartView, MAX_SECONDS, rows_array};
use super::{Class, INLINE_ROWS};
use crate::app::App;
use crate::app::requests::deadline;
use crate::array::Array;
use crate::error::{Error, Result};
use crate::infer::InverseDynamics;

/// `POST /v1/models/{id}/inverse-dynamics`'s body.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct InverseRequest {
    /// States [q, v], one row of nq + nv values each.
    pub x: Vec<Vec<f64>>,
    /// Accelerations q̈, one row of nv values per state.
    pub qdd: Vec<Vec<f64>>,
    /// Seconds the call may compute (default 30, at most 300): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

/// τ and its terms, one row of nv per state.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct InverseView {
    /// M q̈ + c + ∇V − F(q, q̇, 0): the generalized force the inputs must add.
    pub tau: Vec<Vec<f64>>,
    /// M(q) q̈ at the given q̈.
    pub inertial: Vec<Vec<f64>>,
    pub coriolis: Vec<Vec<f64>>,
    /// ∇V(q).
    pub gravity: Vec<Vec<f64>>,
    /// F(q, q̇, 0), the passive forces, the sum of `parts`.
    pub passive: Vec<Vec<f64>>,
    /// F(q, q̇, 0)'s named parts (`input`, zero there, left out).
    pub parts: Vec<ForcePartView>,
}

impl App {
    /// τ at a batch of states `[B, nq + nv]` and accelerations `[B, nv]`, with the model's nv.
    pub async fn inverse_dynamics(
        &self,
        id: &str,
        x: Array,
        qdd: Array,
        deadline: Option<Instant>,
    ) -> Result<(usize, InverseDynamics)> {
        let eval = self.evaluator(id).await?;
        eval.check_energy()?;
        let (nv, k) = (eval.config.nv(), eval.member_count());
        let b = x.rows("x", eval.config.nx())?;
        let rows = qdd.rows("qdd", nv)?;
        if rows != b {
            return Err(Error::invalid(
                "qdd",
                format!("has {rows} rows but x has {b}"),
            ));
        }
        self.admit_call(&eval.energy_cost(b))?;
        let (x, qdd) = (x.data, qdd.data);
        let class = Class::of(b * k <= INLINE_ROWS, b * k);
        let inv = self
            .compute(class, "inverse dynamics", deadline, move |stop| {
                eval.inverse_dynamics_until(&x, &qdd, stop).transpose()
            })
            .await??;
        inv.terms.check_finite("x", nv)?;
        Ok((nv, inv))
    }

    /// [`App::inverse_dynamics`] for a JSON body.
    pub async fn inverse_json(&self, id: &str, req: InverseRequest) -> Result<InverseView> {
        let deadline = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let (x, qdd) = (rows_array("x", req.x)?, rows_array("qdd", req.qdd)?);
        let (nv, inv) = self.inverse_dynamics(id, x, qdd, Some(deadline)).await?;
        let rows = |v: Vec<f64>| v.chunks(nv).map(<[f64]>::to_vec).collect::<Vec<_>>();
        let e = inv.terms;
        Ok(InverseView {
            tau: rows(inv.tau),
            inertial: rows(e.inertial),
            coriolis: rows(e.coriolis),
            gravity: rows(e.gravity),
            passive: rows(e.applied),
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
