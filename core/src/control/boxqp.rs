//! A small box-constrained QP, minimize ½ xᵀHx + gᵀx subject to lo ≤ x ≤ hi, by projected
//! Newton (Bertsekas 1982; the solver of Tassa, Mansard & Todorov 2014 for control-limited
//! DDP): Newton steps on the free variables, a projected Armijo line search, and the clamped
//! set updated from the gradient's sign at the bounds. For the handful of inputs a robot has
//! it ends in a few iterations; unbounded, it is one Newton step (exact). The math:
//! docs/control.md#box-constrained-qp.

use super::linalg::{Mat, cholesky_solve};

/// The solution, which of its components are free (not at an active bound), and the Cholesky
/// factor of H restricted to the free components (for the feedback gains).
pub struct BoxQp {
    pub x: Vec<f64>,
    pub free: Vec<bool>,
    pub l_free: Mat,
}

const MAX_ITERATIONS: usize = 100;
const ARMIJO: f64 = 0.1;

fn value(h: &Mat, g: &[f64], x: &[f64]) -> f64 {
    let hx = h.mul(&Mat::new(x.len(), 1, x.to_vec()));
    x.iter()
        .zip(&hx.data)
        .zip(g)
        .map(|((x, hx), g)| 0.5 * x * hx + g * x)
        .sum()
}

fn restrict(h: &Mat, free: &[bool]) -> Mat {
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let mut out = Mat::zeros(idx.len(), idx.len());
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            out.data[a * idx.len() + b] = h.at(i, j);
        }
    }
    out
}

/// Solves the QP from `x0` (clamped into the box). `None` when H is not positive definite on
/// the free components.
pub fn box_qp(h: &Mat, g: &[f64], lo: &[f64], hi: &[f64], x0: &[f64]) -> Option<BoxQp> {
    let n = g.len();
    let clamp = |x: &[f64]| -> Vec<f64> { (0..n).map(|i| x[i].max(lo[i]).min(hi[i])).collect() };
    let mut x = clamp(x0);
    let mut free = vec![true; n];
    for _ in 0..MAX_ITERATIONS {
        let grad: Vec<f64> = h
            .mul(&Mat::new(n, 1, x.clone()))
            .data
            .iter()
            .zip(g)
            .map(|(hx, g)| hx + g)
            .collect();
        free = (0..n)
            .map(|i| !((x[i] <= lo[i] && grad[i] > 0.0) || (x[i] >= hi[i] && grad[i] < 0.0)))
            .collect();
        if !free.iter().any(|&f| f) {
            break;
        }
        let l = restrict(h, &free).cholesky()?;
        let grad_free: Vec<f64> = (0..n).filter(|&i| free[i]).map(|i| grad[i]).collect();
        let scale = 1.0 + grad.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if grad_free.iter().all(|v| v.abs() <= 1e-13 * scale) {
            break;
        }
        let step_free = cholesky_solve(&l, &Mat::new(grad_free.len(), 1, grad_free));
        let mut dir = vec![0.0; n];
        for (k, i) in (0..n).filter(|&i| free[i]).enumerate() {
            dir[i] = -step_free.data[k];
        }
        // Projected Armijo search along the Newton direction.
        let f0 = value(h, g, &x);
        let mut alpha = 1.0;
        let next = loop {
            let cand = clamp(&(0..n).map(|i| x[i] + alpha * dir[i]).collect::<Vec<_>>());
            let decrease: f64 = (0..n).map(|i| grad[i] * (cand[i] - x[i])).sum();
            if value(h, g, &cand) - f0 <= ARMIJO * decrease {
                break Some(cand);
            }
            alpha *= 0.5;
            if alpha < 1e-12 {
                break None;
            }
        };
        let Some(next) = next else { break };
        let moved = (0..n).fold(0.0f64, |m, i| m.max((next[i] - x[i]).abs()));
        x = next;
        if moved <= 1e-14 * (1.0 + x.iter().fold(0.0f64, |m, v| m.max(v.abs()))) {
            break;
        }
    }
    let l_free = restrict(h, &free).cholesky()?;
    Some(BoxQp { x, free, l_free })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unbounded_is_the_newton_step() {
        let h = Mat::new(2, 2, vec![4.0, 1.0, 1.0, 3.0]);
        let g = [1.0, -2.0];
        let inf = [f64::INFINITY; 2];
        let r = box_qp(&h, &g, &[-f64::INFINITY; 2], &inf, &[0.0; 2]).unwrap();
        // H x = −g: x = (4/11, −9/11)... solved directly.
        let det = 4.0 * 3.0 - 1.0;
        let want = [
            -(3.0 * 1.0 - 1.0 * -2.0) / det,
            -(4.0 * -2.0 - 1.0 * 1.0) / det,
        ];
        for (x, w) in r.x.iter().zip(want) {
            assert!((x - w).abs() < 1e-14, "{:?} vs {want:?}", r.x);
        }
        assert_eq!(r.free, [true, true]);
    }

    #[test]
    fn bounds_clamp_and_the_rest_is_optimal() {
        // Unconstrained optimum x = (2, −1) by H = I, g = (−2, 1); box [−0.5, 0.5]².
        let h = Mat::new(2, 2, vec![1.0, 0.0, 0.0, 1.0]);
        let r = box_qp(&h, &[-2.0, 1.0], &[-0.5, -0.5], &[0.5, 0.5], &[0.0; 2]).unwrap();
        assert_eq!(r.x, [0.5, -0.5]);
        assert_eq!(r.free, [false, false]);
        // Coupled: the clamped component shifts the free one's optimum.
        let h = Mat::new(2, 2, vec![2.0, 1.0, 1.0, 2.0]);
        let r = box_qp(&h, &[-10.0, 0.0], &[-1.0, -1.0], &[1.0, 1.0], &[0.0; 2]).unwrap();
        // x0 = 1 (clamped); then 2·x1 + 1 = 0 → x1 = −0.5.
        assert!(
            (r.x[0] - 1.0).abs() < 1e-14 && (r.x[1] + 0.5).abs() < 1e-12,
            "{:?}",
            r.x
        );
        assert_eq!(r.free, [false, true]);
    }

    #[test]
    fn an_indefinite_hessian_is_refused() {
        let h = Mat::new(2, 2, vec![1.0, 2.0, 2.0, 1.0]);
        let inf = [f64::INFINITY; 2];
        assert!(box_qp(&h, &[0.0, 1.0], &[-f64::INFINITY; 2], &inf, &[0.0; 2]).is_none());
    }
}
