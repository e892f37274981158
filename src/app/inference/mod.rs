//! Inference on trained models for controllers (the gRPC adapter calls these): one-step
//! prediction, rollouts, linearizations and TVLQR, in f64 on the evaluator.
//!
//! Every call's cost is decided before it computes: its response must fit the message limit
//! and its memory (inputs, outputs, one chunk of intermediate work) the per-call budget, else
//! RESOURCE_EXHAUSTED. Calls beyond the inline small ones are "heavy" (see [`admission`]).

mod admission;
mod cache;
mod energy;
mod energy_report;
mod evaluate;
mod inverse;
mod json;
mod plan;
pub mod reads;
mod replay;
mod rollout;

pub use admission::{Class, Heavy, SHORT_EVALUATIONS};
pub use cache::{CACHE_SWEEP, ModelCache};
pub use energy::{Energy, EnergyRequest, EnergyView, ForcePartView};
pub use energy_report::EnergyReportRequest;
pub use evaluate::{EvaluateRequest, Evaluation};
pub use inverse::{InverseRequest, InverseView};
pub use json::{PredictRequest, PredictView, SimulateRequest, SimulateView};
pub use replay::{ParticleSeries, Replay, Series, TrajectoryItem, TrajectoryList};
pub use rollout::{MAX_PARTICLES, RolloutChunk, RolloutInputs, RolloutShape};

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use super::App;
use crate::array::Array;
use crate::control::linalg::Mat;
use crate::error::{Error, Result};
use crate::infer::limits::Cost as CallCost;
use crate::infer::{Evaluator, finite_rows};
use crate::model::file::ModelFile;

/// A batch of states `[B, nq + nv]` and inputs `[B, m]` with the same B; returns B.
fn check_batch(eval: &Evaluator, x: &Array, u: &Array) -> Result<usize> {
    let xr = x.rows("x", eval.config.nx())?;
    let ur = u.rows("u", eval.config.m)?;
    if xr != ur {
        return Err(Error::invalid("u", format!("has {ur} rows but x has {xr}")));
    }
    Ok(xr)
}

/// A `dim × dim` matrix; `field` names it in errors.
fn square(field: &str, a: Array, dim: usize) -> Result<Mat> {
    let rows = a.rows(field, dim)?;
    if rows != dim {
        let what = match field {
            "R" => " (m × m: a weight on the inputs u)",
            _ => " (2nv × 2nv: a weight on the state's deviation x ⊖ x̄ = [δq, δv])",
        };
        return Err(Error::invalid(field, format!("must be {dim}×{dim}{what}")));
    }
    Ok(Mat::new(dim, dim, a.data))
}

/// Up to this many states a Predict runs on the executor thread itself (≈ 15–20 µs a state;
/// one Linearize, also inline, ≈ 60 µs): a hop to the blocking pool and back costs more than
/// that (measured: a one-state Predict round trip went from ~250 to ~190 µs p50 inline, and
/// 64 concurrent clients from 10k to 16k requests/s).
const INLINE_ROWS: usize = 4;

const MB: f64 = (1 << 20) as f64;

/// What a call the core does not estimate will take (`infer::limits` estimates the rest),
/// decided before it computes.
struct Cost {
    response_bytes: usize,
    memory_bytes: usize,
}

/// What a Predict asks for besides x': q̈, an ensemble's every member's x', and a step of
/// its own (None: the model's Δt).
#[derive(Debug, Clone, Copy, Default)]
pub struct Want {
    pub accel: bool,
    pub members: bool,
    pub dt: Option<f64>,
}

/// x' `[B, nq + nv]` (and v̇ `[B, nv]` when asked) for a batch, with each row's distance from the
/// training data. An ensemble's are the members' means, with their spread.
pub struct Prediction {
    pub next: Array,
    pub accel: Option<Array>,
    pub max_abs_z: Vec<f64>,
    /// An ensemble's (or when members were asked for): the members' standard deviation of
    /// x' per coordinate `[B, nq + nv]` (0 for a single model).
    pub std: Option<Array>,
    /// When asked for: every member's x' `[K, B, nq + nv]`.
    pub members: Option<Array>,
    /// K: 1 for a single model.
    pub member_count: usize,
}

impl Prediction {
    /// `b` states of `nx` values and accelerations of `nv`.
    fn of(
        b: usize,
        (nx, nv): (usize, usize),
        next: Vec<f64>,
        accel: Option<Vec<f64>>,
        z: Vec<f64>,
    ) -> Self {
        Self {
            next: Array::new(&[b, nx], next),
            accel: accel.map(|a| Array::new(&[b, nv], a)),
            max_abs_z: z,
            std: None,
            members: None,
            member_count: 1,
        }
    }
}

/// A `[B, 2nv, 2nv]` and B `[B, 2nv, m]` (the tangent space), with each row's distance from
/// the data.
pub struct Linearization {
    pub a: Array,
    pub b: Array,
    pub max_abs_z: Vec<f64>,
}

