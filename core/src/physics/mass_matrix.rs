//! M(q) = L(q) L(q)ᵀ in its three forms: a Cholesky MLP, a learned constant, the template's
//! analytic M factored per sample. Each yields L with its q-derivatives as dual numbers
//! (docs/dynamics.md#cholesky-parameterization).

use super::dual::Dual;
use super::dynamics::Tri;
use super::scalar::Scalar;
use crate::arena::{AVec, Arena, CollectIn};

/// softplus(c) = 1, so a zero network output puts 1 on L's diagonal: M starts near I.
pub const DIAG_SHIFT: f64 = 0.541_324_854_612_918_1; // ln(e − 1)
/// Floor on L's diagonal: M stays positive definite whatever the weights do (a bare constant
/// offset can cross zero during training).
pub const DIAG_EPS: f64 = 1e-3;

/// Number of network outputs for L: n diagonal entries, then the strictly lower triangle.
pub fn outputs(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Maps raw outputs (paper order: the n diagonal entries first, then (1,0), (2,0), (2,1), …)
/// to L, with the diagonal made positive: L_ii = softplus(y_i + c) + ε.
pub fn factor_from_outputs<'a, S: Scalar>(
    a: &'a Arena,
    raw: impl IntoIterator<Item = Dual<S>>,
    n: usize,
) -> Tri<'a, Dual<S>> {
    let mut raw = raw.into_iter();
    let diag: AVec<Dual<S>> = raw
        .by_ref()
        .take(n)
        .map(|y| y.shift(DIAG_SHIFT).softplus().shift(DIAG_EPS))
        .collect_in(a);
    let mut off = raw;
    let mut entries = AVec::with_capacity_in(outputs(n), a);
    for (i, d) in diag.into_iter().enumerate() {
        // Row i: L_i0 … L_i,i−1 from the off-diagonal outputs, then the diagonal.
        entries.extend(off.by_ref().take(i));
        entries.push(d);
    }
    assert_eq!(entries.len(), outputs(n), "n(n+1)/2 outputs for L");
    Tri { n, entries }
}
