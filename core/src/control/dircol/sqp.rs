//! The SQP on the transcription (docs/control.md#direct-collocation): at each iterate z, the
//! QP of `qp` gives a step d on J's exact Hessian (J is quadratic) plus a proximal term ρI and
//! the defects linearized by their exact Jacobian; an ℓ1 merit φ(z) = J(z) + ν‖c(z)‖₁ chooses
//! how far along d to go (Armijo backtracking), with ν kept above the largest defect
//! multiplier so that d descends φ. ρ starts at 0, so a linear-quadratic problem is solved
//! exactly in one step; a QP that fails or a step that φ cuts raises it tenfold (a shorter,
//! better-conditioned step: without this the 200-step swing-up took ever shorter steps, ½ to
//! 2⁻⁵, and had not converged in 200 iterations), a full step accepted lowers it tenfold.
//! Once the defects are below [`CURVATURE_FROM`] the QP's Hessian also has the constraints'
//! curvature (`hessian`), which turns the slow linear tail into a fast one; learned from the
//! first iterate on, it steered the 21-step swing-up into a local minimum that never swings
//! up (J = 948 against 142).

use super::hessian::Curvature;
use super::qp::{Outcome, Subproblem, Until};
use super::transcription::{Entry, defect_jacobian, defects};
use super::{Collocation, Continuous};
use crate::control::plan::Dynamics;
use crate::error::Result;

/// A knot-state defect this small is met: far below any state's meaningful precision, and
/// above the ~1e-12 that Newton steps on the defects reach in double precision.
pub const DEFECT_TOLERANCE: f64 = 1e-8;
/// The largest defect below which the constraints' curvature is learned: near feasibility,
/// where the multipliers describe the solution rather than the guess. Measured on the
/// swing-up at T = 21 and 200: 1e-2 took 65 and 57 iterations, 1e-3 81 and 96, 1e-1
/// converged to a worse plan at T = 21.
const CURVATURE_FROM: f64 = 1e-2;
/// The QPs' interior-point tolerance on gap and feasibility (clarabel's default, stated): a
/// QP's error is the next SQP step's to correct, so the last iterates, not each QP, set the
/// answer's accuracy. Looser QPs while the defects are large (1e-5 above 1e-4) saved ~15% at
/// T = 200 and nothing at T = 21: not worth a second knob.
const QP_TOLERANCE: f64 = 1e-8;
const RHO_MIN: f64 = 1e-8;
const RHO_MAX: f64 = 1e10;
/// Step lengths tried: 1, ½, …, 2⁻¹⁵.
const BACKTRACKS: i32 = 16;
/// Armijo's sufficient-decrease fraction.
const ARMIJO: f64 = 1e-4;

/// An iterate: the decision vector, its cost, its defects, the largest violation of any
/// constraint (a defect, or a state outside its bounds) and the ℓ1 norm of all violations.
#[derive(Clone)]
pub(super) struct Iterate {
    pub z: Vec<f64>,
    pub cost: f64,
    pub defects: Vec<f64>,
    pub violation: f64,
    pub infeasibility: f64,
}

/// Where one start ended: its last iterate, the cost after each accepted step, whether it
/// converged.
pub(super) struct Run {
    pub last: Iterate,
    pub costs: Vec<f64>,
    pub converged: bool,
}

