//! What a call costs before it runs, and how far its inputs lie from the training data.
//!
//! The service refuses a call whose memory would exceed its budget *before* computing
//! (hardening: a 10⁶-state Linearize once took the server past 12 GB), and runs accepted
//! batches in chunks whose intermediate work fits a fixed size, so a large batch costs its
//! inputs and outputs plus one chunk's work, not the whole batch's work at once.

use super::{Evaluator, Mlp64};
use crate::control::plan::{EnsembleCost, Method, PlanRequest};
use crate::error::{Error, Result};

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
        // The tangent's width stands for n: what the structure's matrices and directions are.
        let (n, m) = (self.config.nv(), self.config.m);
        let outer = match pass {
            Pass::Step => 0,
            Pass::Linearize => 2 * n + m,
        };
        let lanes = (n + 1) * (outer + 1);
        let nets: usize = self
            .weights
            .networks()
            .map(|net| 3 * net.widest() * lanes)
            .sum();
        let structure = 4 * (n * (n + 1) / 2 + 4 * n * n + n * m) * lanes;
        2 * 8 * (nets + structure)
    }

    /// States per chunk of a batch in `pass` (at least one).
    pub fn chunk_states(&self, pass: Pass) -> usize {
        (CHUNK_WORK_BYTES / self.work_bytes_per_state(pass).max(1)).max(1)
    }

    /// Per row of `[B, nq + nv]` states and `[B, m]` inputs, the largest |z-score| of q, q̇ and u
    /// under the training data's statistics: how far outside the data the model is asked to
    /// answer (a network saturates there and its outputs are finite but meaningless).
    pub fn max_abs_z(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        self.max_abs_z_rows(x, u).collect()
    }

    /// [`Evaluator::max_abs_z`] into the caller's `[B]` buffer.
    pub fn max_abs_z_into(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        out.iter_mut()
            .zip(self.max_abs_z_rows(x, u))
            .for_each(|(o, z)| *o = z);
    }

    fn max_abs_z_rows<'x>(&'x self, x: &'x [f64], u: &'x [f64]) -> impl Iterator<Item = f64> + 'x {
        let (nq, nv, m) = (self.config.nq(), self.config.nv(), self.config.m);
        let s = &self.config.scaling;
        let z = |v: f64, mean: f64, std: f64| ((v - mean) / std).abs();
        // Rows by index, not `u.chunks(m)`: a model without inputs has empty rows of u.
        x.chunks(nq + nv)
            .enumerate()
            .map_while(move |(b, x)| Some((x, u.get(b * m..(b + 1) * m)?)))
            .map(move |(x, u)| {
                let q = (0..nq).map(|i| z(x[i], s.q_mean[i], s.q_std[i]));
                let qd = (0..nv).map(|i| z(x[nq + i], s.qdot_mean[i], s.qdot_std[i]));
                let uz = (0..m).map(|i| z(u[i], s.u_mean[i], s.u_std[i]));
                q.chain(qd).chain(uz).fold(0.0, f64::max)
            })
    }
}

/// The service's default per-call memory budget (`--max-call-memory-mb`), which the Python
/// module's own budget starts at: a call the service refuses is refused in process too.
pub const DEFAULT_MAX_CALL_MEMORY_MB: usize = 512;

const MB: f64 = (1 << 20) as f64;

/// The way out of a batch too large for a budget.
const FEWER_STATES: &str = "send fewer states per call";

/// What a call will take, decided before it computes (one estimate for the service, which
/// also bounds the response's message, and the in-process callers), with the argument that
/// decides it and how to ask for less.
#[derive(Debug, Clone)]
pub struct Cost {
    /// The argument whose size is at fault when the call is over a limit.
    pub field: &'static str,
    /// How to ask for less, for the refusal.
    pub way_out: String,
    pub response_bytes: usize,
    pub memory_bytes: usize,
}

impl Cost {
    /// RESOURCE_EXHAUSTED naming the field, the budget of `budget` bytes (`knob`: where it is
    /// set) and the way out when the call's memory is over it.
    pub fn within(&self, budget: usize, knob: &str) -> Result<()> {
        if self.memory_bytes <= budget {
            return Ok(());
        }
        Err(Error::ResourceExhausted(format!(
            "{}: the call would take about {:.0} MB, over the per-call memory budget of {:.0} \
             MB ({knob}); {}",
            self.field,
            self.memory_bytes as f64 / MB,
            budget as f64 / MB,
            self.way_out
        )))
    }
}

