//! Plans on an ensemble (README "Ensembles and uncertainty"). By default a plan is made on the
//! mean dynamics (the members' average next state), as every other call answers. With
//! `ensemble_cost: "mean"` it minimizes the members' average cost instead: the inputs are
//! shared, every member rolls them out from x0, and
//!
//! ```text
//! J̄(u) = (1/K) Σ_k J(x^k(u), u),   x^k_{t+1} = f_k(x^k_t, u_t),  x^k_0 = x0
//! ```
//!
//! That is one plan on the stacked system X = (x¹, …, x^K), F(X, u) = (f₁(x¹, u), …,
//! f_K(x^K, u)) with the state weights Q/K and Q_f/K on every member's block and R unchanged,
//! so iLQR and collocation solve it as they are, at (K·nx)³ a step of the backward pass. A
//! plan on the mean dynamics can end where no member goes (the average of two swings, one
//! early and one late); the average cost asks the inputs to work for every member.
//!
//! The answer is in one state's terms: the members' mean states along the inputs, their
//! spread, and the stacked gains' response to a deviation every member shares (Σ_k K^k): the
//! feedback u = ū − K(x − x̄) for a state measured once for all members.

use super::dircol::Continuous;
use super::linalg::Mat;
use super::make_plan;
use super::plan::{Dynamics, EnsembleCost, Plan, PlanRequest, norm, validate};
use crate::error::Result;

/// A plan for an ensemble whose mean dynamics are `mean` and whose members are `members`
/// (K ≥ 1), by the request's `ensemble_cost`. Either way the plan carries the members' spread
/// along its inputs (`Plan::x_std`).
pub fn plan<S: Dynamics + Continuous>(
    mean: &S,
    members: &[S],
    req: &PlanRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Plan> {
    let (nx, ndx) = (Dynamics::nx(mean), mean.ndx());
    validate(req, (nx, ndx), Dynamics::m(mean))?;
    let stacked = Stacked { members, nx, ndx };
    let k = members.len();
    match req.ensemble_cost {
        EnsembleCost::MeanDynamics => {
            let mut plan = make_plan(mean, req, stop)?;
            let x = stacked.rollout(&req.x0, &plan.u);
            plan.x_std = Some(spread(&x, k, nx).1);
            Ok(plan)
        }
        EnsembleCost::Mean => {
            let plan = make_plan(&stacked, &stacked_request(req, k), stop)?;
            Ok(unstack(plan, k, (nx, ndx), |x| {
                mean.difference(&req.goal, x)
            }))
        }
    }
}

/// The members side by side: row b of a stacked batch is (x¹_b, …, x^K_b).
struct Stacked<'a, S> {
    members: &'a [S],
    nx: usize,
    /// A member's deviation's width.
    ndx: usize,
}

impl<S> Stacked<'_, S> {
    /// `f(member, its block of x)` for each member, `width` wide a row, scattered back into
    /// stacked rows.
    fn each(&self, x: &[f64], width: usize, f: impl Fn(&S, &[f64]) -> Vec<f64>) -> Vec<f64> {
        let (k, nx) = (self.members.len(), self.nx);
        let mut out = vec![0.0; x.len() / nx * width];
        for (j, member) in self.members.iter().enumerate() {
            let y = f(member, &block(x, j, nx, k * nx));
            for (row, part) in out.chunks_mut(k * width).zip(y.chunks(width)) {
                row[j * width..(j + 1) * width].copy_from_slice(part);
            }
        }
        out
    }

    /// Each member's Jacobians `f(member, its block of x)` at every row, as the stacked
    /// system's: the state's block diagonal, the input's stacked.
    fn jacobians(
        &self,
        x: &[f64],
        f: impl Fn(&S, &[f64]) -> (Vec<Mat>, Vec<Mat>),
    ) -> (Vec<Mat>, Vec<Mat>) {
        let (k, nx) = (self.members.len(), self.ndx);
        let each: Vec<(Vec<Mat>, Vec<Mat>)> = (self.members.iter().enumerate())
            .map(|(j, member)| f(member, &block(x, j, self.nx, k * self.nx)))
            .collect();
        let m = each[0].1.first().map_or(0, |b| b.cols);
        (0..each[0].0.len())
            .map(|t| {
                let (mut a, mut b) = (Mat::zeros(k * nx, k * nx), Mat::zeros(k * nx, m));
                for (j, (aj, bj)) in each.iter().enumerate() {
                    for i in 0..nx {
                        let r = j * nx + i;
                        a.data[r * k * nx + j * nx..][..nx]
                            .copy_from_slice(&aj[t].data[i * nx..][..nx]);
                        b.data[r * m..][..m].copy_from_slice(&bj[t].data[i * m..][..m]);
                    }
                }
                (a, b)
            })
            .unzip()
    }
}

impl<S: Dynamics> Stacked<'_, S> {
    /// Every member's open-loop rollout of `u` `[T, m]` from x0: stacked states `[T+1, K·nx]`.
    fn rollout(&self, x0: &[f64], u: &[f64]) -> Vec<f64> {
        let mut at: Vec<f64> = x0.repeat(self.members.len());
        let mut x = at.clone();
        for ut in u.chunks(Dynamics::m(self)) {
            at = self.step(&at, ut);
            x.extend_from_slice(&at);
        }
        x
    }
}