/// TVLQR along a nominal of T steps: the gains K `[T, m, 2nv]` and the cost-to-go S
/// `[T+1, 2nv, 2nv]`.
pub struct TvlqrGains {
    pub k: Array,
    pub s: Array,
}

/// Sets the flag when dropped: the caller went away (its future was dropped), so the
/// computation stops at its next check.
struct Gone(Arc<AtomicBool>);

impl Drop for Gone {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

impl App {
    /// The evaluator of a model (or of the model a succeeded job produced), loaded once. A
    /// cached model answers without touching the database: a control loop calls this at
    /// hundreds of hertz, and a SQLite round trip was most of a one-state Predict.
    pub async fn evaluator(&self, id: &str) -> Result<Arc<Evaluator>> {
        if let Some(e) = self.models.get(id) {
            return Ok(e);
        }
        let row = self.resolve_model_row(id).await?;
        if let Some(e) = self.models.get(&row.id) {
            return Ok(e);
        }
        let bytes = self.model_file(&row.id).await?;
        let eval = Arc::new(
            tokio::task::spawn_blocking(move || {
                Evaluator::from_file(&ModelFile::from_bytes(&bytes)?)
            })
            .await
            .map_err(|e| Error::Internal(format!("model load failed: {e}")))??,
        );
        if !self.models.insert(&row.id, eval.clone()) {
            return Err(Error::NotFound(format!("model {}", row.id)));
        }
        Ok(eval)
    }

    pub async fn delete_model(&self, id: &str) -> Result<()> {
        self.store.delete_model(id).await?;
        self.models.evict(id);
        Ok(())
    }

    /// Evicts cached models another process deleted (they share the database); run every
    /// [`CACHE_SWEEP`], so a deletion elsewhere stops serving here within
    /// that bound, with no store query on the Predict path.
    pub async fn sweep_model_cache(&self) -> Result<()> {
        let cached = self.models.cached_ids();
        if cached.is_empty() {
            return Ok(());
        }
        let existing = self.store.existing_models(&cached).await?;
        for id in cached.iter().filter(|id| !existing.contains(*id)) {
            self.models.evict(id);
        }
        Ok(())
    }

    /// RESOURCE_EXHAUSTED naming the limit when `cost` is over one, before any computing:
    /// for a call of the service's own, whose way out is fewer states.
    fn admit(&self, what: &'static str, cost: &Cost) -> Result<()> {
        self.admit_call(&CallCost {
            field: what,
            way_out: "send fewer states per call".into(),
            response_bytes: cost.response_bytes,
            memory_bytes: cost.memory_bytes,
        })
    }

    /// RESOURCE_EXHAUSTED naming the limit, the field and the way out (a plan's is its
    /// horizon, not its states) when `cost` is over a limit, before any computing.
    fn admit_call(&self, cost: &CallCost) -> Result<()> {
        let s = &self.settings;
        if cost.response_bytes > s.grpc_max_message_bytes() {
            return Err(Error::ResourceExhausted(format!(
                "{}: the response would be {:.1} MB, over the message limit of {:.0} MB \
                 (--grpc-max-message-mb); {}",
                cost.field,
                cost.response_bytes as f64 / MB,
                s.grpc_max_message_bytes() as f64 / MB,
                cost.way_out
            )));
        }
        cost.within(s.max_call_memory_bytes(), "--max-call-memory-mb")
    }

    /// `f` inline when the work is small (see [`INLINE_ROWS`]), else as a heavy call of its
    /// class that stops at the deadline (see [`App::heavy_until`]).
    async fn compute<T: Send + 'static>(
        &self,
        class: Class,
        what: &str,
        deadline: Option<Instant>,
        f: impl FnOnce(&dyn Fn() -> bool) -> Option<T> + Send + 'static,
    ) -> Result<T> {
        match class {
            Class::Inline => {
                f(&|| false).ok_or_else(|| Error::Internal(format!("the {what} stopped by itself")))
            }
            _ => {
                self.heavy_until(class, what, deadline, |stop| f(stop))
                    .await
            }
        }
    }

    /// The pool a call of `class` computes in.
    fn pool(&self, class: Class) -> &Heavy {
        match class {
            Class::Short => &self.short_calls,
            Class::Inline | Class::Long => &self.long_calls,
        }
    }

