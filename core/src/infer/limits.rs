//! What a call costs before it runs, and how far its inputs lie from the training data.
//!
//! The service refuses a call whose memory would exceed its budget *before* computing
//! (hardening: a 10⁶-state Linearize once took the server past 12 GB), and runs accepted
//! batches in chunks whose intermediate work fits a fixed size, so a large batch costs its
//! inputs and outputs plus one chunk's work, not the whole batch's work at once.

use super::{Evaluator, Mlp64};

/// Intermediate work one chunk of a batch may take (per thread; a chunk splits over two).
pub const CHUNK_WORK_BYTES: usize = 32 << 20;

/// Which pass a batch goes through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pass {
    /// One step (Predict, Rollout): values and ∂/∂q where the structure needs them.
    Step,
    /// One step with 2n + m dual directions (Linearize, Tvlqr).
    Linearize,
}

impl Mlp64 {
    /// Units of the widest layer, inputs and outputs included.
    fn widest(&self) -> usize {
        self.layers
            .iter()
            .map(|(d_in, d_out, _, _)| (*d_in).max(*d_out))
            .max()
            .unwrap_or(0)
    }
}

impl Evaluator {
    /// An upper estimate of the bytes of intermediate work one state costs in a pass: every
    /// network's live jets (a layer's input and output and the activation's scratch: three
    /// widest layers, each with its derivative blocks) plus the structure's dual numbers (the
    /// Cholesky factor with its q-derivatives, the Coriolis products, the solve), each counted
    /// four times for the RK4 stages' live copies, then doubled for allocator slack.
    pub fn work_bytes_per_state(&self, pass: Pass) -> usize {
        let (n, m) = (self.config.n, self.config.m);
        let outer = match pass {
            Pass::Step => 0,
            Pass::Linearize => 2 * n + m,
        };
        let lanes = (n + 1) * (outer + 1);
        let nets: usize = self
            .weights
            .networks()
            .into_iter()
            .map(|net| 3 * net.widest() * lanes)
            .sum();
        let structure = 4 * (n * (n + 1) / 2 + 4 * n * n + n * m) * lanes;
        2 * 8 * (nets + structure)
    }

    /// States per chunk of a batch in `pass` (at least one).
    pub fn chunk_states(&self, pass: Pass) -> usize {
        (CHUNK_WORK_BYTES / self.work_bytes_per_state(pass).max(1)).max(1)
    }

    /// Per row of `[B, 2n]` states and `[B, m]` inputs, the largest |z-score| of q, q̇ and u
    /// under the training data's statistics: how far outside the data the model is asked to
    /// answer (a network saturates there and its outputs are finite but meaningless).
    pub fn max_abs_z(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        let (n, m) = (self.config.n, self.config.m);
        let s = &self.config.scaling;
        let z = |v: f64, mean: f64, std: f64| ((v - mean) / std).abs();
        x.chunks(2 * n)
            .zip(u.chunks(m))
            .map(|(x, u)| {
                let q = (0..n).map(|i| z(x[i], s.q_mean[i], s.q_std[i]));
                let qd = (0..n).map(|i| z(x[n + i], s.qdot_mean[i], s.qdot_std[i]));
                let uz = (0..m).map(|i| z(u[i], s.u_mean[i], s.u_std[i]));
                q.chain(qd).chain(uz).fold(0.0, f64::max)
            })
            .collect()
    }
}
