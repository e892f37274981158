//! What a training job will cost, estimated from its spec and data sizes before it is queued:
//! the service refuses a job over its limits at submission instead of discovering it at
//! 12 GB in epoch 0.

use crate::model::spec::ModelSpec;
use crate::physics::mass_matrix;
use crate::physics::params::Part;
use crate::physics::parts::{ForceSpec, MassSpec, PotentialSpec};

/// The largest blob SQLite stores (SQLITE_MAX_LENGTH, 10⁹ bytes by default), less a margin
/// for the row around it.
pub const STORE_MAX_BLOB: usize = 900_000_000;

/// Bytes a checkpoint takes per trainable parameter: parameters, Adam's two moments and the
/// best parameters so far, as JSON numbers of up to ~24 characters each.
const CHECKPOINT_BYTES_PER_PARAM: usize = 4 * 25;

/// Tensors autodiff keeps per layer unit and derivative block in one integrator stage (the
/// linear output, the activation and its derivative, the Jacobian products), measured within
/// this factor on the paper's MVF.
const TAPE_TENSORS: usize = 8;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JobEstimate {
    /// Trainable parameters.
    pub params: usize,
    /// Peak memory of the training process for this job, bytes.
    pub peak_bytes: usize,
    /// The checkpoint's size, bytes.
    pub checkpoint_bytes: usize,
    /// Of `peak_bytes`, the data's, which an ensemble's members share.
    pub data_bytes: usize,
}

impl JobEstimate {
    /// The cost of an ensemble of `members` such models trained on the same data: each
    /// member's tape, parameters and checkpoint, the data once. (Members side by side keep
    /// as many tapes live as there are threads; counting every member's keeps the limit
    /// independent of the worker that claims the job.)
    pub fn of_members(self, members: usize) -> Self {
        let own = self.peak_bytes.saturating_sub(self.data_bytes);
        Self {
            params: self.params,
            peak_bytes: own.saturating_mul(members).saturating_add(self.data_bytes),
            checkpoint_bytes: self.checkpoint_bytes.saturating_mul(members),
            data_bytes: self.data_bytes,
        }
    }
}

/// A network's (parameters, Σ layer widths) for `d_in` → `hidden` → `d_out`.
fn mlp(d_in: usize, hidden: &[usize], d_out: usize) -> (usize, usize) {
    let widths: Vec<usize> = std::iter::once(d_in)
        .chain(hidden.iter().copied())
        .chain(std::iter::once(d_out))
        .collect();
    let params = widths.windows(2).map(|w| w[0] * w[1] + w[1]).sum();
    (params, widths.iter().sum())
}

/// The sizes a job's networks follow from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    pub n: usize,
    pub m: usize,
    /// Network inputs from q beyond one per velocity: an angle's (sin q, cos q) and a
    /// rotation's (cos θ, sin θ) are one input more each.
    pub angles: usize,
}

/// (params, widths × derivative blocks) per component; M's and V's networks carry their n
/// q-derivatives (Coriolis term, ∇V), the others only values.
fn components(spec: &ModelSpec, d: Dims, physical: usize) -> Vec<(usize, usize)> {
    let Dims { n, m, angles } = d;
    let q_in = n + angles;
    let tri = mass_matrix::outputs(n);
    let with_grad = |(p, w): (usize, usize)| (p, w.saturating_mul(n + 1));
    let (mass, potential, forces) = match spec {
        ModelSpec::Naive { hidden } => return vec![mlp(q_in + n + m, hidden, n)],
        ModelSpec::Structured {
            mass,
            potential,
            forces,
            ..
        } => (mass, potential, forces),
    };
    let mass = match mass {
        MassSpec::Mlp { hidden } => with_grad(mlp(q_in, hidden, tri)),
        MassSpec::Constant => (tri, 0),
        MassSpec::Template => (0, 0),
    };
    let potential = match (potential.network(), potential) {
        (Some(hidden), _) => with_grad(mlp(q_in, hidden, 1)),
        (None, PotentialSpec::Quadratic) => (tri, 0),
        (None, _) => (0, 0),
    };
    let forces = match (forces.network(), forces) {
        (Some(hidden), _) => mlp(q_in + n + m, hidden, n),
        (None, ForceSpec::ControlAffine { hidden }) => {
            let (p, w) = mlp(q_in, hidden, n * m);
            (p + n, w)
        }
        (None, ForceSpec::ConstantAffine) => (n * m + n, 0),
        (None, ForceSpec::Passive { hidden }) => {
            let (pb, wb) = mlp(q_in, hidden, n * m);
            let (pd, wd) = mlp(q_in + n, hidden, tri);
            (pb + pd, wb + wd)
        }
        (None, _) => (0, 0),
    };
    vec![mass, potential, forces, (physical, 0)]
}

/// The job's cost with `batch` samples per step, `samples` transitions held (training and
/// validation) and `physical` template parameters. Saturating arithmetic: absurd specs
/// estimate as `usize::MAX`, never wrap.
pub fn estimate(
    spec: &ModelSpec,
    dims: Dims,
    batch: usize,
    samples: usize,
    physical: usize,
) -> JobEstimate {
    let Dims { n, m, .. } = dims;
    let parts = components(spec, dims, physical);
    let params = parts.iter().fold(0usize, |a, p| a.saturating_add(p.0));
    // A formula template's programs run on every sample: M's and V's with their n
    // q-derivatives (dual numbers), F's on values.
    let formula = spec.template().map_or(0, |t| {
        spec.white_box_parts().into_iter().fold(0usize, |a, part| {
            let blocks = if part == Part::Forces { 1 } else { n + 1 };
            a.saturating_add(t.nodes(part).saturating_mul(blocks))
        })
    });
    let units = parts.iter().fold(formula, |a, p| a.saturating_add(p.1));
    // The structure per sample: L and ∂L/∂q, the Coriolis products and the solve.
    let structure = n.saturating_pow(3).saturating_add(8 * n * n + n * m);
    let per_sample = units
        .saturating_add(structure)
        .saturating_mul(TAPE_TENSORS * 4 * 4); // × RK4 stages × f32 bytes
    // Host f64 arrays and their f32 device copies.
    let data = samples.saturating_mul(4 * n + m).saturating_mul(8 + 4 * 2);
    // Parameters, gradients, two Adam moments, the best copy, f64 exports.
    let state = params.saturating_mul(4 * 6 + 8 * 2);
    JobEstimate {
        params,
        peak_bytes: batch
            .saturating_mul(per_sample)
            .saturating_add(data)
            .saturating_add(state),
        checkpoint_bytes: params.saturating_mul(CHECKPOINT_BYTES_PER_PARAM),
        data_bytes: data,
    }
}
