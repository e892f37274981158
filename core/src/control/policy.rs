//! The time-varying affine feedback a TVLQR solution defines, applied along a rollout:
//! u_t = ū_t − K_t (x_t ⊖ x̄_t) (the `Tvlqr` convention; ⊖ the configuration space's
//! difference, plain subtraction for a model whose every joint is one number).

use crate::physics::space::Space;

/// Nominal states x̄ `[T or T+1, nq + nv]`, inputs ū `[T, m]` and gains K `[T, m, 2nv]`,
/// row-major, on the model's configuration space.
#[derive(Debug, Clone)]
pub struct Policy {
    pub xbar: Vec<f64>,
    pub ubar: Vec<f64>,
    pub k: Vec<f64>,
    pub space: Space,
    pub m: usize,
}

impl Policy {
    /// The input at step `t` in state `x`.
    pub fn input(&self, t: usize, x: &[f64]) -> Vec<f64> {
        let (nx, ndx, m) = (
            self.space.nq() + self.space.nv(),
            2 * self.space.nv(),
            self.m,
        );
        let xbar = &self.xbar[t * nx..(t + 1) * nx];
        let gain = |i: usize| &self.k[(t * m + i) * ndx..(t * m + i + 1) * ndx];
        if self.space.is_flat() {
            return (0..m)
                .map(|i| {
                    let kdx: f64 = (gain(i).iter().zip(x.iter().zip(xbar)))
                        .map(|(k, (x, xb))| k * (x - xb))
                        .sum();
                    self.ubar[t * m + i] - kdx
                })
                .collect();
        }
        let dx = self.space.state_difference(xbar, x);
        (0..m)
            .map(|i| {
                let kdx: f64 = gain(i).iter().zip(&dx).map(|(k, d)| k * d).sum();
                self.ubar[t * m + i] - kdx
            })
            .collect()
    }
}