impl<S: Dynamics + Continuous> Collocation<'_, S> {
    pub(super) fn iterate(&self, z: Vec<f64>) -> Iterate {
        let c = defects(self.sys, &self.layout, &z, self.h);
        let (outside, worst_outside) = super::outside(&self.states, &self.layout, &z);
        let worst = c.iter().fold(worst_outside, |m, d| m.max(d.abs()));
        // A NaN defect reads as infinitely violated, never as met.
        let nan = c.iter().any(|d| d.is_nan()) || outside.is_nan();
        Iterate {
            cost: self.cost(&z),
            infeasibility: c.iter().map(|d| d.abs()).sum::<f64>() + outside,
            z,
            defects: c,
            violation: if nan { f64::INFINITY } else { worst },
        }
    }

    /// SQP from `z0` until converged, out of iterations or stopped.
    pub(super) fn optimize(&self, z0: Vec<f64>, until: &Until) -> Result<Run> {
        let mut cur = self.iterate(z0);
        let mut costs = vec![cur.cost];
        let (mut rho, mut nu) = (0.0f64, 0.0f64);
        let mut curvature = Curvature::new(&self.layout);
        // The last iterate's point and Jacobian, and the last QP's multipliers: what the
        // curvature learns from once the next Jacobian is known.
        let mut previous: Option<(Vec<f64>, Vec<Entry>)> = None;
        let mut lambda: Vec<f64> = vec![];
        let done = |cur, costs, converged| {
            Ok(Run {
                last: cur,
                costs,
                converged,
            })
        };
        for _ in 0..self.req.max_iterations {
            self.planner.check()?;
            if until.reached() || !cur.violation.is_finite() || !cur.cost.is_finite() {
                return done(cur, costs, false);
            }
            let jacobian = defect_jacobian(self.sys, &self.layout, &cur.z, self.h);
            if let Some((z, j)) = &previous
                && cur.violation < CURVATURE_FROM
            {
                let points = (z.as_slice(), cur.z.as_slice());
                curvature.update(&self.layout, points, (j, &jacobian), &lambda);
            }
            let gradient = self.gradient(&cur.z);
            let qp = Subproblem {
                layout: &self.layout,
                req: self.req,
                z: &cur.z,
                gradient: &gradient,
                defects: &cur.defects,
                jacobian: &jacobian,
                inputs: &self.planner.bounds,
                states: &self.states,
                curvature: &curvature,
                rho,
                tolerance: QP_TOLERANCE,
            };
            let step = match qp.solve(until) {
                Outcome::Solved(step) => step,
                Outcome::Stopped => {
                    self.planner.check()?;
                    return done(cur, costs, false);
                }
                Outcome::Failed => {
                    rho = (rho * 10.0).max(RHO_MIN);
                    if rho > RHO_MAX {
                        return done(cur, costs, false);
                    }
                    continue;
                }
            };
            let slope: f64 = gradient.iter().zip(&step.d).map(|(g, d)| g * d).sum();
            let l1 = cur.infeasibility;
            // The QP's first-order change of J is within the tolerance of J and the defects
            // are met: a KKT point of the NLP (d → 0 there).
            if cur.violation <= DEFECT_TOLERANCE
                && slope.abs() <= self.req.tolerance * cur.cost.abs().max(f64::MIN_POSITIVE)
            {
                return done(cur, costs, true);
            }
            nu = nu.max(1.1 * step.largest + 1e-6);
            let derivative = slope - nu * l1;
            match self.line_search(&cur, &step.d, nu, derivative)? {
                Some((next, full)) => {
                    previous = Some((cur.z.clone(), jacobian));
                    lambda = step.multipliers;
                    let before = cur.cost + nu * l1;
                    let after = next.cost + nu * next.infeasibility;
                    cur = next;
                    costs.push(cur.cost);
                    rho = if full && rho <= RHO_MIN {
                        0.0
                    } else if full {
                        rho / 10.0
                    } else {
                        (rho * 10.0).max(RHO_MIN)
                    };
                    let decrease = (before - after) / before.abs().max(f64::MIN_POSITIVE);
                    if cur.violation <= DEFECT_TOLERANCE && decrease < self.req.tolerance {
                        return done(cur, costs, true);
                    }
                }
                None => {
                    rho = (rho * 10.0).max(RHO_MIN);
                    if rho > RHO_MAX {
                        // No step lowers φ even as a tiny proximal step: a local minimum of φ,
                        // which is the NLP's only when its defects are met.
                        let met = cur.violation <= DEFECT_TOLERANCE;
                        return done(cur, costs, met);
                    }
                }
            }
        }
        done(cur, costs, false)
    }

    /// The longest of 1, ½, … along d with Armijo's decrease of φ, and whether it was the full
    /// step; `None` when none decreases it enough.
    fn line_search(
        &self,
        cur: &Iterate,
        d: &[f64],
        nu: f64,
        derivative: f64,
    ) -> Result<Option<(Iterate, bool)>> {
        let merit = |it: &Iterate| it.cost + nu * it.infeasibility;
        let start = merit(cur);
        for i in 0..BACKTRACKS {
            self.planner.check()?;
            let alpha = 0.5f64.powi(i);
            let z: Vec<f64> = cur.z.iter().zip(d).map(|(z, d)| z + alpha * d).collect();
            let next = self.iterate(z);
            let phi = merit(&next);
            if phi.is_finite() && phi <= start + ARMIJO * alpha * derivative.min(0.0) {
                return Ok(Some((next, i == 0)));
            }
        }
        Ok(None)
    }

    /// ∇J: 2W(z ⊖ goal) at the knots' states, 2R u at the inputs, 0 at the midpoints.
    fn gradient(&self, z: &[f64]) -> Vec<f64> {
        let (l, req) = (&self.layout, self.req);
        let mut g = vec![0.0; l.len()];
        let mut put = |at: usize, w: &crate::control::linalg::Mat, d: &[f64]| {
            for i in 0..w.rows {
                g[at + i] = 2.0 * (0..w.cols).map(|j| w.at(i, j) * d[j]).sum::<f64>();
            }
        };
        let off_goal = |k: usize| self.sys.difference(&req.goal, &z[l.x(k)..][..l.nx]);
        for k in 0..l.intervals {
            put(l.x(k), &req.q, &off_goal(k));
            put(l.u(k), &req.r, &z[l.u(k)..][..l.m]);
        }
        put(l.x(l.intervals), &req.qf, &off_goal(l.intervals));
        g
    }
}
