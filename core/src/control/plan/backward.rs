//! iLQR's backward pass (`control::plan`): the Riccati recursion on the quadratic model of the
//! cost-to-go, each step's inputs a box QP, with the Levenberg–Marquardt term μI on Q_uu (docs/control.md#backward-pass).

use super::{Dynamics, Planner, Trajectory};
use crate::control::boxqp::box_qp;
use crate::control::linalg::{Mat, cholesky_solve};
use crate::error::Result;

/// Feedforward k_t and feedback K_t of a step, and what a full step should gain.
pub(super) struct Backward {
    pub(super) k: Vec<Vec<f64>>,
    pub(super) gains: Vec<Mat>,
    /// The quadratic model's decrease for a full step.
    pub(super) expected: f64,
}

impl<D: Dynamics> Planner<'_, D> {
    /// The feedforward k_t and feedback K_t of the regularized quadratic model, or `None` when
    /// some Q_uu is not positive definite on its free inputs.
    pub(super) fn backward(
        &self,
        cur: &Trajectory,
        a: &[Mat],
        b: &[Mat],
        mu: f64,
        warm: &[Vec<f64>],
    ) -> Result<Option<Backward>> {
        let (nx, m, t) = (self.sys.nx(), self.sys.m(), self.req.horizon);
        // Deviations, gains and the cost-to-go live in the tangent space.
        let ndx = self.sys.ndx();
        let req = self.req;
        let col = |v: Vec<f64>| Mat::new(v.len(), 1, v);
        let scaled =
            |w: &Mat, s: f64| Mat::new(w.rows, w.cols, w.data.iter().map(|v| v * s).collect());
        let dx = |s: usize| self.off_goal(&cur.x[s * nx..(s + 1) * nx]);
        let mut vx = scaled(&req.qf, 2.0).mul(&col(dx(t)));
        let mut vxx = scaled(&req.qf, 2.0);
        let (mut k_ff, mut k_fb) = (vec![Vec::new(); t], vec![Mat::zeros(m, ndx); t]);
        let mut expected = 0.0;
        let mut mu_eye = Mat::zeros(m, m);
        (0..m).for_each(|i| mu_eye.data[i * m + i] = mu);
        for s in (0..t).rev() {
            self.check()?;
            let u = &cur.u[s * m..(s + 1) * m];
            let (at, bt) = (&a[s], &b[s]);
            let qx = scaled(&req.q, 2.0).mul(&col(dx(s))).add(&at.t().mul(&vx));
            let qu = scaled(&req.r, 2.0)
                .mul(&col(u.to_vec()))
                .add(&bt.t().mul(&vx));
            let qxx = scaled(&req.q, 2.0).add(&at.t().mul(&vxx).mul(at));
            let quu = scaled(&req.r, 2.0)
                .add(&bt.t().mul(&vxx).mul(bt))
                .add(&mu_eye)
                .symmetrized();
            let qux = bt.t().mul(&vxx).mul(at);
            let lo: Vec<f64> = (0..m).map(|i| self.bounds.lo[i] - u[i]).collect();
            let hi: Vec<f64> = (0..m).map(|i| self.bounds.hi[i] - u[i]).collect();
            let Some(qp) = box_qp(&quu, &qu.data, &lo, &hi, &warm[s]) else {
                return Ok(None);
            };
            let mut kmat = Mat::zeros(m, ndx);
            let free: Vec<usize> = (0..m).filter(|&i| qp.free[i]).collect();
            if !free.is_empty() {
                let mut rhs = Mat::zeros(free.len(), ndx);
                for (r, &i) in free.iter().enumerate() {
                    rhs.data[r * ndx..(r + 1) * ndx]
                        .copy_from_slice(&qux.data[i * ndx..(i + 1) * ndx]);
                }
                let sol = cholesky_solve(&qp.l_free, &rhs);
                for (r, &i) in free.iter().enumerate() {
                    for j in 0..ndx {
                        kmat.data[i * ndx + j] = -sol.at(r, j);
                    }
                }
            }
            let k = col(qp.x.clone());
            let kt = kmat.t();
            // V_x = Q_x + Kᵀ Q_uu k + Kᵀ Q_u + Q_uxᵀ k;  V_xx likewise (Tassa 2014, eq. 11).
            vx = qx
                .add(&kt.mul(&quu).mul(&k))
                .add(&kt.mul(&qu))
                .add(&qux.t().mul(&k));
            vxx = qxx
                .add(&kt.mul(&quu).mul(&kmat))
                .add(&kt.mul(&qux))
                .add(&qux.t().mul(&kmat))
                .symmetrized();
            let ktqu: f64 = qp.x.iter().zip(&qu.data).map(|(a, b)| a * b).sum();
            let kquuk: f64 = qp.x.iter().zip(&quu.mul(&k).data).map(|(a, b)| a * b).sum();
            expected -= ktqu + 0.5 * kquuk;
            k_ff[s] = qp.x;
            k_fb[s] = kmat;
        }
        Ok(Some(Backward {
            k: k_ff,
            gains: k_fb,
            expected,
        }))
    }
}