    /// `f` as a heavy call, given a `stop` that turns true at the caller's deadline or when
    /// the caller goes away; `f` returns `None` when it stopped. A computation that never
    /// asked once held its permit long after its caller had given up, so every loop a request
    /// drives polls it. The answer leaves at the deadline, not at `f`'s next check. `stop` is
    /// `Sync` so that a solver running code of its own may poll it from a second thread.
    async fn heavy_until<T: Send + 'static>(
        &self,
        class: Class,
        what: &str,
        deadline: Option<Instant>,
        f: impl FnOnce(&(dyn Fn() -> bool + Sync)) -> Option<T> + Send + 'static,
    ) -> Result<T> {
        let gone = Arc::new(AtomicBool::new(false));
        let _guard = Gone(gone.clone());
        let work = self.pool(class).run(move || {
            let stop =
                || gone.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d);
            f(&stop)
        });
        let passed = || Error::DeadlineExceeded(format!("the {what} passed its deadline"));
        let done = match deadline {
            Some(d) => tokio::time::timeout_at(d.into(), work)
                .await
                .map_err(|_| passed())??,
            None => work.await?,
        };
        done.ok_or_else(passed)
    }

    /// x' (and v̇ when asked) for a batch.
    pub async fn predict(
        &self,
        id: &str,
        x: Array,
        u: Array,
        want: Want,
        deadline: Option<Instant>,
    ) -> Result<Prediction> {
        let eval = self.evaluator(id).await?;
        let b = check_batch(&eval, &x, &u)?;
        let dt = eval.step_seconds(want.dt)?;
        let (n, nx) = (eval.config.nv(), eval.config.nx());
        let k = eval.member_count();
        let spread = k > 1 || want.members;
        self.admit_call(&eval.predict_cost(b, want.accel, want.members))?;
        let (x, u) = (x.data, u.data);
        let class = Class::of(b * k <= INLINE_ROWS, b * k);
        let out = self
            .compute(class, "prediction", deadline, move |stop| {
                let max_abs_z = eval.max_abs_z(&x, &u);
                if !spread {
                    let (next, accel) = eval.predict_until(&x, &u, dt, want.accel, stop)?;
                    return Some(Prediction::of(b, (nx, n), next, accel, max_abs_z));
                }
                let p = eval.predict_members_until(&x, &u, dt, want.accel, stop)?;
                let mut out = Prediction::of(b, (nx, n), p.mean, p.accel, max_abs_z);
                out.member_count = k;
                out.std = Some(Array::new(&[b, nx], p.std));
                out.members = (want.members).then(|| Array::new(&[k, b, nx], p.next.concat()));
                Some(out)
            })
            .await?;
        finite_rows("x", "next state", &out.next.data, nx)?;
        Ok(out)
    }

    /// A and B for a batch in the tangent space, row-major `[B, 2nv, 2nv]` and `[B, 2nv, m]`.
    pub async fn linearize(
        &self,
        id: &str,
        x: Array,
        u: Array,
        deadline: Option<Instant>,
    ) -> Result<Linearization> {
        let eval = self.evaluator(id).await?;
        let b = check_batch(&eval, &x, &u)?;
        let (nx, m) = (eval.config.ndx(), eval.config.m);
        self.admit_call(&eval.linearize_cost(b))?;
        let (x, u) = (x.data, u.data);
        let rows = b * eval.member_count();
        let class = Class::of(rows == 1, rows * (nx + m + 1));
        let out = self
            .compute(class, "linearization", deadline, move |stop| {
                let (a, bm) = eval.linearize_until(&x, &u, stop)?;
                Some(Linearization {
                    a: Array::new(&[b, nx, nx], a),
                    b: Array::new(&[b, nx, m], bm),
                    max_abs_z: eval.max_abs_z(&x, &u),
                })
            })
            .await?;
        finite_rows("x", "linearization", &out.a.data, nx * nx)?;
        finite_rows("x", "linearization", &out.b.data, nx * m)?;
        Ok(out)
    }

    /// TVLQR gains along a nominal (x̄, ū) on tangent-space deviations; defects are ignored.
    /// K `[T, m, 2nv]`, S `[T+1, 2nv, 2nv]`.
    pub async fn tvlqr(
        &self,
        id: &str,
        xbar: Array,
        ubar: Array,
        weights: [Array; 3],
        deadline: Option<Instant>,
    ) -> Result<TvlqrGains> {
        let eval = self.evaluator(id).await?;
        let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
        let t_x = xbar.rows("x_bar", nx)?;
        let t = ubar.rows("u_bar", m)?;
        if t_x != t + 1 {
            return Err(Error::invalid(
                "x_bar",
                format!("needs T+1 = {} states for T = {t} inputs, got {t_x}", t + 1),
            ));
        }
        if t > self.settings.max_rollout_steps {
            return Err(Error::ResourceExhausted(format!(
                "horizon {t} is over the limit of {} (--max-rollout-steps)",
                self.settings.max_rollout_steps
            )));
        }
        let [q, r, qf] = weights;
        let (qm, rm, qfm) = (
            square("Q", q, ndx)?,
            square("R", r, m)?,
            square("Qf", qf, ndx)?,
        );
        self.admit_call(&eval.tvlqr_cost(t))?;
        let class = Class::of(false, t * eval.member_count() * (ndx + m + 1));
        self.heavy_until(class, "tvlqr", deadline, move |stop| {
            match eval.tvlqr_until(&xbar.data, &ubar.data, [&qm, &rm, &qfm], stop) {
                Err(Error::Cancelled) => None,
                Err(e) => Some(Err(e)),
                Ok(g) => Some(Ok(TvlqrGains {
                    k: Mat::stack(g.k),
                    s: Mat::stack(g.s),
                })),
            }
        })
        .await?
    }
}