/// The estimates of the batched calls and plans.
impl Evaluator {
    /// What an ensemble holds of its members' answers, `bytes` each, until their mean is taken
    /// (nothing for a single model).
    pub fn members_held(&self, bytes: usize) -> usize {
        match self.member_count() {
            1 => 0,
            k => k.saturating_mul(bytes),
        }
    }

    /// x' (and q̈ with `accel`) for `b` states; with `members`, every member's x' as well.
    pub fn predict_cost(&self, b: usize, accel: bool, members: bool) -> Cost {
        let (n, nx, m) = (self.config.nv(), self.config.nx(), self.config.m);
        let k = self.member_count();
        // x' (and its σ), q̈, max |z|; every member's x' when asked.
        let states = 1 + usize::from(k > 1 || members) + if members { k } else { 0 };
        let accel = if accel { n } else { 0 };
        let response_bytes = 8 * b * (states * nx + 1 + accel);
        let work = b.min(2 * self.chunk_states(Pass::Step)) * self.work_bytes_per_state(Pass::Step);
        // Every member's answers are held until their mean is taken.
        let held = self.members_held(8 * b * (nx + accel));
        Cost {
            field: "x",
            way_out: FEWER_STATES.into(),
            response_bytes,
            memory_bytes: 8 * b * (nx + m) + 2 * response_bytes + held + work,
        }
    }

    /// A and B at `b` states.
    pub fn linearize_cost(&self, b: usize) -> Cost {
        let (nx, m) = (self.config.ndx(), self.config.m);
        let response_bytes = 8 * b * (nx * nx + nx * m + 1);
        let work = b.min(2 * self.chunk_states(Pass::Linearize))
            * self.work_bytes_per_state(Pass::Linearize);
        // The parts, their concatenation, A and B, and the encoded message (and an
        // ensemble's members' A and B until their mean is taken).
        let held = self.members_held(8 * b * (nx * nx + nx * m));
        Cost {
            field: "x",
            way_out: FEWER_STATES.into(),
            response_bytes,
            memory_bytes: 8 * b * (nx + m) + 4 * response_bytes + work + held,
        }
    }

    /// The energies of `b` states (`energy::energy_until`): T, V, E and the power, then the
    /// four terms and F's named parts, n each.
    pub fn energy_cost(&self, b: usize) -> Cost {
        let (n, m, k) = (self.config.nv(), self.config.m, self.member_count());
        let parts = self.force_part_count();
        let response_bytes = 8 * b * (4 + n * (4 + parts));
        // The inputs, the answer's arrays and its message; each member's row of one state
        // until their mean is taken.
        let row = 8 * (k + 1) * n * (4 + parts);
        Cost {
            field: "x",
            way_out: FEWER_STATES.into(),
            response_bytes,
            memory_bytes: 8 * b * (self.config.nx() + m) + 2 * response_bytes + row,
        }
    }

    /// TVLQR's gains along a nominal of `t` steps.
    pub fn tvlqr_cost(&self, t: usize) -> Cost {
        let (nx, m) = (self.config.ndx(), self.config.m);
        let (jac, gains) = (nx * nx + nx * m, m * nx + nx * nx);
        let work = t.min(2 * self.chunk_states(Pass::Linearize))
            * self.work_bytes_per_state(Pass::Linearize);
        // A and B as rows, as matrices and in the solver; S and K, then their message.
        Cost {
            field: "u_bar",
            way_out: "send a shorter nominal trajectory".into(),
            response_bytes: 8 * (t * m * nx + (t + 1) * nx * nx),
            memory_bytes: 8 * t * (4 * jac + 3 * gains) + work + self.members_held(8 * t * jac),
        }
    }

    /// A rollout of `steps` kept whole (the in-process callers' answer; the service streams
    /// it in chunks): its inputs (a policy's nominal and gains with `policy`), states and
    /// applied inputs.
    pub fn rollout_cost(&self, steps: usize, policy: bool) -> Cost {
        let (nx, m) = (self.config.nx(), self.config.m);
        let given = if policy { nx + m + m * nx } else { m };
        let response_bytes = 8 * ((steps + 1) * nx + steps * m);
        Cost {
            field: if policy { "policy" } else { "u" },
            way_out: "roll out fewer steps per call".into(),
            response_bytes,
            memory_bytes: 8 * steps * given
                + response_bytes
                + self.work_bytes_per_state(Pass::Step) * self.member_count(),
        }
    }

