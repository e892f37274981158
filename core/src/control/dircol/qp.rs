//! One SQP iteration's subproblem, a sparse convex QP in the step d, handed to clarabel:
//!
//! ```text
//! minimize ½ dᵀ(2W + ρI)d + ∇J(z)ᵀd
//! subject to C(z) d = −c(z)          (the defects, linearized)
//!            d_{x_0} = 0              (x_0 is the request's and stays so)
//!            lo − u_k ≤ d_{u_k} ≤ hi − u_k   (finite bounds only)
//!            x_min − x ≤ d_x ≤ x_max − x     (every knot after x_0 and every midpoint)
//! ```
//!
//! W is the cost's block-diagonal weight (Q, R, 0 at a midpoint, Q_f at the last knot), so 2W
//! is J's exact Hessian; ρ is the proximal term the SQP raises when a step fails.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

use super::hessian::Curvature;
use super::transcription::{Entry, Layout};
use super::triplets::Triplets;
use crate::control::plan::{Bounds, PlanRequest};

/// What the QP gives: the step, the defect rows' multipliers and the largest multiplier of a
/// constraint the merit weighs (a defect's or a state bound's; x_0 and the input bounds hold
/// at every iterate).
pub(super) struct Step {
    pub d: Vec<f64>,
    pub multipliers: Vec<f64>,
    pub largest: f64,
}

pub(super) enum Outcome {
    Solved(Step),
    /// The QP has no solution the solver could find (infeasible bounds, or numerics).
    Failed,
    /// The request's time limit, its deadline or its caller's cancellation.
    Stopped,
}

/// When the solver must give up: `cancel` (set when the request's `stop` says so) or the
/// request's time limit, both checked at every interior-point iteration.
#[derive(Clone)]
pub(super) struct Until {
    pub cancel: Arc<AtomicBool>,
    pub time_limit: Option<Instant>,
}

impl Until {
    pub(super) fn reached(&self) -> bool {
        self.cancel.load(Ordering::Relaxed) || self.time_limit.is_some_and(|t| Instant::now() >= t)
    }
}

/// The subproblem's data at the current iterate `z`.
pub(super) struct Subproblem<'a> {
    pub layout: &'a Layout,
    pub req: &'a PlanRequest,
    pub z: &'a [f64],
    pub gradient: &'a [f64],
    pub defects: &'a [f64],
    pub jacobian: &'a [Entry],
    pub inputs: &'a Bounds,
    pub states: &'a Bounds,
    pub curvature: &'a Curvature,
    pub rho: f64,
    /// The interior point's tolerance on gap and feasibility.
    pub tolerance: f64,
}

impl Subproblem<'_> {
    /// A fresh interior-point solve. Reusing one solver with its data updated in place (the
    /// pattern is the same at every iterate) was measured no faster and, its equilibration
    /// frozen at the first iterate, took more SQP iterations (101 against 65 at T = 21).
    pub(super) fn solve(&self, until: &Until) -> Outcome {
        let (p, (a, b, [equalities, inequalities, states_from])) =
            (self.hessian(), self.constraints());
        let mut cones = vec![SupportedConeT::ZeroConeT(equalities)];
        if inequalities > 0 {
            cones.push(SupportedConeT::NonnegativeConeT(inequalities));
        }
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .presolve_enable(false)
            .tol_gap_abs(self.tolerance)
            .tol_gap_rel(self.tolerance)
            .tol_feas(self.tolerance)
            .max_threads(1)
            // Refinement was 45% of a solve (a profile of the 200-step swing-up: its
            // triangular solves and KKT products); the SQP's next step corrects what it would
            // have, and without it the swing-ups converge in as many iterations.
            .iterative_refinement_enable(false)
            .build()
            .expect("valid settings");
        let Ok(mut solver) = DefaultSolver::new(&p, self.gradient, &a, &b, &cones, settings) else {
            return Outcome::Failed;
        };
        let watch = until.clone();
        solver.set_termination_callback(move |_| watch.reached());
        solver.solve();
        let s = &solver.solution;
        match s.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => Outcome::Solved(Step {
                d: s.x.clone(),
                multipliers: s.z[..self.layout.defects()].to_vec(),
                largest: (s.z[..self.layout.defects()].iter())
                    .chain(&s.z[states_from..])
                    .fold(0.0f64, |m, v| m.max(v.abs())),
            }),
            SolverStatus::CallbackTerminated | SolverStatus::MaxTime => Outcome::Stopped,
            _ => Outcome::Failed,
        }
    }

    /// The upper triangle of 2W + B + ρI, B the constraints' learned curvature; every entry
    /// of every block listed (zeros too) so that the pattern is the same at every iterate.
    fn hessian(&self) -> CscMatrix<f64> {
        let (l, req) = (self.layout, self.req);
        let mut t = Triplets::default();
        let e = self.curvature.size;
        for (k, b) in self.curvature.blocks.iter().enumerate() {
            for i in 0..e {
                for j in i..e {
                    t.push(l.x(k) + i, l.x(k) + j, b[i * e + j]);
                }
            }
        }
        let mut weight = |at: usize, w: Option<&crate::control::linalg::Mat>, size: usize| {
            for i in 0..size {
                for j in i..size {
                    let v = w.map_or(0.0, |w| 2.0 * w.at(i, j));
                    let diagonal = if i == j { self.rho } else { 0.0 };
                    t.push(at + i, at + j, v + diagonal);
                }
            }
        };
        for k in 0..l.intervals {
            weight(l.x(k), Some(&req.q), l.nx);
            weight(l.u(k), Some(&req.r), l.m);
            weight(l.xc(k), None, l.nx);
        }
        weight(l.x(l.intervals), Some(&req.qf), l.nx);
        t.matrix(l.len(), l.len())
    }

    /// A and b of `A d + s = b`: the defects and x_0 as equalities (s = 0), then the finite
    /// bounds as inequalities (s ≥ 0), the inputs' then the states'; the count of each kind
    /// and the first row of the states' bounds.
    fn constraints(&self) -> (CscMatrix<f64>, Vec<f64>, [usize; 3]) {
        let l = self.layout;
        let mut t = Triplets::default();
        for &(i, j, v) in self.jacobian {
            t.push(i, j, v);
        }
        let mut b: Vec<f64> = self.defects.iter().map(|c| -c).collect();
        for i in 0..l.nx {
            t.push(b.len(), l.x(0) + i, 1.0);
            b.push(0.0);
        }
        let equalities = b.len();
        for k in 0..l.intervals {
            self.box_rows((&mut t, &mut b), l.u(k), self.inputs);
        }
        let states_from = b.len();
        for at in l.free_states() {
            self.box_rows((&mut t, &mut b), at, self.states);
        }
        let inequalities = b.len() - equalities;
        let counts = [equalities, inequalities, states_from];
        (t.matrix(b.len(), l.len()), b, counts)
    }
}

impl Subproblem<'_> {
    /// Rows `d_i ≤ hi_i − z_i` and `−d_i ≤ z_i − lo_i` for the finite bounds of the variables
    /// from `at` on.
    fn box_rows(&self, (t, b): (&mut Triplets, &mut Vec<f64>), at: usize, bounds: &Bounds) {
        for (i, (lo, hi)) in bounds.lo.iter().zip(&bounds.hi).enumerate() {
            let z = self.z[at + i];
            if hi.is_finite() {
                t.push(b.len(), at + i, 1.0);
                b.push(hi - z);
            }
            if lo.is_finite() {
                t.push(b.len(), at + i, -1.0);
                b.push(z - lo);
            }
        }
    }
}
