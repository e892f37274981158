//! The constraints' curvature for the SQP's QP: a damped BFGS approximation of each
//! interval's part of ∇²(λᵀc), the Lagrangian's Hessian less the cost's (partitioned
//! quasi-Newton). Interval k's two defects depend only on v_k = (x_k, u_k, x_c, x_{k+1}),
//! which the layout keeps contiguous, so the Hessian is block-banded like the Jacobian and
//! each block is a small dense matrix learned from the change of v_k's Lagrangian gradient
//! between iterates. Without it the QP's step ignores how the defects bend and the SQP crawls
//! (the 200-step swing-up cut every step to ½ or less and had not converged in 200
//! iterations); Powell's damping keeps every block positive semidefinite, so the QP stays
//! convex where the true curvature is not.

use super::transcription::{Entry, Layout};

pub(super) struct Curvature {
    /// Per interval, the dense `[e, e]` block over v_k, e = 3nx + m; zero until learned.
    pub blocks: Vec<Vec<f64>>,
    pub size: usize,
}

impl Curvature {
    pub(super) fn new(l: &Layout) -> Self {
        let size = 3 * l.nx + l.m;
        Self {
            blocks: vec![vec![0.0; size * size]; l.intervals],
            size,
        }
    }

    /// Learns from the step `from` → `to` (whole decision vectors), with the defect
    /// Jacobians at both as triplets and the multipliers λ of the last QP.
    pub(super) fn update(
        &mut self,
        l: &Layout,
        (from, to): (&[f64], &[f64]),
        (jac_from, jac_to): (&[Entry], &[Entry]),
        lambda: &[f64],
    ) {
        let e = self.size;
        let (g_from, g_to) = (
            self.gradients(l, jac_from, lambda),
            self.gradients(l, jac_to, lambda),
        );
        for k in 0..l.intervals {
            let at = l.x(k);
            let s: Vec<f64> = (0..e).map(|i| to[at + i] - from[at + i]).collect();
            let y: Vec<f64> = (0..e)
                .map(|i| g_to[k * e + i] - g_from[k * e + i])
                .collect();
            damped_bfgs(&mut self.blocks[k], e, &s, &y);
        }
    }

    /// Per interval, v_k's part of Jᵀλ (`[T, e]`).
    fn gradients(&self, l: &Layout, jac: &[Entry], lambda: &[f64]) -> Vec<f64> {
        let e = self.size;
        let mut g = vec![0.0; l.intervals * e];
        for &(i, j, v) in jac {
            let k = i / (2 * l.nx);
            g[k * e + (j - l.x(k))] += lambda[i] * v;
        }
        g
    }
}

/// One BFGS update of the `[e, e]` block `b` with Powell's damping (Nocedal & Wright,
/// Procedure 18.2): y is blended toward Bs so that sᵀr ≥ 0.2 sᵀBs, which keeps B positive
/// semidefinite. A block still zero starts as γI, γ = yᵀy / sᵀy (the scale of the curvature
/// seen along s) when that is positive.
fn damped_bfgs(b: &mut [f64], e: usize, s: &[f64], y: &[f64]) {
    let dot = |a: &[f64], c: &[f64]| a.iter().zip(c).map(|(x, z)| x * z).sum::<f64>();
    let (ss, sy, yy) = (dot(s, s), dot(s, y), dot(y, y));
    if !(ss > 0.0 && ss.is_finite() && yy.is_finite()) {
        return;
    }
    if b.iter().all(|v| *v == 0.0) {
        if sy <= 0.0 {
            return;
        }
        let gamma = yy / sy;
        for i in 0..e {
            b[i * e + i] = gamma;
        }
    }
    let bs: Vec<f64> = (0..e).map(|i| dot(&b[i * e..(i + 1) * e], s)).collect();
    let sbs = dot(s, &bs);
    if sbs.is_nan() || sbs <= 1e-300 {
        return;
    }
    let theta = if sy >= 0.2 * sbs {
        1.0
    } else {
        0.8 * sbs / (sbs - sy)
    };
    let r: Vec<f64> = (0..e)
        .map(|i| theta * y[i] + (1.0 - theta) * bs[i])
        .collect();
    let sr = dot(s, &r);
    if sr.is_nan() || sr <= 0.0 {
        return;
    }
    for i in 0..e {
        for j in 0..e {
            b[i * e + j] += r[i] * r[j] / sr - bs[i] * bs[j] / sbs;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn times(b: &[f64], s: &[f64]) -> Vec<f64> {
        let e = s.len();
        (0..e)
            .map(|i| (0..e).map(|j| b[i * e + j] * s[j]).sum())
            .collect()
    }

    /// Each update satisfies the secant equation B s = y when the curvature along s is
    /// positive, and damping keeps B positive semidefinite when it is not.
    #[test]
    fn updates_meet_the_secant_equation_and_stay_semidefinite() {
        let h = [4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0];
        let mut b = vec![0.0; 9];
        for s in [[1.0, 0.0, 0.0], [0.3, 1.0, 0.0], [0.1, -0.2, 1.0]] {
            let y = times(&h, &s);
            damped_bfgs(&mut b, 3, &s, &y);
            for (got, want) in times(&b, &s).iter().zip(&y) {
                // Rounding in a handful of operations on O(1) numbers.
                assert!((got - want).abs() < 1e-12, "{b:?}");
            }
        }
        // Negative curvature along s: B must not follow it below zero.
        let s = [0.5, -1.0, 0.3];
        let y: Vec<f64> = times(&h, &s).iter().map(|v| -v).collect();
        damped_bfgs(&mut b, 3, &s, &y);
        let mut rng = crate::rng::Rng::new(3);
        for _ in 0..1000 {
            let x: Vec<f64> = (0..3).map(|_| rng.normal()).collect();
            let q: f64 = x.iter().zip(times(&b, &x)).map(|(a, c)| a * c).sum();
            assert!(q >= -1e-12, "xᵀBx = {q}");
        }
    }
}
