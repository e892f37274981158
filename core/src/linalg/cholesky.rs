//! L Lᵀ = A for a symmetric positive-definite A, and the triangular solves with L: the one
//! implementation behind the multibody workspace (`Data::factor`, `Data::solve`), the
//! manipulator equation (`dynamics::cholesky`, `solve_llt`), control (`Mat::cholesky`,
//! `cholesky_solve`) and the stiffness check. Loops over slices, generic over [`Scalar`]:
//! for f64 they monomorphise to plain loops and allocate nothing.
//!
//! Only A's lower triangle is read and only L's lower triangle is written, so an n×n buffer
//! keeps whatever its upper triangle held. L is laid out [`Square`] (n×n row-major) or
//! [`Packed`] (its lower triangle row by row, `dynamics::Tri`'s order).
//!
//! Every entry computed is a − Σₖ xₖ yₖ, and how that sum is rounded is the one thing the
//! callers did differently before they shared this code. Each keeps its [`Order`]: another
//! would move its answers in the last bits, and recorded answers pin them to the bit
//! (tests/fixtures/inference/answers.json).

use crate::physics::scalar::Scalar;

/// How a − Σₖ tₖ is rounded.
pub trait Order: Copy {
    /// a − Σ `terms`, the terms in the order given.
    fn minus<S: Scalar>(self, a: S, terms: impl Iterator<Item = S>) -> S;

    /// Each column c of `row`: row_c − Σₖ lₖ rₖ_c over the (lₖ, rₖ) of `terms`, rounded as
    /// `minus` rounds it.
    #[inline]
    fn minus_rows<'r, S: Scalar + 'r>(
        self,
        row: &mut [S],
        terms: impl Iterator<Item = (&'r S, &'r [S])> + Clone,
    ) {
        for (c, x) in row.iter_mut().enumerate() {
            let products = terms.clone().map(|(l, r)| l.clone() * r[c].clone());
            *x = self.minus(x.clone(), products);
        }
    }
}

/// ((a − t₀) − t₁) − …: the multibody workspace's order, which [`factor`] and [`solve`] use.
#[derive(Debug, Clone, Copy)]
pub struct Running;

impl Order for Running {
    #[inline]
    fn minus<S: Scalar>(self, a: S, terms: impl Iterator<Item = S>) -> S {
        terms.fold(a, |s, t| s - t)
    }

    /// Per column the same arithmetic as `minus`. One column is one running sum, kept in a
    /// register rather than stored back once per term (twice as fast as the loop below);
    /// several go term by term over whole rows, an inner loop along contiguous columns that
    /// vectorises, where a multi-column solve (the derivatives' M⁻¹ of a block) spends its time.
    #[inline]
    fn minus_rows<'r, S: Scalar + 'r>(
        self,
        row: &mut [S],
        terms: impl Iterator<Item = (&'r S, &'r [S])> + Clone,
    ) {
        if let [x] = row {
            *x = terms.fold(x.clone(), |s, (l, r)| s - l.clone() * r[0].clone());
            return;
        }
        for (l, r) in terms {
            (row.iter_mut().zip(r)).for_each(|(x, p)| *x = x.clone() - l.clone() * p.clone());
        }
    }
}

/// a − ((t₀ + t₁) + …), and a itself when there are no terms: the manipulator equation's
/// order (`dynamics::cholesky`, `solve_llt`), which learned models train and answer with.
#[derive(Debug, Clone, Copy)]
pub struct Summed;

impl Order for Summed {
    #[inline]
    fn minus<S: Scalar>(self, a: S, terms: impl Iterator<Item = S>) -> S {
        match terms.reduce(|s, t| s + t) {
            Some(t) => a - t,
            None => a,
        }
    }
}

/// [`Summed`] with the sum started at −0.0, as f64's `Iterator::sum` starts it: with no terms
/// a − (−0.0) = a + 0.0, which turns a −0.0 into +0.0 and changes nothing else. The f64
/// code that summed with `sum()` (control, the stiffness check) keeps its answers to the bit.
#[derive(Debug, Clone, Copy)]
pub struct StdSum;

impl Order for StdSum {
    #[inline]
    fn minus<S: Scalar>(self, a: S, terms: impl Iterator<Item = S>) -> S {
        match terms.reduce(|s, t| s + t) {
            Some(t) => a - t,
            None => a.shift(0.0),
        }
    }
}

/// Where L's entries sit in a slice: row i's lower part, (i, 0) … (i, i), is contiguous.
pub trait Layout: Copy {
    /// The order n of the matrix.
    fn n(self) -> usize;
    /// The index of entry (i, 0).
    fn row(self, i: usize) -> usize;
}

/// n×n row-major: entry (i, j) at i n + j.
#[derive(Debug, Clone, Copy)]
pub struct Square(pub usize);

impl Layout for Square {
    #[inline]
    fn n(self) -> usize {
        self.0
    }
    #[inline]
    fn row(self, i: usize) -> usize {
        i * self.0
    }
}

/// The lower triangle row by row, (0,0), (1,0), (1,1), (2,0), …: n(n+1)/2 entries.
#[derive(Debug, Clone, Copy)]
pub struct Packed(pub usize);

impl Layout for Packed {
    #[inline]
    fn n(self) -> usize {
        self.0
    }
    #[inline]
    fn row(self, i: usize) -> usize {
        i * (i + 1) / 2
    }
}

