//! Predict and Rollout as JSON for REST (`POST /v1/models/{id}/predict`, `POST
//! /v1/models/{id}/simulate`): the same calls gRPC makes, their arrays as rows, a rollout's
//! streamed chunks joined into one answer (bounded as gRPC's by --max-rollout-steps).

use serde::{Deserialize, Serialize};

use super::energy::{DEFAULT_SECONDS, MAX_SECONDS, rows_array};
use super::{RolloutInputs, RolloutShape, Want};
use crate::app::App;
use crate::app::requests::deadline;
use crate::error::{Error, Result};

/// `POST /v1/models/{id}/predict`'s body.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PredictRequest {
    /// States [q, v], one row of nq + nv values each.
    pub x: Vec<Vec<f64>>,
    /// Inputs, one row of m values per state.
    pub u: Vec<Vec<f64>>,
    /// The step in seconds (1e-5 to 10; unset: the model's own). The dynamics are
    /// continuous: a model trained at one rate predicts at another.
    #[serde(default)]
    pub dt: Option<f64>,
    /// Also v̇ per state.
    #[serde(default)]
    pub want_accel: bool,
    /// Also every ensemble member's x'.
    #[serde(default)]
    pub members: bool,
    /// Seconds the call may compute (default 30, at most 300): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

/// x' per state, with what was asked for.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct PredictView {
    /// The step taken, in seconds.
    pub dt: f64,
    /// One row of nq + nv values per state (an ensemble's members' mean).
    pub x_next: Vec<Vec<f64>>,
    /// v̇, one row of nv per state, when asked for.
    pub accel: Option<Vec<Vec<f64>>>,
    /// Per state, the largest |z-score| of q, q̇ and u under the training data's statistics.
    pub max_abs_z: Vec<f64>,
    /// An ensemble's members' standard deviation of x' (or a single model's zeros when
    /// members were asked for).
    pub x_next_std: Option<Vec<Vec<f64>>>,
    /// Every member's x' [K][B][nq + nv], when asked for.
    pub members: Option<Vec<Vec<Vec<f64>>>>,
    pub member_count: usize,
}

/// `POST /v1/models/{id}/simulate`'s body: a rollout under a sequence of inputs.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SimulateRequest {
    /// The first state [q, v].
    pub x0: Vec<f64>,
    /// One input row of m values per step.
    pub u: Vec<Vec<f64>>,
    /// Seconds between states (1e-5 to 10; unset: the model's own).
    #[serde(default)]
    pub dt: Option<f64>,
    /// Particles to propagate (1–1024; unset: one rollout of the mean dynamics).
    #[serde(default)]
    pub particles: Option<usize>,
    /// Seconds the call may compute (default 30, at most 300): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

/// The states x_0..x_T and what came with them.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct SimulateView {
    /// Seconds between states.
    pub dt: f64,
    /// T + 1 rows of nq + nv values (the particles' mean with particles).
    pub x: Vec<Vec<f64>>,
    /// With particles: their standard deviation, T + 1 rows.
    pub x_std: Option<Vec<Vec<f64>>>,
    /// Per step, the largest |z-score| of the state and input it was applied at.
    pub max_abs_z: Vec<f64>,
}

fn rows(a: &[f64], width: usize) -> Vec<Vec<f64>> {
    a.chunks(width.max(1)).map(<[f64]>::to_vec).collect()
}

impl App {
    /// A REST Predict.
    pub async fn predict_json(&self, id: &str, req: PredictRequest) -> Result<PredictView> {
        let until = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let (x, u) = (rows_array("x", req.x)?, rows_array("u", req.u)?);
        let want = Want {
            accel: req.want_accel,
            members: req.members,
            dt: req.dt,
        };
        let dt = self.evaluator(id).await?.step_seconds(req.dt)?;
        let p = self.predict(id, x, u, want, Some(until)).await?;
        let nx = p.next.shape.last().map_or(0, |&w| w as usize);
        let b = p.max_abs_z.len();
        Ok(PredictView {
            dt,
            x_next: rows(&p.next.data, nx),
            accel: (p.accel).map(|a| rows(&a.data, a.data.len() / b.max(1))),
            max_abs_z: p.max_abs_z,
            x_next_std: p.std.map(|s| rows(&s.data, nx)),
            members: (p.members).map(|m| {
                let each = m.data.chunks((b * nx).max(1));
                each.map(|k| rows(k, nx)).collect()
            }),
            member_count: p.member_count,
        })
    }

    /// A REST rollout under a sequence of inputs: the stream's chunks joined.
    pub async fn simulate_json(&self, id: &str, req: SimulateRequest) -> Result<SimulateView> {
        let until = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let dt = self.evaluator(id).await?.step_seconds(req.dt)?;
        let u = rows_array("u", req.u)?;
        let nx = req.x0.len();
        let shape = RolloutShape {
            chunk: 0,
            particles: req.particles,
            dt: Some(dt),
        };
        let mut rx = (self.rollout(id, req.x0, RolloutInputs::U(u), shape, Some(until))).await?;
        let (mut x, mut std, mut z) = (vec![], None::<Vec<f64>>, vec![]);
        while let Some(chunk) = rx.recv().await {
            let c = chunk?;
            if c.start != x.len() / nx.max(1) {
                return Err(Error::Internal(
                    "a rollout's chunks arrived out of order".into(),
                ));
            }
            x.extend(c.x.data);
            if let Some(s) = c.x_std {
                std.get_or_insert_with(Vec::new).extend(s.data);
            }
            z.extend(c.max_abs_z);
        }
        Ok(SimulateView {
            dt,
            x: rows(&x, nx),
            x_std: std.map(|s| rows(&s, nx)),
            max_abs_z: z,
        })
    }
}
