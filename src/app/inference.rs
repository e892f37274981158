//! Inference on trained models for controllers (the gRPC adapter calls these): one-step
//! prediction, rollouts, linearizations and TVLQR, in f64 on the evaluator.
//!
//! Every call's cost is decided before it computes: its response must fit the message limit
//! and its memory (inputs, outputs, one chunk of intermediate work) the per-call budget, else
//! RESOURCE_EXHAUSTED. Calls beyond the inline small ones are "heavy": at most
//! `max_heavy_calls` compute at once on the blocking pool, the others wait (a bounded queue).

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use tokio::sync::{Semaphore, mpsc};

use super::App;
use crate::control::linalg::Mat;
use crate::control::policy::Policy;
use crate::error::{Error, Result};
use crate::infer::limits::Pass;
use crate::infer::{Evaluator, finite_rows};
use crate::train::artifact::ModelFile;

/// Loaded models by id, and the ids deleted while this process ran: a load that raced a
/// delete must not put the deleted model back (model ids are never reused, so the set only
/// grows by one id per deletion).
#[derive(Default)]
pub struct ModelCache {
    inner: Mutex<CacheState>,
}

#[derive(Default)]
struct CacheState {
    loaded: HashMap<String, Arc<Evaluator>>,
    deleted: HashSet<String>,
}

impl ModelCache {
    fn lock(&self) -> std::sync::MutexGuard<'_, CacheState> {
        self.inner.lock().expect("model cache lock")
    }

    fn get(&self, model_id: &str) -> Option<Arc<Evaluator>> {
        self.lock().loaded.get(model_id).cloned()
    }

    /// False when the model was deleted meanwhile.
    fn insert(&self, model_id: &str, eval: Arc<Evaluator>) -> bool {
        let mut c = self.lock();
        if c.deleted.contains(model_id) {
            return false;
        }
        c.loaded.insert(model_id.to_string(), eval);
        true
    }

    pub fn evict(&self, model_id: &str) {
        let mut c = self.lock();
        c.loaded.remove(model_id);
        c.deleted.insert(model_id.to_string());
    }

    pub fn cached_ids(&self) -> Vec<String> {
        self.lock().loaded.keys().cloned().collect()
    }
}

/// Heavy calls waiting per permit before further ones are refused: a queue, not a pile.
const WAITING_PER_PERMIT: usize = 16;

/// Admission of heavy inference work: `permits` compute at once, a bounded number wait.
/// Calls and rollout streams each have their own (see [`Heavy::streaming`]).
pub struct Heavy {
    permits: Arc<Semaphore>,
    waiting: AtomicUsize,
    max_waiting: usize,
}

/// Decrements the waiting count however the wait ends (a caller's deadline drops the future).
struct Waiting<'a>(&'a AtomicUsize);

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Heavy {
    /// A pool for calls: `permits` at once, a bounded queue behind them.
    pub fn new(permits: usize) -> Self {
        let permits = permits.max(1);
        Self {
            permits: Arc::new(Semaphore::new(permits)),
            waiting: AtomicUsize::new(0),
            max_waiting: permits * WAITING_PER_PERMIT,
        }
    }

    /// A pool for rollout streams: their chunks queue without a cap (a waiting stream is a
    /// parked task holding no thread, and streams are capped per connection), apart from
    /// calls, so that many streams cannot crowd Predict, Linearize or Tvlqr out.
    pub fn streaming(permits: usize) -> Self {
        Self {
            max_waiting: usize::MAX,
            ..Self::new(permits)
        }
    }

    /// Runs `f` on the blocking pool once a permit is free; the permit is held until `f`
    /// returns, even if the caller has gone.
    pub async fn run<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T> {
        if self.waiting.fetch_add(1, Ordering::SeqCst) >= self.max_waiting {
            self.waiting.fetch_sub(1, Ordering::SeqCst);
            return Err(Error::ResourceExhausted(format!(
                "{} heavy inference calls are already waiting; retry later (--max-heavy-calls)",
                self.max_waiting
            )));
        }
        let guard = Waiting(&self.waiting);
        let permit = self
            .permits
            .clone()
            .acquire_owned()
            .await
            .map_err(|_| Error::Internal("the inference pool is closed".into()))?;
        drop(guard);
        tokio::task::spawn_blocking(move || {
            let _permit = permit;
            f()
        })
        .await
        .map_err(|e| Error::Internal(format!("inference task failed: {e}")))
    }
}