/// L Lᵀ = A for n×n row-major `a` and `l` in the [`Running`] order. Where A is not positive
/// definite, the failing pivot's square root (NaN, or 0 and then ±∞ after it) runs on into
/// what depends on it; [`factor_checked`] reports it instead.
pub fn factor<S: Scalar>(a: &[S], n: usize, l: &mut [S]) {
    let unchecked = factor_by(l, Square(n), Running, |_, k| a[k].clone(), |_| true);
    debug_assert!(unchecked.is_ok());
}

/// L Lᵀ = A for n×n row-major `a` and `l` in `order`, or the index of the first pivot that
/// is not positive and finite (A is not positive definite from that row on; L's columns
/// before it are written).
pub fn factor_checked(a: &[f64], n: usize, l: &mut [f64], order: impl Order) -> Result<(), usize> {
    factor_by(
        l,
        Square(n),
        order,
        |_, k| a[k],
        |&d| d > 0.0 && d.is_finite(),
    )
}

/// [`factor_checked`] of a square matrix given by its rows, in the [`StdSum`] order of the f64
/// code that factored such matrices; L n×n row-major, zero above its diagonal.
pub fn factor_rows(m: &[Vec<f64>]) -> Result<Vec<f64>, usize> {
    let n = m.len();
    let a: Vec<f64> = m.iter().flat_map(|row| &row[..n]).copied().collect();
    let mut l = vec![0.0; n * n];
    factor_checked(&a, n, &mut l, StdSum)?;
    Ok(l)
}

/// L Lᵀ = A in place: on entry the lower triangle of `l`, laid out as `layout`, holds A's.
/// Not positive definite: as [`factor`].
pub fn factor_in_place<S: Scalar>(l: &mut [S], layout: impl Layout, order: impl Order) {
    let unchecked = factor_by(l, layout, order, |l, k| l[k].clone(), |_| true);
    debug_assert!(unchecked.is_ok());
}

/// The factorisation: `a(l, k)` is A's entry at index k of `layout` (read from `l` itself when
/// factoring in place: an entry is overwritten only once it has been read), and the first
/// pivot that `admits` refuses ends it. Column by column, L's entries as the manipulator
/// equation always built them: the tape accumulates a shared value's gradient in
/// the order its uses were recorded, so this order keeps training's gradients
/// as they were (an entry's own arithmetic does not depend on it).
#[inline]
fn factor_by<S: Scalar>(
    l: &mut [S],
    layout: impl Layout,
    order: impl Order,
    a: impl Fn(&[S], usize) -> S,
    admits: impl Fn(&S) -> bool,
) -> Result<(), usize> {
    let n = layout.n();
    for j in 0..n {
        let rj = layout.row(j);
        let d = order.minus(a(l, rj + j), l[rj..rj + j].iter().map(S::square));
        if !admits(&d) {
            return Err(j);
        }
        l[rj + j] = d.sqrt();
        for i in j + 1..n {
            let ri = layout.row(i);
            let products =
                (l[ri..ri + j].iter().zip(&l[rj..rj + j])).map(|(x, y)| x.clone() * y.clone());
            let s = order.minus(a(l, ri + j), products);
            l[ri + j] = s / l[rj + j].clone();
        }
    }
    Ok(())
}

/// x ← (L Lᵀ)⁻¹ x for an n×cols row-major block (each column a right-hand side), L n×n
/// row-major, in the [`Running`] order.
pub fn solve<S: Scalar>(l: &[S], n: usize, x: &mut [S], cols: usize) {
    solve_by(l, Square(n), x, cols, Running);
}

/// x ← (L Lᵀ)⁻¹ x for an n×cols row-major block, L laid out as `layout`.
pub fn solve_by<S: Scalar>(
    l: &[S],
    layout: impl Layout,
    x: &mut [S],
    cols: usize,
    order: impl Order,
) {
    forward(l, layout, x, cols, order);
    back(l, layout, x, cols, order);
}

/// x ← L⁻¹ x for an n×cols row-major block: row i is (x_i − Σ_{k<i} l_ik x_k) / l_ii.
pub fn forward<S: Scalar>(
    l: &[S],
    layout: impl Layout,
    x: &mut [S],
    cols: usize,
    order: impl Order,
) {
    if cols == 0 {
        return;
    }
    for i in 0..layout.n() {
        let at = layout.row(i);
        let (done, rest) = x.split_at_mut(i * cols);
        let row = &mut rest[..cols];
        order.minus_rows(row, l[at..at + i].iter().zip(done.chunks_exact(cols)));
        divide(row, &l[at + i]);
    }
}

/// x ← L⁻ᵀ x for an n×cols row-major block: from the last row up, row i is
/// (x_i − Σ_{k>i} l_ki x_k) / l_ii.
pub fn back<S: Scalar>(l: &[S], layout: impl Layout, x: &mut [S], cols: usize, order: impl Order) {
    if cols == 0 {
        return;
    }
    let n = layout.n();
    for i in (0..n).rev() {
        let (head, after) = x.split_at_mut((i + 1) * cols);
        let row = &mut head[i * cols..];
        let column = (i + 1..n).map(|k| &l[layout.row(k) + i]);
        order.minus_rows(row, column.zip(after.chunks_exact(cols)));
        divide(row, &l[layout.row(i) + i]);
    }
}

#[inline]
fn divide<S: Scalar>(row: &mut [S], d: &S) {
    row.iter_mut().for_each(|x| *x = x.clone() / d.clone());
}

#[cfg(test)]
#[path = "cholesky_tests.rs"]
mod tests;
