//! Input and output scalings from dataset statistics, stored with the model.
//!
//! With u ~ N(0, 120²) the generalized forces are O(100): unscaled networks barely train
//! (docs/training.md#input-and-output-scalings). Network inputs are standardized, and network outputs are multiplied by the
//! scale their physical quantity has in the data. M's scale is free (identifiability), so a
//! learned M starts near the identity and forces are scaled like accelerations; with an analytic
//! M the force scale is the spread of M(q)q̈ over the data at the initial parameters.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scaling {
    pub q_mean: Vec<f64>,
    pub q_std: Vec<f64>,
    pub qdot_mean: Vec<f64>,
    pub qdot_std: Vec<f64>,
    pub u_mean: Vec<f64>,
    pub u_std: Vec<f64>,
    /// Statistics of the finite-difference accelerations (q̇' − q̇)/Δt.
    pub acc_mean: Vec<f64>,
    pub acc_std: Vec<f64>,
    /// Typical size of each generalized force.
    pub force_scale: Vec<f64>,
}

impl Scaling {
    /// Every statistic is a finite number.
    pub fn is_finite(&self) -> bool {
        [
            &self.q_mean,
            &self.q_std,
            &self.qdot_mean,
            &self.qdot_std,
            &self.u_mean,
            &self.u_std,
            &self.acc_mean,
            &self.acc_std,
            &self.force_scale,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
    }

    /// Identity scalings (used where no data is at hand, e.g. in unit tests).
    pub fn identity(n: usize, m: usize) -> Self {
        Self {
            q_mean: vec![0.0; n],
            q_std: vec![1.0; n],
            qdot_mean: vec![0.0; n],
            qdot_std: vec![1.0; n],
            u_mean: vec![0.0; m],
            u_std: vec![1.0; m],
            acc_mean: vec![0.0; n],
            acc_std: vec![1.0; n],
            force_scale: vec![1.0; n],
        }
    }

    pub fn mean_force_scale(&self) -> f64 {
        self.force_scale.iter().sum::<f64>() / self.force_scale.len() as f64
    }

    pub fn mean_q_std(&self) -> f64 {
        self.q_std.iter().sum::<f64>() / self.q_std.len() as f64
    }

    /// Scale of a learned quadratic potential's K: K q is O(force) when q is O(σ_q).
    pub fn quadratic_scale(&self) -> f64 {
        self.mean_force_scale() / self.mean_q_std()
    }

    /// Output scale of a potential network: ∂V/∂q should be O(force) when q moves by O(σ_q).
    pub fn potential_scale(&self) -> f64 {
        self.mean_force_scale() * self.mean_q_std()
    }
}
