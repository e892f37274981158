//! Collocation on a configuration space with nq ≠ nv (a rotation kept as a unit complex
//! number): the program is laid out in the chart where every joint is one number
//! (`Dynamics::chart_of`; a rotation by its angle), whose variables are 2nv wide. For the
//! joints there are (the line and the circle, both commutative) integrate is addition in that
//! chart, the tangent-space f = (v, v̇) is the chart's time derivative, and the tangent
//! Jacobians are the chart's, so the Hermite–Simpson defects in the chart are the defects on
//! the space and the plan it finds is the space's. Costs read x ⊖ goal through the space's
//! difference (a rotation's shortest way round), not the chart's subtraction.

use super::{Continuous, collocate};
use crate::control::linalg::Mat;
use crate::control::plan::{Dynamics, Plan, PlanRequest};
use crate::error::{Error, Result};

/// A checked request on `sys` (ndx ≠ nx), collocated in the chart and answered in states.
pub(super) fn plan<S: Dynamics + Continuous>(
    sys: &S,
    req: &PlanRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Plan> {
    for (name, bound) in [("x_min", &req.x_min), ("x_max", &req.x_max)] {
        if bound.is_some() {
            return Err(Error::invalid(
                name,
                "state bounds are taken on models whose every joint is one number; this one \
                 keeps a rotation as (cos θ, sin θ), whose values a box does not bound",
            ));
        }
    }
    let charted = Charted { sys };
    let (nx, ndx) = (Dynamics::nx(sys), sys.ndx());
    let x_init = (req.x_init.as_ref()).map(|x| {
        let rows: Vec<&[f64]> = x.data.chunks(nx).collect();
        Mat::new(x.rows, ndx, unwrapped(sys, &rows))
    });
    let in_chart = PlanRequest {
        x0: sys.chart_of(&req.x0),
        goal: sys.chart_of(&req.goal),
        x_init,
        ..req.clone()
    };
    let mut plan = collocate(&charted, &in_chart, stop)?;
    plan.x = charted.states(&plan.x);
    Ok(plan)
}

/// States `rows` in the chart, each row's angles continuing the row before's (a rotation
/// that turns past π keeps counting rather than jumping by 2π): c₀ = chart(x₀),
/// c_k = c_{k−1} + (x_k ⊖ x_{k−1}).
fn unwrapped<S: Dynamics>(sys: &S, rows: &[&[f64]]) -> Vec<f64> {
    let Some(first) = rows.first() else {
        return vec![];
    };
    let mut c = sys.chart_of(first);
    let mut out = c.clone();
    for pair in rows.windows(2) {
        let d = sys.difference(pair[0], pair[1]);
        c.iter_mut().zip(&d).for_each(|(c, d)| *c += d);
        out.extend_from_slice(&c);
    }
    out
}

/// `sys` in its chart: states ndx wide, each the chart coordinates of one of `sys`'s.
pub(super) struct Charted<'a, S> {
    sys: &'a S,
}

impl<S: Dynamics> Charted<'_, S> {
    /// Rows of chart coordinates as `sys`'s states.
    fn states(&self, c: &[f64]) -> Vec<f64> {
        (c.chunks(self.sys.ndx()))
            .flat_map(|c| self.sys.state_at(c))
            .collect()
    }
}

impl<S: Dynamics> Dynamics for Charted<'_, S> {
    fn nx(&self) -> usize {
        self.sys.ndx()
    }
    fn m(&self) -> usize {
        self.sys.m()
    }
    /// c ⊕ (f(x, u) ⊖ x) at x = the state at c: the chart's next point continues from c
    /// (no jump of 2π when a rotation passes π).
    fn step(&self, c: &[f64], u: &[f64]) -> Vec<f64> {
        let (nx, ndx) = (self.sys.nx(), self.sys.ndx());
        let x = self.states(c);
        let next = self.sys.step(&x, u);
        let mut out = Vec::with_capacity(c.len());
        for ((c, x), next) in c.chunks(ndx).zip(x.chunks(nx)).zip(next.chunks(nx)) {
            let d = self.sys.difference(x, next);
            out.extend(c.iter().zip(&d).map(|(c, d)| c + d));
        }
        out
    }
    fn linearize(&self, c: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        self.sys.linearize(&self.states(c), u)
    }
    fn difference(&self, c0: &[f64], c1: &[f64]) -> Vec<f64> {
        self.sys
            .difference(&self.sys.state_at(c0), &self.sys.state_at(c1))
    }
}

impl<S: Dynamics + Continuous> Continuous for Charted<'_, S> {
    fn nx(&self) -> usize {
        Continuous::nx(self.sys)
    }
    fn m(&self) -> usize {
        Continuous::m(self.sys)
    }
    fn dt(&self) -> f64 {
        self.sys.dt()
    }
    fn derivative(&self, c: &[f64], u: &[f64]) -> Vec<f64> {
        self.sys.derivative(&self.states(c), u)
    }
    fn derivative_jacobian(&self, c: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        self.sys.derivative_jacobian(&self.states(c), u)
    }
}
