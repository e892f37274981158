//! The manipulator equation, generic over the scalar type (docs/dynamics.md#manipulator-equation):
//!
//! ```text
//! M(q) q̈ = F(q, q̇, u) − c(q, q̇) − ∂V/∂q,   M = L Lᵀ
//! ```
//!
//! Everything here takes the Cholesky factor L with its q-derivatives ([`Factor`]), so a
//! learned L, a constant L and the factor of an analytic M all share one Coriolis term and one
//! solve. Nothing forms M⁻¹.

use std::ops::{Deref, Range};

use super::dual::{Dual, groups};
use super::scalar::Scalar;
use super::space::Space;
use crate::arena::{AVec, Arena, CollectIn};
use crate::linalg::cholesky::{Packed, Summed, factor_in_place, solve_by};

/// A lower-triangular n×n matrix stored row by row: (0,0), (1,0), (1,1), (2,0), …
/// This is also the order of a mass network's off-diagonal outputs (see `mass_matrix`).
#[derive(Debug, Clone)]
pub struct Tri<'a, T> {
    pub n: usize,
    pub entries: AVec<'a, T>,
}

impl<'a, T> Tri<'a, T> {
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

    /// The arena its entries live in.
    pub fn arena(&self) -> &'a Arena {
        self.entries.bump()
    }

    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Tri<'a, U> {
        Tri {
            n: self.n,
            entries: self.entries.iter().map(f).collect_in(self.arena()),
        }
    }
}

/// The index of a lower-triangle entry (i, j), j ≤ i, in row-by-row order.
pub fn tri_index(i: usize, j: usize) -> usize {
    Tri::<()>::index(i, j)
}

fn sum<S: Scalar>(terms: impl IntoIterator<Item = S>) -> Option<S> {
    terms.into_iter().reduce(|a, b| a + b)
}

/// Cholesky factor of a symmetric positive-definite matrix (only the lower triangle of `m` is
/// read). With dual entries this also differentiates the factorization. Its sums are rounded
/// in the [`Summed`] order, as every learned model's answers were recorded.
pub fn cholesky<'a, S: Scalar, R: Deref<Target = [S]>>(a: &'a Arena, m: &[R]) -> Tri<'a, S> {
    let n = m.len();
    let mut entries = AVec::with_capacity_in(Tri::<S>::len(n), a);
    for (i, row) in m.iter().enumerate() {
        entries.extend_from_slice(&row[..=i]);
    }
    factor_in_place(&mut entries, Packed(n), Summed);
    Tri { n, entries }
}

/// Solves L Lᵀ x = r by forward then back substitution.
pub fn solve_llt<'a, S: Scalar>(l: &Tri<S>, mut r: AVec<'a, S>) -> AVec<'a, S> {
    solve_by(&l.entries, Packed(l.n), &mut r, 1, Summed);
    r
}

/// (Lᵀ v)_a = Σ_{b ≥ a} L_ba v_b.
pub fn tri_t_mul<'a, S: Scalar>(l: &Tri<'a, S>, v: &[S]) -> AVec<'a, S> {
    (0..l.n)
        .map(|a| sum((a..l.n).map(|b| l.get(b, a).clone() * v[b].clone())).expect("n ≥ 1"))
        .collect_in(l.arena())
}

/// L(q) with its q-derivatives: what the Coriolis term and the solve take.
pub struct Factor<'a, S> {
    pub l: Tri<'a, S>,
    /// ∂L/∂q_k for each direction k, `None` where an entry does not depend on q_k.
    pub dl: AVec<'a, Tri<'a, Option<S>>>,
}

impl<'a, S: Scalar> Factor<'a, S> {
    /// The factor of n coordinates from `f(dirs)`, L over dual numbers whose tangents are the
    /// directions `dirs`, one group of them at a time ([`groups`]).
    pub fn from_groups(
        a: &'a Arena,
        n: usize,
        f: impl Fn(Range<usize>) -> Tri<'a, Dual<S>>,
    ) -> Self {
        let mut l = None;
        let mut dl = AVec::with_capacity_in(n, a);
        for dirs in groups::<S>(n) {
            let group = f(dirs.clone());
            dl.extend((0..dirs.len()).map(|k| group.map(|e| e.tangent(k).cloned())));
            l.get_or_insert_with(|| group.map(|e| e.v.clone()));
        }
        Self {
            l: l.expect("n ≥ 1"),
            dl,
        }
    }

    fn arena(&self) -> &'a Arena {
        self.l.arena()
    }
}

