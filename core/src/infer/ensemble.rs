//! An ensemble's evaluator (README "Ensembles and uncertainty"): the batched entry points
//! answer with the members' mean, so every caller (Predict, Linearize, TVLQR, Plan's
//! dynamics, collocation's continuous dynamics, rollouts, the error against horizon) runs on
//! the mean dynamics: the average of the members' next states (a rotation's projected back
//! onto the circle), whose Jacobians are the average of theirs. A single model's answers never pass through here.

use super::Evaluator;
use crate::control::ensemble::mean_std;
use crate::control::make_plan;
use crate::control::plan::{Plan, PlanRequest};
use crate::error::Result;

/// The elementwise mean of equally long vectors, summed in member order.
pub(super) fn mean(parts: impl Iterator<Item = Vec<f64>>) -> Vec<f64> {
    let mut k = 0.0;
    let mut sum: Vec<f64> = vec![];
    for p in parts {
        if sum.is_empty() {
            sum = p;
        } else {
            sum.iter_mut().zip(&p).for_each(|(s, v)| *s += v);
        }
        k += 1.0;
    }
    sum.iter_mut().for_each(|s| *s /= k);
    sum
}

/// Each member's predictions and their spread.
pub struct MemberPredictions {
    /// Per member, x' `[B, nq + nv]`.
    pub next: Vec<Vec<f64>>,
    /// The members' mean x' (a rotation's on the circle: `Space::project_states`) and, per
    /// coordinate, their sample standard deviation (0 for one member; see
    /// `model::report::Spread`).
    pub mean: Vec<f64>,
    pub std: Vec<f64>,
    /// The members' mean v̇ `[B, nv]`, when asked for.
    pub accel: Option<Vec<f64>>,
}

impl MemberPredictions {
    fn of(next: Vec<Vec<f64>>, accel: Option<Vec<f64>>) -> Self {
        let (mean, std) = mean_std(&next);
        Self {
            next,
            mean,
            std,
            accel,
        }
    }
}

impl Evaluator {
    /// An ensemble's members (None for a single model).
    pub(super) fn ensemble(&self) -> Option<&[Evaluator]> {
        self.members.as_deref()
    }

    /// Members: 1 for a single model.
    pub fn member_count(&self) -> usize {
        self.members.as_ref().map_or(1, |m| m.len())
    }

    /// Member `k` as a single model (a single model's member 0 is itself).
    pub fn member(&self, k: usize) -> &Evaluator {
        match &self.members {
            Some(members) => &members[k],
            None => self,
        }
    }

    /// Every member's x' for a batch, with their mean and spread (the mean is what
    /// `predict_until` answers; a single model's is its own prediction, bit for bit), and the
    /// mean q̈ when asked; None when `stop` said so.
    pub fn predict_members_until(
        &self,
        x: &[f64],
        u: &[f64],
        dt: f64,
        want_accel: bool,
        stop: &dyn Fn() -> bool,
    ) -> Option<MemberPredictions> {
        let each: Vec<(Vec<f64>, Option<Vec<f64>>)> = (0..self.member_count())
            .map(|k| self.member(k).predict_until(x, u, dt, want_accel, stop))
            .collect::<Option<_>>()?;
        let accel = want_accel.then(|| mean(each.iter().filter_map(|e| e.1.clone())));
        let next = each.into_iter().map(|e| e.0).collect();
        let mut p = MemberPredictions::of(next, accel);
        self.config.space.project_states(&mut p.mean);
        Some(p)
    }
}

impl Evaluator {
    /// A plan by the request's method (`control::make_plan`); an ensemble's also by its
    /// `ensemble_cost`, with the members' spread along it (`control::ensemble`). A single
    /// model plans as itself whatever `ensemble_cost` says.
    pub fn plan(&self, req: &PlanRequest, stop: &(dyn Fn() -> bool + Sync)) -> Result<Plan> {
        match self.ensemble() {
            Some(members) => crate::control::ensemble::plan(self, members, req, stop),
            None => make_plan(self, req, stop),
        }
    }
}
