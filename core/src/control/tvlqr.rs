//! Finite-horizon, time-varying LQR (docs/control.md#tvlqr):
//!
//! ```text
//! minimize Σ_{t<T} (δx_tᵀ Q δx_t + δu_tᵀ R δu_t) + δx_Tᵀ Q_f δx_T   (no ½)
//! S_T = Q_f
//! K_t = (R + B_tᵀ S_{t+1} B_t)⁻¹ B_tᵀ S_{t+1} A_t        (Cholesky solve)
//! S_t = Q + K_tᵀ R K_t + (A_t − B_t K_t)ᵀ S_{t+1} (A_t − B_t K_t)   (Joseph form, stays PSD)
//! policy: u_t = ū_t − K_t (x_t − x̄_t)
//! ```
//!
//! K has T entries and S has T + 1: the convention of Drake's
//! FiniteHorizonLinearQuadraticRegulator and of python-control's `dlqr` (u = −K δx), whose
//! infinite-horizon gain a long constant horizon converges to.

use super::linalg::{Mat, cholesky_solve};
use crate::error::{Error, Result};

/// Relative asymmetry tolerated in Q, R and Q_f.
pub const SYMMETRY_TOL: f64 = 1e-9;

#[derive(Debug, Clone, PartialEq)]
pub struct Gains {
    /// K_t, t = 0..T−1, each m × nx.
    pub k: Vec<Mat>,
    /// S_t, t = 0..T, each nx × nx.
    pub s: Vec<Mat>,
}

/// A weight matrix of the right size, finite, symmetric, and PSD (PD when `definite`).
pub fn check_weight(name: &str, w: &Mat, dim: usize, definite: bool) -> Result<()> {
    if w.rows != dim || w.cols != dim {
        return Err(Error::invalid(
            name,
            format!("must be {dim}×{dim}, got {}×{}", w.rows, w.cols),
        ));
    }
    if let Some(v) = w.data.iter().find(|v| !v.is_finite()) {
        return Err(Error::invalid(
            name,
            format!("has a non-finite entry ({v})"),
        ));
    }
    if w.asymmetry() > SYMMETRY_TOL {
        return Err(Error::invalid(name, "must be symmetric"));
    }
    let scale = w.data.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    // PSD: positive definite after a tiny relative shift; PD: positive definite as given.
    let shift = if definite { 0.0 } else { 1e-12 * scale };
    let mut shifted = w.symmetrized();
    for i in 0..dim {
        shifted.data[i * dim + i] += shift;
    }
    if shifted.cholesky().is_none() {
        let what = if definite {
            "positive definite"
        } else {
            "positive semidefinite"
        };
        return Err(Error::invalid(name, format!("must be {what}")));
    }
    Ok(())
}

/// The field an error about the nominal trajectory names: the Tvlqr call's; a plan names its
/// own start instead (`Planner::finish`).
pub const NOMINAL: &str = "x_bar";

/// The TVLQR gains for the linearizations (A_t, B_t), t = 0..T−1.
pub fn tvlqr(a: &[Mat], b: &[Mat], q: &Mat, r: &Mat, qf: &Mat) -> Result<Gains> {
    if a.is_empty() || a.len() != b.len() {
        return Err(Error::invalid(
            "horizon",
            format!(
                "need T ≥ 1 matching A and B, got {} and {}",
                a.len(),
                b.len()
            ),
        ));
    }
    let (nx, m) = (a[0].rows, b[0].cols);
    check_weight("Q", q, nx, false)?;
    check_weight("Qf", qf, nx, false)?;
    check_weight("R", r, m, true)?;
    let mut s = vec![qf.symmetrized()];
    let mut k = Vec::with_capacity(a.len());
    for t in (0..a.len()).rev() {
        let (at, bt) = (&a[t], &b[t]);
        let next = s.last().expect("S_T is there");
        let sb = next.mul(bt); // S B, nx × m
        let btsb = bt.t().mul(&sb); // Bᵀ S B
        let h = r.add(&btsb).symmetrized();
        if h.data.iter().any(|v| !v.is_finite()) {
            // Not R's fault: S grows like ‖A‖²ᵏ back from the end where A is unstable.
            return Err(Error::invalid(
                "horizon",
                format!(
                    "the cost-to-go S_{} overflows f64 ({} steps before the end): the \
                     linearization is too unstable for this horizon; shorten it or scale Q_f down",
                    t + 1,
                    a.len() - t - 1
                ),
            ));
        }
        // R was checked positive definite above, so this is never R's fault: BᵀSB has swamped
        // it in floating point, where the model's B (or the cost-to-go) is out of scale.
        let l = h.cholesky().ok_or_else(|| {
            let largest = bt.data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            Error::invalid(
                NOMINAL,
                format!(
                    "no gains at step {t}: R + BᵀSB is not positive definite in floating point \
                     (the model's B_{t} has entries up to {largest:e}; R itself is positive \
                     definite): the model's linearization there is out of range; keep the \
                     nominal within the states the model was trained on"
                ),
            )
        })?;
        let kt = cholesky_solve(&l, &sb.t().mul(at)); // (R + BᵀSB)⁻¹ BᵀSA
        let acl = at.sub(&bt.mul(&kt));
        let st = q
            .add(&kt.t().mul(r).mul(&kt))
            .add(&acl.t().mul(next).mul(&acl))
            .symmetrized();
        k.push(kt);
        s.push(st);
    }
    k.reverse();
    s.reverse();
    Ok(Gains { k, s })
}
