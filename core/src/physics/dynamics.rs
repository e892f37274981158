//! The manipulator equation, generic over the scalar type (docs/dynamics.md#manipulator-equation):
//!
//! ```text
//! M(q) q̈ = F(q, q̇, u) − c(q, q̇) − ∂V/∂q,   M = L Lᵀ
//! ```
//!
//! Everything here takes the Cholesky factor L with its q-derivatives (as dual numbers), so a
//! learned L, a constant L and the factor of an analytic M all share one Coriolis term and one
//! solve. Nothing forms M⁻¹.

use super::dual::Dual;
use super::scalar::Scalar;
use crate::linalg::cholesky::{Packed, Summed, factor_in_place, solve_by};

/// A lower-triangular n×n matrix stored row by row: (0,0), (1,0), (1,1), (2,0), …
/// This is also the order of a mass network's off-diagonal outputs (see `mass_matrix`).
#[derive(Debug, Clone)]
pub struct Tri<T> {
    pub n: usize,
    pub entries: Vec<T>,
}

impl<T> Tri<T> {
    pub fn index(i: usize, j: usize) -> usize {
        debug_assert!(j <= i);
        i * (i + 1) / 2 + j
    }

    pub fn len(n: usize) -> usize {
        n * (n + 1) / 2
    }

    pub fn get(&self, i: usize, j: usize) -> &T {
        &self.entries[Self::index(i, j)]
    }

    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Tri<U> {
        Tri {
            n: self.n,
            entries: self.entries.iter().map(f).collect(),
        }
    }
}

fn sum<S: Scalar>(terms: impl IntoIterator<Item = S>) -> Option<S> {
    terms.into_iter().reduce(|a, b| a + b)
}

/// Cholesky factor of a symmetric positive-definite matrix (only the lower triangle of `m` is
/// read). With dual entries this also differentiates the factorization. Its sums are rounded
/// in the [`Summed`] order, as every learned model's answers were recorded.
pub fn cholesky<S: Scalar>(m: &[Vec<S>]) -> Tri<S> {
    let n = m.len();
    let mut entries = Vec::with_capacity(Tri::<S>::len(n));
    for (i, row) in m.iter().enumerate() {
        entries.extend_from_slice(&row[..=i]);
    }
    factor_in_place(&mut entries, Packed(n), Summed);
    Tri { n, entries }
}

/// Solves L Lᵀ x = r by forward then back substitution.
pub fn solve_llt<S: Scalar>(l: &Tri<S>, mut r: Vec<S>) -> Vec<S> {
    solve_by(&l.entries, Packed(l.n), &mut r, 1, Summed);
    r
}

/// (Lᵀ v)_a = Σ_{b ≥ a} L_ba v_b.
pub fn tri_t_mul<S: Scalar>(l: &Tri<S>, v: &[S]) -> Vec<S> {
    (0..l.n)
        .map(|a| sum((a..l.n).map(|b| l.get(b, a).clone() * v[b].clone())).expect("n ≥ 1"))
        .collect()
}