    /// A particle rollout of `steps` kept whole (`particles::particle_rollout`): its inputs,
    /// the particles' states, inputs and z of one step (what the service's pieces hold too),
    /// one step's work for every particle, and the answer: the mean and spread of every
    /// state, the mean inputs and z.
    pub fn particle_rollout_cost(&self, steps: usize, particles: usize, policy: bool) -> Cost {
        let (nx, m) = (self.config.nx(), self.config.m);
        let given = if policy { nx + m + m * nx } else { m };
        let response_bytes = 8 * (2 * (steps + 1) * nx + steps * (m + 1));
        let per_steps = 8 * steps * given + response_bytes;
        let per_particles = 8 * particles * (3 * nx + 2 * m + 1)
            + self.work_bytes_per_state(Pass::Step) * particles;
        // The larger share names the argument to cut.
        let (field, way_out) = match (per_steps >= per_particles, policy) {
            (true, true) => ("policy", "roll out fewer steps per call"),
            (true, false) => ("u", "roll out fewer steps per call"),
            (false, _) => ("particles", "propagate fewer particles"),
        };
        Cost {
            field,
            way_out: way_out.into(),
            response_bytes,
            memory_bytes: per_steps + per_particles,
        }
    }

    /// A plan of the request's horizon, method and ensemble cost (the request validated).
    pub fn plan_cost(&self, req: &PlanRequest) -> Cost {
        let t = req.horizon;
        let (nx, m) = (self.config.nx(), self.config.m);
        // The members' average cost plans on all of them stacked: K·nx states.
        let k = self.member_count();
        let stacked = k > 1 && req.ensemble_cost == EnsembleCost::Mean;
        let nx = if stacked { k * nx } else { nx };
        // Jacobians, the backward pass's matrices and gains, the line search's ten
        // trajectories, the best start's, the returned plan and its message. Restarts add
        // time, not memory (one start is kept besides the current one); the time is the
        // deadline's to bound, which the solver checks at every time step.
        let per_step = match req.method {
            Method::Ilqr => 8 * (4 * (nx * nx + nx * m) + 11 * (nx + m) + 2 * m * nx),
            Method::Dircol => dircol_bytes_per_interval(nx, m),
        };
        let iterations = req.max_iterations.saturating_add(1);
        let memory_bytes = t * per_step
            + t.min(2 * self.chunk_states(Pass::Linearize))
                * self.work_bytes_per_state(Pass::Linearize)
            + self.members_held(8 * (t + 1) * (nx * nx + nx * m));
        let step_mb = per_step as f64 / MB;
        let way_out = if stacked {
            format!(
                "plan a shorter horizon (about {step_mb:.1} MB a step), or with ensemble_cost \
                 \"mean_dynamics\": the mean cost (\"mean\") plans all {k} members' states at \
                 once, {k} times the states of one"
            )
        } else {
            format!("plan a shorter horizon (about {step_mb:.2} MB a step)")
        };
        Cost {
            field: "horizon",
            way_out,
            response_bytes: 8usize
                .saturating_mul((t + 1) * nx + t * m + t * m * nx)
                .saturating_add(8usize.saturating_mul(iterations)),
            memory_bytes,
        }
    }
}

/// Direct collocation's memory per interval, all of which lives until the plan is answered:
/// f's Jacobians at three points, the defect Jacobian as triplets (this iterate's and the
/// last's), the learned curvature's block, the QP's matrices in clarabel (P and A, A's
/// scaled copy) and its KKT system with the factor's fill (about twice the band of one
/// interval's rows: variables, defects, bounds), and the interior point's ~20 vectors.
/// Measured on the double pendulum: a peak of 146 MB at T = 4000, 36.5 KB an interval; this
/// gives 38 KB there.
fn dircol_bytes_per_interval(nx: usize, m: usize) -> usize {
    let jacobian = nx * (5 * nx + 2 * m + 1);
    let (block, kkt) = (3 * nx + m, 4 * nx + 3 * m);
    8 * 3 * (nx * nx + nx * m)
        + 2 * 24 * jacobian
        + 8 * block * block
        + 12 * (block * block + 2 * jacobian)
        + 16 * 3 * kkt * kkt
        + 8 * 20 * kkt
}