/// The Coriolis/centrifugal term c(q, q̇) = Ṁ q̇ − ∂/∂q (½ q̇ᵀ M q̇) (paper appendix A) from L and
/// ∂L/∂q_k. With w = Lᵀq̇ and L̇ = Σ_k ∂_kL q̇_k:
///   Ṁ q̇ = L̇ w + L (L̇ᵀ q̇),   ∂_i (½ q̇ᵀMq̇) = w · (∂_iL)ᵀ q̇.
/// (docs/dynamics.md#coriolis-term derives it.)
pub fn coriolis<'a, S: Scalar>(factor: &Factor<'a, S>, qd: &[S]) -> AVec<'a, S> {
    let (values, dls, a) = (&factor.l, &factor.dl, factor.arena());
    let n = values.n;
    let w = tri_t_mul(values, qd);
    // L̇ = Σ_k ∂_kL q̇_k, entry-wise; an entry with no tangent at all is zero.
    let ldot: Tri<Option<S>> = Tri {
        n,
        entries: (0..Tri::<S>::len(n))
            .map(|e| {
                sum((0..n).filter_map(|k| dls[k].entries[e].clone().map(|t| t * qd[k].clone())))
            })
            .collect_in(a),
    };
    let opt_tri_mul = |m: &Tri<Option<S>>, v: &[S], transpose: bool| -> AVec<'a, Option<S>> {
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
            .collect_in(a)
    };
    let ldot_w = opt_tri_mul(&ldot, &w, false);
    let ldot_t_qd = opt_tri_mul(&ldot, qd, true);
    // L (L̇ᵀ q̇): treat missing entries of L̇ᵀq̇ as zero.
    let l_ldot_t_qd: AVec<Option<S>> = (0..n)
        .map(|i| {
            sum((0..=i).filter_map(|j| ldot_t_qd[j].clone().map(|x| values.get(i, j).clone() * x)))
        })
        .collect_in(a);
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
        .collect_in(a)
}

/// q̈ from the manipulator equation given L(q) with q-tangents, ∂V/∂q and F.
/// `grad_v` is `None` for a zero potential.
pub fn acceleration<'a, S: Scalar>(
    factor: &Factor<'a, S>,
    grad_v: Option<&[S]>,
    forces: &[S],
    qd: &[S],
) -> AVec<'a, S> {
    let mut rhs = coriolis(factor, qd);
    for (r, f) in rhs.iter_mut().zip(forces) {
        *r = f.clone() - r.clone();
    }
    if let Some(g) = grad_v {
        for (r, g) in rhs.iter_mut().zip(g) {
            *r = r.clone() - g.clone();
        }
    }
    solve_llt(&factor.l, rhs)
}

/// The manipulator equation's residual at a given q̈, M(q) q̈ + c(q, q̇) + ∂V/∂q − F: zero
/// where q̈ is the model's own acceleration, and the torque loss's error where q̈ and the
/// inputs in F are measured (docs/training.md#torque-loss).
pub fn residual<'a, S: Scalar>(
    factor: &Factor<'a, S>,
    grad_v: Option<&[S]>,
    forces: &[S],
    qd: &[S],
    qdd: &[S],
) -> AVec<'a, S> {
    let l = &factor.l;
    let w = tri_t_mul(l, qdd);
    let mut r = coriolis(factor, qd);
    for (i, r) in r.iter_mut().enumerate() {
        let mw = sum((0..=i).map(|j| l.get(i, j).clone() * w[j].clone())).expect("n ≥ 1");
        *r = mw + r.clone() - forces[i].clone();
    }
    if let Some(g) = grad_v {
        for (r, g) in r.iter_mut().zip(g) {
            *r = r.clone() + g.clone();
        }
    }
    r
}

/// Values as dual numbers without tangents (parameters: constants for ∂/∂q).
pub fn constants(values: &[f64]) -> Vec<Dual<f64>> {
    values.iter().map(|&v| Dual::constant(v)).collect()
}

/// v̇ in f64 of a white-box mechanism on `space`: M(q) and V(q) over dual numbers (their
/// tangents along each velocity give ∂M/∂q for the Coriolis term and ∇V), and the generalized
/// forces.
pub fn white_box_acceleration<'a, M, R>(
    a: &'a Arena,
    space: &Space,
    mass: impl Fn(&[Dual<f64>]) -> M,
    potential: impl Fn(&[Dual<f64>]) -> Dual<f64>,
    forces: &[f64],
    q: &[f64],
    qd: &[f64],
) -> AVec<'a, f64>
where
    M: Deref<Target = [R]>,
    R: Deref<Target = [Dual<f64>]>,
{
    let n = space.nv();
    let factor = Factor::from_groups(a, n, |dirs| {
        cholesky(a, &mass(&space.seeded_in(a, q, &1.0, dirs)))
    });
    let grad_v: AVec<f64> = groups::<f64>(n)
        .flat_map(|dirs| {
            let v = potential(&space.seeded_in(a, q, &1.0, dirs.clone()));
            (0..dirs.len()).map(move |k| v.tangent(k).copied().unwrap_or(0.0))
        })
        .collect_in(a);
    acceleration(&factor, Some(&grad_v), forces, qd)
}
