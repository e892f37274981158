//! iLQR's forward passes (`control::plan`): the open-loop rollout of an input sequence and the
//! line search, every step size in one batched closed-loop rollout.

use super::backward::Backward;
use super::{Dynamics, Planner, STEP_SIZES, Trajectory};
use crate::error::Result;

impl<D: Dynamics> Planner<'_, D> {
    /// The open-loop rollout of `u` from x0.
    pub(in crate::control) fn rollout(&self, u: Vec<f64>) -> Result<Trajectory> {
        let (nx, m) = (self.sys.nx(), self.sys.m());
        let mut x = self.req.x0.clone();
        for s in 0..self.req.horizon {
            self.check()?;
            let next = self
                .sys
                .step(&x[s * nx..(s + 1) * nx], &u[s * m..(s + 1) * m]);
            x.extend(next);
        }
        let cost = self.cost(&x, &u);
        Ok(Trajectory {
            x,
            u,
            cost,
            jacobians: None,
        })
    }

    /// All step sizes in one batched closed-loop rollout; the cheapest that lowers the cost.
    pub(super) fn line_search(
        &self,
        cur: &Trajectory,
        back: &Backward,
    ) -> Result<Option<Trajectory>> {
        let (nx, m, t) = (self.sys.nx(), self.sys.m(), self.req.horizon);
        let alphas: Vec<f64> = (0..STEP_SIZES).map(|i| 0.5f64.powi(i as i32)).collect();
        let rows = alphas.len();
        let mut xs: Vec<Vec<f64>> = vec![self.req.x0.clone(); rows];
        let mut us: Vec<Vec<f64>> = vec![Vec::with_capacity(t * m); rows];
        for s in 0..t {
            self.check()?;
            let (mut xb, mut ub) = (Vec::with_capacity(rows * nx), Vec::with_capacity(rows * m));
            for (r, alpha) in alphas.iter().enumerate() {
                let x = &xs[r][s * nx..(s + 1) * nx];
                let dx = self.sys.difference(&cur.x[s * nx..(s + 1) * nx], x);
                let mut u: Vec<f64> = (0..m)
                    .map(|i| {
                        let fb: f64 = (0..dx.len()).map(|j| back.gains[s].at(i, j) * dx[j]).sum();
                        cur.u[s * m + i] + alpha * back.k[s][i] + fb
                    })
                    .collect();
                self.bounds.clamp(&mut u);
                xb.extend_from_slice(x);
                ub.extend_from_slice(&u);
                us[r].extend(u);
            }
            let next = self.sys.step(&xb, &ub);
            for (r, x) in xs.iter_mut().enumerate() {
                x.extend_from_slice(&next[r * nx..(r + 1) * nx]);
            }
        }
        Ok(xs
            .into_iter()
            .zip(us)
            .map(|(x, u)| {
                let cost = self.cost(&x, &u);
                Trajectory {
                    x,
                    u,
                    cost,
                    jacobians: None,
                }
            })
            .filter(|c| c.cost < cur.cost)
            .min_by(|a, b| a.cost.total_cmp(&b.cost)))
    }
}
