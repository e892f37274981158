//! Batched MLP evaluation with derivatives, as matrix products: the inference path's hot loop.
//!
//! [`Activations`] holds a batch's activations together with their derivatives in two sets of
//! directions: `inner` ones (∂/∂q, which M's Jacobian and ∇V need) and `outer` ones (∂/∂ε, the
//! directions a linearization differentiates in), plus the mixed second derivatives ∂²/∂q∂ε
//! (which is where ∂²M/∂q² and ∇²V come from). Every block is `[batch, width]` and a linear
//! layer is linear in all of them, so one matrix product `[blocks·batch, in] × [in, out]`
//! propagates everything; only the activation mixes blocks:
//!
//! ```text
//! h = tanh z,   s = 1 − h²,   s' = −2 h s
//! ∂h = s ∂z                        (first order, inner or outer)
//! ∂²h = s ∂²z + s' ∂_q z ∂_ε z     (mixed)
//! ```

use crate::arena::{AVec, Arena, zeros};
use crate::simd::{mad, multiversion, tanh_kernel};

/// Activations and derivatives of a batch: blocks `[outer + 1][inner + 1][batch][width]`,
/// block (0, 0) the values; in the call's arena.
#[derive(Debug, Clone)]
pub struct Activations<'a> {
    pub batch: usize,
    pub width: usize,
    pub inner: usize,
    pub outer: usize,
    pub data: AVec<'a, f64>,
}

impl<'a> Activations<'a> {
    pub fn zeros(a: &'a Arena, batch: usize, width: usize, inner: usize, outer: usize) -> Self {
        let len = (inner + 1) * (outer + 1) * batch * width;
        Self {
            batch,
            width,
            inner,
            outer,
            data: zeros(a, len),
        }
    }

    fn block_len(&self) -> usize {
        self.batch * self.width
    }

    fn offset(&self, o: usize, i: usize) -> usize {
        (o * (self.inner + 1) + i) * self.block_len()
    }

    /// Entry (sample b, unit j) of block (o, i).
    pub fn at(&self, o: usize, i: usize, b: usize, j: usize) -> f64 {
        self.data[self.offset(o, i) + b * self.width + j]
    }

    pub fn set(&mut self, o: usize, i: usize, b: usize, j: usize, v: f64) {
        let k = self.offset(o, i) + b * self.width + j;
        self.data[k] = v;
    }