/// A batch of rows: `rows` × `width`, row-major.
pub struct Rows {
    pub rows: usize,
}

/// Checks an array's shape and values; `field` names it in errors.
pub fn rows(field: &str, shape: &[u64], data: &[f64], width: usize) -> Result<Rows> {
    let [r, w] = shape else {
        return Err(Error::invalid(
            field,
            format!("shape must be [rows, {width}], got {shape:?}"),
        ));
    };
    // Checked: a client-supplied shape such as [2⁶³ + 1, 4] must not wrap around to match.
    let expected = usize::try_from(*r)
        .ok()
        .zip(usize::try_from(*w).ok())
        .and_then(|(r, w)| r.checked_mul(w));
    if *w != width as u64 || *r == 0 || expected != Some(data.len()) {
        return Err(Error::invalid(
            field,
            format!(
                "expected [rows ≥ 1, {width}] with rows·{width} values, got shape {shape:?} and {} values",
                data.len()
            ),
        ));
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(
            field,
            format!("row {} has a non-finite value", i / width),
        ));
    }
    Ok(Rows { rows: *r as usize })
}

fn square(field: &str, shape: &[u64], data: &[f64], dim: usize) -> Result<Mat> {
    let r = rows(field, shape, data, dim)?;
    if r.rows != dim {
        return Err(Error::invalid(field, format!("must be {dim}×{dim}")));
    }
    Ok(Mat::new(dim, dim, data.to_vec()))
}

/// A batch of states `[B, 2n]` and inputs `[B, m]` with the same B; returns B.
fn check_batch(eval: &Evaluator, x: (&[f64], &[u64]), u: (&[f64], &[u64])) -> Result<usize> {
    let xr = rows("x", x.1, x.0, 2 * eval.config.n)?.rows;
    let ur = rows("u", u.1, u.0, eval.config.m)?.rows;
    if xr != ur {
        return Err(Error::invalid("u", format!("has {ur} rows but x has {xr}")));
    }
    Ok(xr)
}

/// Up to this many states a Predict runs on the executor thread itself (≈ 15–20 µs a state;
/// one Linearize, also inline, ≈ 60 µs): a hop to the blocking pool and back costs more than
/// that (measured: a one-state Predict round trip went from ~250 to ~190 µs p50 inline, and
/// 64 concurrent clients from 10k to 16k requests/s).
const INLINE_ROWS: usize = 4;

/// How often a process checks that its cached models still exist: the documented bound on
/// how long a model deleted through another process on the same database is still served.
pub const CACHE_SWEEP: std::time::Duration = std::time::Duration::from_millis(500);

/// A Rollout chunk's bytes at most (states, inputs and z of one message): a stream whose
/// reader stalls holds one chunk in its channel and one being sent, so 600 stalled streams
/// stay within a few hundred MB.
const ROLLOUT_CHUNK_BYTES: usize = 256 << 10;

const MB: f64 = (1 << 20) as f64;

/// What a call will take, decided before it computes.
struct Cost {
    response_bytes: usize,
    memory_bytes: usize,
}

/// x' (and q̈ when asked) for a batch, with each row's distance from the training data.
pub struct Prediction {
    pub next: Vec<f64>,
    pub accel: Option<Vec<f64>>,
    pub max_abs_z: Vec<f64>,
}

/// A `[B, 2n, 2n]` and B `[B, 2n, m]`, row-major, with each row's distance from the data.
pub struct Linearization {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub max_abs_z: Vec<f64>,
}

/// An array as a request carries it: values and shape.
pub type Array = (Vec<f64>, Vec<u64>);

/// The inputs of a rollout as requested: a sequence `[T, m]`, or a feedback policy with
/// x̄ `[T or T+1, 2n]`, ū `[T, m]` and K `[T, m, 2n]`.
pub enum RolloutInputs {
    U(Array),
    Policy {
        x_bar: Array,
        u_bar: Array,
        k: Array,
    },
}

/// The inputs checked against the model.
enum Inputs {
    Open(Vec<f64>),
    Policy(Policy),
}