/// The Coriolis/centrifugal term c(q, q̇) = Ṁ q̇ − ∂/∂q (½ q̇ᵀ M q̇) (paper appendix A) from L and
/// ∂L/∂q_k. With w = Lᵀq̇ and L̇ = Σ_k ∂_kL q̇_k:
///   Ṁ q̇ = L̇ w + L (L̇ᵀ q̇),   ∂_i (½ q̇ᵀMq̇) = w · (∂_iL)ᵀ q̇.
/// (docs/dynamics.md#coriolis-term derives it.)
pub fn coriolis<S: Scalar>(l: &Tri<Dual<S>>, qd: &[S]) -> Vec<S> {
    let n = l.n;
    let values = l.map(|e| e.v.clone());
    let w = tri_t_mul(&values, qd);
    // ∂_k L as a Tri per direction k (None where that entry has no k-tangent).
    let dl = |k: usize| -> Tri<Option<S>> { l.map(|e| e.tangent(k).cloned()) };
    let dls: Vec<Tri<Option<S>>> = (0..n).map(dl).collect();
    // L̇ = Σ_k ∂_kL q̇_k, entry-wise; an entry with no tangent at all is zero.
    let ldot: Tri<Option<S>> = Tri {
        n,
        entries: (0..Tri::<S>::len(n))
            .map(|e| {
                sum((0..n).filter_map(|k| dls[k].entries[e].clone().map(|t| t * qd[k].clone())))
            })
            .collect(),
    };
    let opt_tri_mul = |m: &Tri<Option<S>>, v: &[S], transpose: bool| -> Vec<Option<S>> {
        (0..n)
            .map(|i| {
                sum((0..n).filter_map(|j| {
                    let (r, c) = if transpose { (j, i) } else { (i, j) };
                    if c > r {
                        return None;
                    }
                    m.get(r, c).clone().map(|x| x * v[j].clone())
                }))
            })
            .collect()
    };
    let ldot_w = opt_tri_mul(&ldot, &w, false);
    let ldot_t_qd: Vec<Option<S>> = opt_tri_mul(&ldot, qd, true);
    // L (L̇ᵀ q̇): treat missing entries of L̇ᵀq̇ as zero.
    let l_ldot_t_qd: Vec<Option<S>> = (0..n)
        .map(|i| {
            sum((0..=i).filter_map(|j| ldot_t_qd[j].clone().map(|x| values.get(i, j).clone() * x)))
        })
        .collect();
    (0..n)
        .map(|i| {
            let mdot_qd = [ldot_w[i].clone(), l_ldot_t_qd[i].clone()];
            let dli_t_qd = opt_tri_mul(&dls[i], qd, true);
            let grad_ke = sum((0..n).filter_map(|a| dli_t_qd[a].clone().map(|x| w[a].clone() * x)));
            let plus = sum(mdot_qd.into_iter().flatten());
            match (plus, grad_ke) {
                (Some(p), Some(g)) => p - g,
                (Some(p), None) => p,
                (None, Some(g)) => -g,
                // M constant in q: no Coriolis forces; 0 built from q̇ to stay in S.
                (None, None) => qd[i].clone() - qd[i].clone(),
            }
        })
        .collect()
}

/// q̈ from the manipulator equation given L(q) with q-tangents, ∂V/∂q and F.
/// `grad_v` is `None` for a zero potential.
pub fn acceleration<S: Scalar>(
    l: &Tri<Dual<S>>,
    grad_v: Option<Vec<S>>,
    forces: Vec<S>,
    qd: &[S],
) -> Vec<S> {
    let c = coriolis(l, qd);
    let mut rhs: Vec<S> = forces.into_iter().zip(c).map(|(f, c)| f - c).collect();
    if let Some(g) = grad_v {
        rhs = rhs.into_iter().zip(g).map(|(r, g)| r - g).collect();
    }
    solve_llt(&l.map(|e| e.v.clone()), rhs)
}

/// q as dual variables: q_k carries tangent `one` in direction k.
pub fn dual_vars<S: Scalar>(q: &[S], one: &S) -> Vec<Dual<S>> {
    let n = q.len();
    q.iter()
        .enumerate()
        .map(|(k, qk)| Dual::variable(qk.clone(), k, n, one.clone()))
        .collect()
}

/// Values as dual numbers without tangents (parameters: constants for ∂/∂q).
pub fn constants(values: &[f64]) -> Vec<Dual<f64>> {
    values.iter().map(|&v| Dual::constant(v)).collect()
}

/// q̈ in f64 of a white-box mechanism: M(q) and V(q) over dual numbers (their q-tangents give
/// ∂M/∂q for the Coriolis term and ∇V), and the generalized forces.
pub fn white_box_acceleration(
    mass: impl Fn(&[Dual<f64>]) -> Vec<Vec<Dual<f64>>>,
    potential: impl Fn(&[Dual<f64>]) -> Dual<f64>,
    forces: Vec<f64>,
    q: &[f64],
    qd: &[f64],
) -> Vec<f64> {
    let qv = dual_vars(q, &1.0);
    let v = potential(&qv);
    let grad_v = (0..q.len())
        .map(|k| v.tangent(k).copied().unwrap_or(0.0))
        .collect();
    acceleration(&cholesky(&mass(&qv)), Some(grad_v), forces, qd)
}