    /// `self × W + b` (bias on the values only); W row-major `[width, out]`.
    pub fn linear(&self, a: &'a Arena, w: &[f64], bias: &[f64], out: usize) -> Activations<'a> {
        let mut z = Activations::zeros(a, self.batch, out, self.inner, self.outer);
        for r in 0..self.batch {
            z.data[r * out..(r + 1) * out].copy_from_slice(bias);
        }
        let mut narrow = zeros(a, (out % LANES) * self.width);
        matmul_acc(&self.data, w, &mut z.data, self.width, out, &mut narrow);
        z
    }

    /// tanh applied to the values, with the chain rule on every derivative block.
    pub fn tanh(&mut self, a: &Arena) {
        let len = self.block_len();
        let mut slope = zeros(a, if self.data.len() > len { len } else { 0 });
        activate(&mut self.data, len, self.inner, self.outer, &mut slope);
    }
}

multiversion! {
    /// c += a × w for row-major a `[rows, k]`, w `[k, out]`, c `[rows, out]`, in register
    /// tiles. The layers are narrow (k, out ≤ 64 typically): w stays in L1, so no packing,
    /// which dominated a single state's time with a general GEMM (and measured no faster than
    /// these tiles at 1024 states). `narrow`: room for the last `out % 8` columns of w,
    /// transposed (`(out % 8) · k`).
    fn matmul_acc(a: &[f64], w: &[f64], c: &mut [f64], k: usize, out: usize, narrow: &mut [f64]) => matmul_kernel
}

/// Doubles per vector in a register tile: one AVX-512 register, two AVX2 ones.
const LANES: usize = 8;
/// Rows per register tile. A tile of 4 rows × 2 vectors keeps 8 independent accumulator
/// chains (enough to hide the FMA latency) and feeds every loaded weight vector to 4 FMAs.
const TILE_ROWS: usize = 4;

#[inline(always)]
fn matmul_kernel<const FMA: bool>(
    a: &[f64],
    w: &[f64],
    c: &mut [f64],
    k: usize,
    out: usize,
    narrow: &mut [f64],
) {
    let rows = a.len() / k;
    let mut j0 = 0;
    while j0 + 2 * LANES <= out {
        column_block::<FMA, 2>(a, w, c, k, out, rows, j0);
        j0 += 2 * LANES;
    }
    if j0 + LANES <= out {
        column_block::<FMA, 1>(a, w, c, k, out, rows, j0);
        j0 += LANES;
    }
    if j0 < out {
        narrow_columns::<FMA>(a, w, c, k, out, j0, narrow);
    }
}

/// Columns j0 .. j0 + V·8 of every row: tiles of 4 rows, then the 1–3 rows left in one tile
/// (a single state's jet has 3 rows: values and two ∂/∂q blocks).
#[inline(always)]
fn column_block<const FMA: bool, const V: usize>(
    a: &[f64],
    w: &[f64],
    c: &mut [f64],
    k: usize,
    out: usize,
    rows: usize,
    j0: usize,
) {
    let mut r = 0;
    while r + TILE_ROWS <= rows {
        tile::<FMA, TILE_ROWS, V>(a, w, c, k, out, r, j0);
        r += TILE_ROWS;
    }
    match rows - r {
        1 => tile::<FMA, 1, V>(a, w, c, k, out, r, j0),
        2 => tile::<FMA, 2, V>(a, w, c, k, out, r, j0),
        3 => tile::<FMA, 3, V>(a, w, c, k, out, r, j0),
        _ => {}
    }
}

/// c[r..r+R, j0..j0+V·8] += a[r..r+R, :] × w[:, j0..j0+V·8], accumulating in registers.
#[inline(always)]
fn tile<const FMA: bool, const R: usize, const V: usize>(
    a: &[f64],
    w: &[f64],
    c: &mut [f64],
    k: usize,
    out: usize,
    r: usize,
    j0: usize,
) {
    let mut acc = [[[0.0; LANES]; V]; R];
    for (i, acc) in acc.iter_mut().enumerate() {
        for (v, acc) in acc.iter_mut().enumerate() {
            acc.copy_from_slice(&c[(r + i) * out + j0 + v * LANES..][..LANES]);
        }
    }
    let a = &a[r * k..(r + R) * k];
    for (kk, w) in w.chunks_exact(out).enumerate() {
        let w = &w[j0..j0 + V * LANES];
        for (i, acc) in acc.iter_mut().enumerate() {
            let x = a[i * k + kk];
            for (acc, w) in acc.iter_mut().zip(w.chunks_exact(LANES)) {
                for (c, &w) in acc.iter_mut().zip(w) {
                    *c = mad::<FMA>(x, w, *c);
                }
            }
        }
    }
    for (i, acc) in acc.iter().enumerate() {
        for (v, acc) in acc.iter().enumerate() {
            c[(r + i) * out + j0 + v * LANES..][..LANES].copy_from_slice(acc);
        }
    }
}

/// The last < 8 columns (an output layer: L's entries, V, F) as dot products over k, eight
/// partial sums at a time; a column-vector loop here would be one masked FMA per k.
#[inline(always)]
fn narrow_columns<const FMA: bool>(
    a: &[f64],
    w: &[f64],
    c: &mut [f64],
    k: usize,
    out: usize,
    j0: usize,
    wt: &mut [f64],
) {
    for (kk, w) in w.chunks_exact(out).enumerate() {
        for (j, &v) in w[j0..].iter().enumerate() {
            wt[j * k + kk] = v;
        }
    }
    for (row, c) in a.chunks_exact(k).zip(c.chunks_exact_mut(out)) {
        for (c, wt) in c[j0..].iter_mut().zip(wt.chunks_exact(k)) {
            let mut part = [0.0; LANES];
            let (xs, ws) = (row.chunks_exact(LANES), wt.chunks_exact(LANES));
            let tail: f64 = xs
                .remainder()
                .iter()
                .zip(ws.remainder())
                .map(|(x, w)| x * w)
                .sum();
            for (x, w) in xs.zip(ws) {
                for ((p, &x), &w) in part.iter_mut().zip(x).zip(w) {
                    *p = mad::<FMA>(x, w, *p);
                }
            }
            *c += part.iter().sum::<f64>() + tail;
        }
    }
}

multiversion! {
    /// The activation of a jet's buffer (blocks of `len`): see the module comment.
    /// `s`: room for the slope 1 − h² of every value (`len`) when there are derivatives.
    fn activate(data: &mut [f64], len: usize, ni: usize, no: usize, s: &mut [f64]) => activate_kernel
}

#[inline(always)]
fn activate_kernel<const FMA: bool>(
    data: &mut [f64],
    len: usize,
    ni: usize,
    no: usize,
    s: &mut [f64],
) {
    let (values, rest) = data.split_at_mut(len);
    tanh_kernel::<FMA>(values);
    if rest.is_empty() {
        return;
    }
    for (s, h) in s.iter_mut().zip(values.iter()) {
        *s = 1.0 - h * h;
    }
    // Mixed blocks first: they need the first-order blocks before those are scaled.
    for o in 1..=no {
        for i in 1..=ni {
            let k = o * (ni + 1) + i;
            let (head, tail) = rest.split_at_mut((k - 1) * len);
            let dzi = &head[(i - 1) * len..i * len];
            let dzo = &head[(o * (ni + 1) - 1) * len..o * (ni + 1) * len];
            for (t, d) in tail[..len].iter_mut().enumerate() {
                let sp = -2.0 * values[t] * s[t];
                *d = s[t] * *d + sp * dzi[t] * dzo[t];
            }
        }
    }
    for o in 0..=no {
        for i in 0..=ni {
            if (o == 0) == (i == 0) {
                continue; // the values, or a mixed block (done above)
            }
            let k = o * (ni + 1) + i;
            for (d, s) in rest[(k - 1) * len..k * len].iter_mut().zip(s.iter()) {
                *d *= s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiled_matmul_matches_the_triple_loop() {
        // Shapes that exercise full tiles, leftover rows (not a multiple of 6) and leftover
        // columns (not a multiple of 8). Sums of ≤ 40 products of O(1) terms: 1e-13 absolute
        // allows for the different summation order only.
        for (rows, k, out) in [(1, 3, 32), (7, 32, 32), (13, 5, 11), (64, 32, 1), (6, 8, 8)] {
            let a: Vec<f64> = (0..rows * k)
                .map(|i| ((i * 7 % 13) as f64 - 6.0) / 5.0)
                .collect();
            let w: Vec<f64> = (0..k * out)
                .map(|i| ((i * 5 % 11) as f64 - 5.0) / 4.0)
                .collect();
            let c0: Vec<f64> = (0..rows * out).map(|i| (i % 3) as f64).collect();
            let mut want = c0.clone();
            for r in 0..rows {
                for j in 0..out {
                    for kk in 0..k {
                        want[r * out + j] += a[r * k + kk] * w[kk * out + j];
                    }
                }
            }
            let mut got = c0;
            let mut narrow = vec![0.0; (out % LANES) * k];
            matmul_acc(&a, &w, &mut got, k, out, &mut narrow);
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() < 1e-13, "{rows}×{k}×{out}: {g} vs {w}");
            }
        }
    }

    #[test]
    fn jet_tanh_matches_nested_duals() {
        use crate::physics::dual::Dual;
        use crate::physics::scalar::Scalar;
        // z(q, ε) = a + b q + c ε + d q ε at one unit: the jet's blocks vs Dual<Dual<f64>>.
        let (a, b, c, d) = (0.3, -0.7, 1.1, 0.4);
        let arena = Arena::new();
        let mut jet = Activations::zeros(&arena, 1, 1, 1, 1);
        jet.set(0, 0, 0, 0, a);
        jet.set(0, 1, 0, 0, b);
        jet.set(1, 0, 0, 0, c);
        jet.set(1, 1, 0, 0, d);
        jet.tanh(&arena);
        let inner = |v: f64, dq: f64| -> Dual<f64> { Dual::new(v, vec![Some(dq)]) };
        let z: Dual<Dual<f64>> = Dual::new(inner(a, b), vec![Some(inner(c, d))]);
        let h = z.tanh();
        let outer = h.tangent(0).unwrap();
        let want = [
            h.v.v,
            *h.v.tangent(0).unwrap(),
            outer.v,
            *outer.tangent(0).unwrap(),
        ];
        let got = [
            jet.at(0, 0, 0, 0),
            jet.at(0, 1, 0, 0),
            jet.at(1, 0, 0, 0),
            jet.at(1, 1, 0, 0),
        ];
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-15, "{got:?} vs {want:?}");
        }
    }
}