impl Inputs {
    /// The checked inputs and the number of steps T.
    fn check(req: RolloutInputs, nx: usize, m: usize) -> Result<(Self, usize)> {
        match req {
            RolloutInputs::U((u, shape)) => {
                let t = rows("u", &shape, &u, m)?.rows;
                Ok((Inputs::Open(u), t))
            }
            RolloutInputs::Policy { x_bar, u_bar, k } => {
                let t = rows("policy.u_bar", &u_bar.1, &u_bar.0, m)?.rows;
                let tx = rows("policy.x_bar", &x_bar.1, &x_bar.0, nx)?.rows;
                if tx != t && tx != t + 1 {
                    return Err(Error::invalid(
                        "policy.x_bar",
                        format!("needs T or T+1 rows for T = {t}, got {tx}"),
                    ));
                }
                let expected = [t as u64, m as u64, nx as u64];
                if k.1 != expected
                    || t.checked_mul(m * nx) != Some(k.0.len())
                    || k.0.iter().any(|v| !v.is_finite())
                {
                    return Err(Error::invalid(
                        "policy.k",
                        format!("must be {expected:?} finite values, got shape {:?}", k.1),
                    ));
                }
                let policy = Policy {
                    xbar: x_bar.0,
                    ubar: u_bar.0,
                    k: k.0,
                    nx,
                    m,
                };
                Ok((Inputs::Policy(policy), t))
            }
        }
    }
}

/// One streamed piece of a rollout: states from index `start` (x0 is state 0), the inputs
/// applied in it, and for each input the largest |z| of the (state, input) it was applied at.
pub struct RolloutChunk {
    pub start: usize,
    /// Widths of a state row and of an input row (2n, m).
    pub width: (usize, usize),
    pub x: Vec<f64>,
    pub u: Vec<f64>,
    pub max_abs_z: Vec<f64>,
}