impl<S: Dynamics> Dynamics for Stacked<'_, S> {
    fn nx(&self) -> usize {
        self.members.len() * self.nx
    }
    fn m(&self) -> usize {
        self.members[0].m()
    }
    fn step(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        self.each(x, self.nx, |s, x| s.step(x, u))
    }
    fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        self.jacobians(x, |s, x| s.linearize(x, u))
    }
    fn ndx(&self) -> usize {
        self.members.len() * self.ndx
    }
    fn difference(&self, x0: &[f64], x1: &[f64]) -> Vec<f64> {
        let nx = self.nx;
        (self.members.iter().zip(x0.chunks(nx).zip(x1.chunks(nx))))
            .flat_map(|(s, (a, b))| s.difference(a, b))
            .collect()
    }
    fn chart_of(&self, x: &[f64]) -> Vec<f64> {
        (self.members.iter().zip(x.chunks(self.nx)))
            .flat_map(|(s, x)| s.chart_of(x))
            .collect()
    }
    fn state_at(&self, c: &[f64]) -> Vec<f64> {
        (self.members.iter().zip(c.chunks(self.ndx)))
            .flat_map(|(s, c)| s.state_at(c))
            .collect()
    }
}

impl<S: Continuous> Continuous for Stacked<'_, S> {
    /// A member's derivative is a tangent, `ndx` wide.
    fn nx(&self) -> usize {
        self.members.len() * self.ndx
    }
    fn m(&self) -> usize {
        self.members[0].m()
    }
    fn dt(&self) -> f64 {
        self.members[0].dt()
    }
    fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        self.each(x, self.ndx, |s, x| s.derivative(x, u))
    }
    fn derivative_jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        self.jacobians(x, |s, x| s.derivative_jacobian(x, u))
    }
}

/// Block `j` (`nx` wide) of every row of `width`.
fn block(x: &[f64], j: usize, nx: usize, width: usize) -> Vec<f64> {
    (x.chunks(width))
        .flat_map(|row| row[j * nx..(j + 1) * nx].iter().copied())
        .collect()
}

/// The request on the stacked system of `k` members: x0, the goal, the initial states and
/// the state bounds repeated for every member, each member's states weighed by Q/K and Q_f/K.
fn stacked_request(req: &PlanRequest, k: usize) -> PlanRequest {
    let each = |w: &Mat| {
        let n = w.rows;
        let mut out = Mat::zeros(k * n, k * n);
        for j in 0..k {
            for i in 0..n {
                for c in 0..n {
                    out.data[(j * n + i) * k * n + j * n + c] = w.data[i * n + c] / k as f64;
                }
            }
        }
        out
    };
    let rows = |x: &Mat| {
        let data = x.data.chunks(x.cols).flat_map(|r| r.repeat(k)).collect();
        Mat::new(x.rows, k * x.cols, data)
    };
    PlanRequest {
        x0: req.x0.repeat(k),
        goal: req.goal.repeat(k),
        q: each(&req.q),
        qf: each(&req.qf),
        x_init: req.x_init.as_ref().map(rows),
        x_min: req.x_min.as_ref().map(|v| v.repeat(k)),
        x_max: req.x_max.as_ref().map(|v| v.repeat(k)),
        ..req.clone()
    }
}

/// The stacked plan in one state's terms: the members' mean states and their spread, the
/// gains and cost-to-go for a deviation every member shares, the mean's distance to the goal
/// (`off_goal`: x ⊖ g).
fn unstack(
    mut plan: Plan,
    k: usize,
    (nx, ndx): (usize, usize),
    off_goal: impl Fn(&[f64]) -> Vec<f64>,
) -> Plan {
    let (x, std) = spread(&plan.x, k, nx);
    // K_t is [m, K·nx]: a shared δx moves every block. S_t is [K·nx, K·nx]: δXᵀ S δX with
    // δX = (δx, …, δx) sums every block.
    let fold = |w: &Mat, rows: usize| {
        let mut out = Mat::zeros(rows, ndx);
        for r in 0..w.rows {
            for c in 0..w.cols {
                out.data[(r % rows) * ndx + c % ndx] += w.data[r * w.cols + c];
            }
        }
        out
    };
    plan.gains.k = plan.gains.k.iter().map(|g| fold(g, g.rows)).collect();
    plan.gains.s = plan.gains.s.iter().map(|s| fold(s, ndx)).collect();
    plan.goal_error = norm(&off_goal(&x[x.len() - nx..]));
    plan.x = x;
    plan.x_std = Some(std);
    plan
}

/// Per row of stacked states `[R, K·nx]`, the members' mean and sample standard deviation
/// (divided by K − 1; 0 for one member) of each coordinate, each `[R, nx]`.
pub fn spread(x: &[f64], k: usize, nx: usize) -> (Vec<f64>, Vec<f64>) {
    let parts: Vec<Vec<f64>> = (0..k).map(|j| block(x, j, nx, k * nx)).collect();
    mean_std(&parts)
}

/// The elementwise mean of equally long vectors and their sample standard deviation
/// (divided by K − 1: K is small, and the members are K draws of what training could have
/// given; 0 for one vector).
pub fn mean_std(parts: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let k = parts.len() as f64;
    let mut mean = vec![0.0; parts.first().map_or(0, Vec::len)];
    for p in parts {
        mean.iter_mut().zip(p).for_each(|(s, v)| *s += v);
    }
    mean.iter_mut().for_each(|s| *s /= k);
    let mut ss = vec![0.0; mean.len()];
    for p in parts {
        for ((s, v), m) in ss.iter_mut().zip(p).zip(&mean) {
            *s += (v - m).powi(2);
        }
    }
    let std = if parts.len() > 1 {
        ss.iter().map(|s| (s / (k - 1.0)).sqrt()).collect()
    } else {
        vec![0.0; mean.len()]
    };
    (mean, std)
}
