//! A piece of a particle rollout as a streamed chunk: the computation is the core's
//! (`infer::particles`), continued piece after piece from the particles' states.

use super::{Inputs, Piece, RolloutChunk, Span, input_at};
use crate::array::Array;
use crate::infer::Evaluator;
use crate::infer::particles::{ParticleTrack, advance};

/// `take` steps of `dt` of every particle from their states `xs` `[P, nq + nv]` at step `t` (the first
/// piece also carries x0's row); the piece continues from the particles' states.
pub(super) fn piece(
    eval: &Evaluator,
    inputs: &Inputs,
    xs: Vec<f64>,
    (t, take, dt): Span,
    first: bool,
) -> Piece {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    let mut track = ParticleTrack::default();
    if first {
        track.push_states(&xs, nx);
    }
    let mut xs = xs;
    let input = |step: usize, x: &[f64]| input_at(inputs, m, step, x);
    // The deadline and the reader are checked between pieces, never inside one.
    let error = advance(eval, &mut xs, t, (take, dt), input, &mut track, &|| false).err();
    let rows = track.mean.len() / nx;
    let chunk = RolloutChunk {
        start: if first { 0 } else { t + 1 },
        x: Array::new(&[rows, nx], track.mean),
        u: Array::new(&[track.max_abs_z.len(), m], track.u),
        max_abs_z: track.max_abs_z,
        x_std: Some(Array::new(&[rows, nx], track.std)),
    };
    (chunk, xs, error)
}