impl App {
    /// The evaluator of a model (or of the model a succeeded job produced), loaded once. A
    /// cached model answers without touching the database: a control loop calls this at
    /// hundreds of hertz, and a SQLite round trip was most of a one-state Predict.
    pub async fn evaluator(&self, id: &str) -> Result<Arc<Evaluator>> {
        if let Some(e) = self.models.get(id) {
            return Ok(e);
        }
        let row = self.resolve_model(id).await?;
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

    /// RESOURCE_EXHAUSTED naming the limit when `cost` is over one, before any computing.
    fn admit(&self, what: &str, cost: &Cost) -> Result<()> {
        let s = &self.settings;
        if cost.response_bytes > s.grpc_max_message_bytes {
            return Err(Error::ResourceExhausted(format!(
                "{what}: the response would be {:.1} MB, over the message limit of {:.0} MB \
                 (--grpc-max-message-mb); send fewer states per call",
                cost.response_bytes as f64 / MB,
                s.grpc_max_message_bytes as f64 / MB
            )));
        }
        if cost.memory_bytes > s.max_call_memory_bytes {
            return Err(Error::ResourceExhausted(format!(
                "{what}: the call would take about {:.0} MB, over the per-call memory budget of \
                 {:.0} MB (--max-call-memory-mb); send fewer states per call",
                cost.memory_bytes as f64 / MB,
                s.max_call_memory_bytes as f64 / MB
            )));
        }
        Ok(())
    }

    /// `f` inline when the work is small (see [`INLINE_ROWS`]), else as a heavy call.
    async fn compute<T: Send + 'static>(
        &self,
        small: bool,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T> {
        if small {
            Ok(f())
        } else {
            self.heavy.run(f).await
        }
    }

    /// x' (and q̈ when asked) for a batch.
    pub async fn predict(
        &self,
        id: &str,
        x: (Vec<f64>, Vec<u64>),
        u: (Vec<f64>, Vec<u64>),
        want_accel: bool,
    ) -> Result<Prediction> {
        let eval = self.evaluator(id).await?;
        let b = check_batch(&eval, (&x.0, &x.1), (&u.0, &u.1))?;
        let (n, nx, m) = (eval.config.n, 2 * eval.config.n, eval.config.m);
        let response_bytes = 8 * b * (nx + 1 + if want_accel { n } else { 0 });
        let work = b.min(2 * eval.chunk_states(Pass::Step)) * eval.work_bytes_per_state(Pass::Step);
        self.admit(
            "x",
            &Cost {
                response_bytes,
                memory_bytes: 8 * b * (nx + m) + 2 * response_bytes + work,
            },
        )?;
        let (x, u) = (x.0, u.0);
        let out = self
            .compute(b <= INLINE_ROWS, move || {
                let (next, accel) = eval.predict(&x, &u, want_accel);
                let max_abs_z = eval.max_abs_z(&x, &u);
                Prediction {
                    next,
                    accel,
                    max_abs_z,
                }
            })
            .await?;
        finite_rows("x", "next state", &out.next, nx)?;
        Ok(out)
    }

    /// A and B for a batch, row-major `[B, 2n, 2n]` and `[B, 2n, m]`.
    pub async fn linearize(
        &self,
        id: &str,
        x: (Vec<f64>, Vec<u64>),
        u: (Vec<f64>, Vec<u64>),
    ) -> Result<Linearization> {
        let eval = self.evaluator(id).await?;
        let b = check_batch(&eval, (&x.0, &x.1), (&u.0, &u.1))?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let response_bytes = 8 * b * (nx * nx + nx * m + 1);
        let work = b.min(2 * eval.chunk_states(Pass::Linearize))
            * eval.work_bytes_per_state(Pass::Linearize);
        // The parts, their concatenation, A and B, and the encoded message.
        self.admit(
            "x",
            &Cost {
                response_bytes,
                memory_bytes: 8 * b * (nx + m) + 4 * response_bytes + work,
            },
        )?;
        let (x, u) = (x.0, u.0);
        let out = self
            .compute(b == 1, move || {
                let (a, bm) = eval.linearize_batch(&x, &u);
                Linearization {
                    a,
                    b: bm,
                    max_abs_z: eval.max_abs_z(&x, &u),
                }
            })
            .await?;
        finite_rows("x", "linearization", &out.a, nx * nx)?;
        finite_rows("x", "linearization", &out.b, nx * m)?;
        Ok(out)
    }

    /// TVLQR gains along a nominal (x̄, ū); defects are ignored. K `[T, m, 2n]`, S `[T+1, 2n, 2n]`.
    pub async fn tvlqr(
        &self,
        id: &str,
        xbar: (Vec<f64>, Vec<u64>),
        ubar: (Vec<f64>, Vec<u64>),
        weights: [(Vec<f64>, Vec<u64>); 3],
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let eval = self.evaluator(id).await?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let t_x = rows("x_bar", &xbar.1, &xbar.0, nx)?.rows;
        let t = rows("u_bar", &ubar.1, &ubar.0, m)?.rows;
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
            square("Q", &q.1, &q.0, nx)?,
            square("R", &r.1, &r.0, m)?,
            square("Qf", &qf.1, &qf.0, nx)?,
        );
        let (jac, gains) = (nx * nx + nx * m, m * nx + nx * nx);
        let response_bytes = 8 * (t * m * nx + (t + 1) * nx * nx);
        let work = t.min(2 * eval.chunk_states(Pass::Linearize))
            * eval.work_bytes_per_state(Pass::Linearize);
        // A and B as rows, as matrices and in the solver; S and K, then their message.
        self.admit(
            "u_bar",
            &Cost {
                response_bytes,
                memory_bytes: 8 * t * (4 * jac + 3 * gains) + work,
            },
        )?;
        self.heavy
            .run(move || {
                let g = eval.tvlqr(&xbar.0, &ubar.0, &qm, &rm, &qfm)?;
                Ok((
                    g.k.into_iter().flat_map(|k| k.data).collect(),
                    g.s.into_iter().flat_map(|s| s.data).collect(),
                ))
            })
            .await?
    }

    /// Checks a rollout and starts it: chunks arrive on the receiver as they are computed.
    /// Each chunk is computed as a heavy call and then sent without holding a thread, so a
    /// reader that stalls holds one chunk of memory and no thread; the rollout ends at the
    /// caller's deadline `until`, or when the receiver is dropped.
    pub async fn rollout(
        &self,
        id: &str,
        x0: Vec<f64>,
        inputs: RolloutInputs,
        chunk: usize,
        until: Option<Instant>,
    ) -> Result<mpsc::Receiver<Result<RolloutChunk>>> {
        let eval = self.evaluator(id).await?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        if x0.len() != nx || x0.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("x0", format!("must be {nx} finite values")));
        }
        let (inputs, steps) = Inputs::check(inputs, nx, m)?;
        let max = self.settings.max_rollout_steps;
        if steps > max {
            return Err(Error::ResourceExhausted(format!(
                "{steps} steps is over the limit of {max} (--max-rollout-steps)"
            )));
        }
        let row_bytes = 8 * (nx + m + 1);
        let chunk = if chunk == 0 { 1000 } else { chunk }.clamp(1, ROLLOUT_CHUNK_BYTES / row_bytes);
        self.admit(
            "chunk",
            &Cost {
                response_bytes: chunk * row_bytes,
                memory_bytes: 3 * chunk * row_bytes + eval.work_bytes_per_state(Pass::Step),
            },
        )?;
        let (tx, rx) = mpsc::channel(1);
        let app = self.clone();
        let job = Rollout {
            eval,
            inputs: Arc::new(inputs),
            steps,
            chunk,
        };
        tokio::spawn(async move { job.stream(&app, x0, tx, until).await });
        Ok(rx)
    }
}

