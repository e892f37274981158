//! The time-varying affine feedback a TVLQR solution defines, applied along a rollout:
//! u_t = ū_t − K_t (x_t − x̄_t) (the `Tvlqr` convention).

/// Nominal states x̄ `[T or T+1, nx]`, inputs ū `[T, m]` and gains K `[T, m, nx]`, row-major.
#[derive(Debug, Clone)]
pub struct Policy {
    pub xbar: Vec<f64>,
    pub ubar: Vec<f64>,
    pub k: Vec<f64>,
    pub nx: usize,
    pub m: usize,
}

impl Policy {
    /// The input at step `t` in state `x`.
    pub fn input(&self, t: usize, x: &[f64]) -> Vec<f64> {
        let (nx, m) = (self.nx, self.m);
        let xbar = &self.xbar[t * nx..(t + 1) * nx];
        (0..m)
            .map(|i| {
                let k = &self.k[(t * m + i) * nx..(t * m + i + 1) * nx];
                let kdx: f64 = k
                    .iter()
                    .zip(x.iter().zip(xbar))
                    .map(|(k, (x, xb))| k * (x - xb))
                    .sum();
                self.ubar[t * m + i] - kdx
            })
            .collect()
    }
}
