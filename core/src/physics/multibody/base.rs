//! The base parameters of a robot (docs/robots.md#base-parameters; Gautier 1990): stack the
//! regressor Y at random states into W, factor W P = Q R with column pivoting, and take the
//! rank r from R's diagonal. The first r pivoted columns are independent; every other column
//! is a combination of them, W_d = W_b R₁⁻¹R₂, so τ = W_b β with
//!
//!     β = π_b + R₁⁻¹R₂ π_d:
//!
//! r combinations of the standard parameters that motion data determines (a dependent column
//! that is zero, a parameter τ never feels, appears in none).

use super::Model;
use super::regressor::regressor;
use crate::rng::Rng;

/// β = Σ coefficient · π_k over (k, coefficient) in k's order; the independent parameter's
/// coefficient is 1.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseParameter {
    /// The independent parameter (its regressor column is one of W_b's).
    pub lead: usize,
    pub terms: Vec<(usize, f64)>,
}

impl BaseParameter {
    pub fn value(&self, pi: &[f64]) -> f64 {
        self.terms.iter().map(|&(k, c)| c * pi[k]).sum()
    }
}

/// Rank threshold relative to R's largest diagonal entry: rounding in W (random states of
/// order 1, entries of order 10) is ~1e-15 of it, a real dependence is exactly 0, and a
/// parameter that matters is far above (a 1 mm lever on a 10 g link: ~1e-5).
const RANK_TOLERANCE: f64 = 1e-10;
/// Coefficients smaller than this are rounding of a zero.
const COEFFICIENT_ZERO: f64 = 1e-9;

/// The base parameters of `model`'s kinematics (its inertias are not read), from enough
/// random states (seeded: the same robot gives the same list).
pub fn base_parameters(model: &Model) -> Vec<BaseParameter> {
    let n = model.n;
    let cols = model.parameter_count();
    let states = (2 * cols).div_ceil(n.max(1)) + 8;
    let mut rng = Rng::new(1990);
    let mut w: Vec<Vec<f64>> = Vec::with_capacity(states * n);
    for _ in 0..states {
        let mut draw = || {
            (0..n)
                .map(|_| rng.uniform_in(-1.5, 1.5))
                .collect::<Vec<_>>()
        };
        let (q, qd, qdd) = (draw(), draw(), draw());
        w.extend(regressor(model, &q, &qd, &qdd));
    }
    let (r, perm) = pivoted_qr(&mut w, cols);
    let top = r.first().map_or(0.0, |row| row[0].abs());
    let rank = (0..r.len().min(cols))
        .take_while(|&i| r[i][i].abs() > RANK_TOLERANCE * top)
        .count();
    // R₁⁻¹R₂ column by column.
    let k: Vec<Vec<f64>> = (rank..cols).map(|d| back_substitute(&r, rank, d)).collect();
    let mut base: Vec<BaseParameter> = (0..rank)
        .map(|i| {
            let mut terms = vec![(perm[i], 1.0)];
            for (j, x) in k.iter().enumerate() {
                if x[i].abs() > COEFFICIENT_ZERO {
                    terms.push((perm[rank + j], x[i]));
                }
            }
            terms.sort_by_key(|&(k, _)| k);
            BaseParameter {
                lead: perm[i],
                terms,
            }
        })
        .collect();
    // Body by body from the root, as a person reads the robot.
    base.sort_by_key(|b| b.lead);
    base
}

/// x with R₁ x = R₂[:, d] (R₁ the leading `rank` block).
fn back_substitute(r: &[Vec<f64>], rank: usize, d: usize) -> Vec<f64> {
    let mut x = vec![0.0; rank];
    for i in (0..rank).rev() {
        let s: f64 = ((i + 1)..rank).map(|j| r[i][j] * x[j]).sum();
        x[i] = (r[i][d] - s) / r[i][i];
    }
    x
}

/// Householder QR with column pivoting of the rows `a` (`cols` wide), in place: R's rows
/// (the leading min(rows, cols)) and the permutation (R's column j is a's column perm[j]).
fn pivoted_qr(a: &mut [Vec<f64>], cols: usize) -> (Vec<Vec<f64>>, Vec<usize>) {
    let rows = a.len();
    let mut perm: Vec<usize> = (0..cols).collect();
    for k in 0..rows.min(cols) {
        // The remaining column of largest norm below row k (recomputed: cheap at this size).
        let norm = |j: usize, a: &[Vec<f64>]| (k..rows).map(|i| a[i][j] * a[i][j]).sum::<f64>();
        let p = (k..cols)
            .max_by(|&x, &y| norm(x, a).total_cmp(&norm(y, a)))
            .expect("k < cols");
        if p != k {
            perm.swap(k, p);
            for row in a.iter_mut() {
                row.swap(k, p);
            }
        }
        let alpha = norm(k, a).sqrt();
        if alpha == 0.0 {
            break;
        }
        let alpha = if a[k][k] > 0.0 { -alpha } else { alpha };
        let mut v: Vec<f64> = (k..rows).map(|i| a[i][k]).collect();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        if vv > 0.0 {
            // A ← (𝟙 − 2 v vᵀ / vᵀv) A on rows k.., columns k.., row by row.
            let mut s = vec![0.0; cols - k];
            for (vi, row) in v.iter().zip(&a[k..]) {
                s.iter_mut().zip(&row[k..]).for_each(|(s, x)| *s += vi * x);
            }
            let f = 2.0 / vv;
            for (vi, row) in v.iter().zip(&mut a[k..]) {
                row[k..]
                    .iter_mut()
                    .zip(&s)
                    .for_each(|(x, s)| *x -= f * s * vi);
            }
        }
    }
    (a[..rows.min(cols)].to_vec(), perm)
}