struct Rollout {
    eval: Arc<Evaluator>,
    inputs: Arc<Inputs>,
    steps: usize,
    chunk: usize,
}

/// A computed piece: the chunk, the state to continue from, and the error that ended it.
type Piece = (RolloutChunk, Vec<f64>, Option<Error>);

impl Rollout {
    async fn stream(
        self,
        app: &App,
        x0: Vec<f64>,
        tx: mpsc::Sender<Result<RolloutChunk>>,
        until: Option<Instant>,
    ) {
        let stopped = || {
            app.telemetry
                .computations_stopped
                .fetch_add(1, Ordering::Relaxed)
        };
        let passed = || until.is_some_and(|d| Instant::now() > d);
        let (mut t, mut x) = (0, x0);
        while t < self.steps {
            if passed() || tx.is_closed() {
                stopped();
                let _ = tx.try_send(Err(deadline_passed()));
                return;
            }
            let first = t == 0;
            let take = (self.chunk - usize::from(first)).max(1).min(self.steps - t);
            let piece = {
                let (eval, inputs) = (self.eval.clone(), self.inputs.clone());
                let start = x.clone();
                app.streaming
                    .run(move || compute_piece(&eval, &inputs, start, t, take, first))
                    .await
            };
            let (chunk, last, error) = match piece {
                Ok(p) => p,
                Err(e) => {
                    let _ = tx.send(Err(e)).await;
                    return;
                }
            };
            let sent = if chunk.u.is_empty() {
                true
            } else {
                let send = tx.send(Ok(chunk));
                match until {
                    Some(d) => tokio::time::timeout_at(d.into(), send)
                        .await
                        .is_ok_and(|r| r.is_ok()),
                    None => send.await.is_ok(),
                }
            };
            if !sent {
                stopped();
                return;
            }
            if let Some(e) = error {
                let _ = tx.send(Err(e)).await;
                return;
            }
            t += take;
            x = last;
        }
    }
}

fn deadline_passed() -> Error {
    Error::DeadlineExceeded("the rollout passed its deadline".into())
}

/// `take` steps from state `x` at step `t` (the first piece also carries x0).
fn compute_piece(
    eval: &Evaluator,
    inputs: &Inputs,
    x: Vec<f64>,
    t: usize,
    take: usize,
    first: bool,
) -> Piece {
    let (nx, m) = (2 * eval.config.n, eval.config.m);
    let mut states = if first { x.clone() } else { vec![] };
    let (mut applied, mut from) = (Vec::with_capacity(take * m), Vec::with_capacity(take * nx));
    let mut last = x.clone();
    let mut error = None;
    let input = |s: usize, x: &[f64]| match inputs {
        Inputs::Open(u) => u[(t + s) * m..(t + s + 1) * m].to_vec(),
        Inputs::Policy(p) => p.input(t + s, x),
    };
    let mut done = 0;
    eval.rollout(&x, take, input, |next, u| {
        if next.iter().any(|v| !v.is_finite()) {
            error = Some(Error::invalid(
                "x0",
                format!(
                    "the state became non-finite at step {}: the trajectory left what the model can evaluate",
                    t + done + 1
                ),
            ));
            return false;
        }
        from.extend_from_slice(&last);
        applied.extend_from_slice(u);
        states.extend_from_slice(next);
        last = next.to_vec();
        done += 1;
        true
    });
    let max_abs_z = eval.max_abs_z(&from, &applied);
    let start = if first { 0 } else { t + 1 };
    (
        RolloutChunk {
            start,
            width: (nx, m),
            x: states,
            u: applied,
            max_abs_z,
        },
        last,
        error,
    )
}
