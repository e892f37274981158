//! Particle rollouts (TS∞, Chua et al. 2018): P particles start at x0 and particle p follows
//! member p mod K for the whole rollout, under the inputs (or a policy applied to its own
//! state). What streams is each step's mean over the particles and their spread. A single
//! model's particles all follow it, with zero spread.

use super::{Inputs, Piece, RolloutChunk, diverged, input_at};
use crate::array::Array;
use crate::infer::Evaluator;
use crate::model::report::Spread;

/// `take` steps of every particle from their states `xs` `[P, 2n]` at step `t` (the first
/// piece also carries x0's row); the piece continues from the particles' states.
pub(super) fn piece(
    eval: &Evaluator,
    inputs: &Inputs,
    xs: Vec<f64>,
    t: usize,
    take: usize,
    first: bool,
) -> Piece {
    let (nx, m) = (2 * eval.config.n, eval.config.m);
    let mut out = Stats::default();
    if first {
        out.push(&xs, nx);
    }
    let (mut applied, mut z) = (Vec::with_capacity(take * m), Vec::with_capacity(take));
    let (mut xs, mut error) = (xs, None);
    for s in 0..take {
        let us: Vec<f64> = (xs.chunks(nx))
            .flat_map(|x| input_at(inputs, m, t, s, x))
            .collect();
        let next = step(eval, &xs, &us);
        if next.iter().any(|v| !v.is_finite()) {
            error = Some(diverged(t + s + 1));
            break;
        }
        let zs = eval.max_abs_z(&xs, &us);
        z.push(zs.into_iter().fold(0.0, f64::max));
        applied.extend(column_means(&us, m));
        out.push(&next, nx);
        xs = next;
    }
    let rows = out.mean.len() / nx;
    let chunk = RolloutChunk {
        start: if first { 0 } else { t + 1 },
        x: Array::new(&[rows, nx], out.mean),
        u: Array::new(&[z.len(), m], applied),
        max_abs_z: z,
        x_std: Some(Array::new(&[rows, nx], out.std)),
    };
    (chunk, xs, error)
}

/// One step of every particle: those of one member as one batch on that member.
fn step(eval: &Evaluator, xs: &[f64], us: &[f64]) -> Vec<f64> {
    let (nx, m) = (2 * eval.config.n, eval.config.m);
    let (p, k) = (xs.len() / nx, eval.member_count());
    let mut next = vec![0.0; xs.len()];
    for member in 0..k.min(p) {
        let rows: Vec<usize> = (member..p).step_by(k).collect();
        let x: Vec<f64> = rows
            .iter()
            .flat_map(|&r| &xs[r * nx..(r + 1) * nx])
            .copied()
            .collect();
        let u: Vec<f64> = rows
            .iter()
            .flat_map(|&r| &us[r * m..(r + 1) * m])
            .copied()
            .collect();
        let (y, _) = eval.member(member).predict(&x, &u, false);
        for (&r, y) in rows.iter().zip(y.chunks(nx)) {
            next[r * nx..(r + 1) * nx].copy_from_slice(y);
        }
    }
    next
}

/// Each column's mean over the rows of a `[P, w]` array.
fn column_means(a: &[f64], w: usize) -> Vec<f64> {
    (0..w)
        .map(|j| Spread::of(&a.iter().skip(j).step_by(w).copied().collect::<Vec<_>>()).mean)
        .collect()
}

/// The particles' mean and standard deviation per coordinate, step after step.
#[derive(Default)]
struct Stats {
    mean: Vec<f64>,
    std: Vec<f64>,
}

impl Stats {
    fn push(&mut self, xs: &[f64], nx: usize) {
        for j in 0..nx {
            let column: Vec<f64> = xs.iter().skip(j).step_by(nx).copied().collect();
            let s = Spread::of(&column);
            self.mean.push(s.mean);
            self.std.push(s.std);
        }
    }
}
