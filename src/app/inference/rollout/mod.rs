//! Rollouts: checked, then computed chunk by chunk as heavy work and streamed without holding
//! a thread, so that a reader that stalls costs one chunk of memory and nothing else.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use tokio::sync::mpsc;

mod particles;

use super::Cost;
use crate::app::App;
use crate::array::Array;
use crate::control::policy::Policy;
use crate::error::{Error, Result};
use crate::infer::Evaluator;
use crate::infer::limits::Pass;
use crate::infer::particles::{check_particles, diverged};
use crate::physics::space::Space;

/// A Rollout chunk's bytes at most (states, inputs and z of one message): a stream whose
/// reader stalls holds one chunk in its channel and one being sent, so 600 stalled streams
/// stay within a few hundred MB.
const ROLLOUT_CHUNK_BYTES: usize = 256 << 10;

pub use crate::infer::particles::MAX_PARTICLES;

/// Particle steps per computed piece at most: a piece of a many-particle rollout takes about
/// as long as a plain one's longest (the deadline and the reader are checked between pieces).
const PIECE_PARTICLE_STEPS: usize = 4096;

/// How a rollout streams: states per chunk (0: the default), the particles it propagates
/// (None: one rollout of the mean dynamics), and the seconds between states (None: the
/// model's Δt).
#[derive(Debug, Clone, Copy, Default)]
pub struct RolloutShape {
    pub chunk: usize,
    pub particles: Option<usize>,
    pub dt: Option<f64>,
}

/// The inputs of a rollout as requested: a sequence `[T, m]`, or a feedback policy with
/// x̄ `[T or T+1, nq + nv]`, ū `[T, m]` and K `[T, m, 2nv]`.
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
    fn check(req: RolloutInputs, space: &Space, m: usize) -> Result<(Self, usize)> {
        let (nx, ndx) = (space.nq() + space.nv(), 2 * space.nv());
        match req {
            RolloutInputs::U(u) => {
                let t = u.rows("u", m)?;
                Ok((Inputs::Open(u.data), t))
            }
            RolloutInputs::Policy { x_bar, u_bar, k } => {
                let t = u_bar.rows("policy.u_bar", m)?;
                let tx = x_bar.rows("policy.x_bar", nx)?;
                if tx != t && tx != t + 1 {
                    return Err(Error::invalid(
                        "policy.x_bar",
                        format!("needs T or T+1 rows for T = {t}, got {tx}"),
                    ));
                }
                let expected = [t as u64, m as u64, ndx as u64];
                if k.shape != expected
                    || t.checked_mul(m * ndx) != Some(k.data.len())
                    || k.data.iter().any(|v| !v.is_finite())
                {
                    return Err(Error::invalid(
                        "policy.k",
                        format!(
                            "must be {expected:?} finite values, got shape {:?}",
                            k.shape
                        ),
                    ));
                }
                let policy = Policy {
                    xbar: x_bar.data,
                    ubar: u_bar.data,
                    k: k.data,
                    space: space.clone(),
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
    /// States `[S, nq + nv]`.
    pub x: Array,
    /// Inputs `[T, m]`.
    pub u: Array,
    /// T values.
    pub max_abs_z: Vec<f64>,
    /// With particles: their standard deviation per coordinate `[S, nq + nv]` (`x` is their mean).
    pub x_std: Option<Array>,
}

impl App {
    /// Checks a rollout and starts it: chunks arrive on the receiver as they are computed.
    /// Each chunk is computed as a heavy call and then sent without holding a thread, so a
    /// reader that stalls holds one chunk of memory and no thread; the rollout ends at the
    /// caller's deadline `until`, or when the receiver is dropped.
    pub async fn rollout(
        &self,
        id: &str,
        x0: Vec<f64>,
        inputs: RolloutInputs,
        shape: RolloutShape,
        until: Option<Instant>,
    ) -> Result<mpsc::Receiver<Result<RolloutChunk>>> {
        if let Some(p) = shape.particles {
            check_particles(p)?;
        }
        let eval = self.evaluator(id).await?;
        let dt = eval.step_seconds(shape.dt)?;
        let (nx, m) = (eval.config.nx(), eval.config.m);
        if x0.len() != nx || x0.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("x0", format!("must be {nx} finite values")));
        }
        let (inputs, steps) = Inputs::check(inputs, &eval.config.space, m)?;
        let max = self.settings.max_rollout_steps;
        if steps > max {
            return Err(Error::ResourceExhausted(format!(
                "{steps} steps is over the limit of {max} (--max-rollout-steps)"
            )));
        }
        let particles = shape.particles.unwrap_or(0);
        // A state's mean and spread, its input and z; with particles, a step's states too.
        let row_bytes = 8 * (nx + m + 1 + if particles > 0 { nx } else { 0 });
        let chunk = shape.chunk;
        let mut chunk =
            if chunk == 0 { 1000 } else { chunk }.clamp(1, ROLLOUT_CHUNK_BYTES / row_bytes);
        if let Some(steps) = PIECE_PARTICLE_STEPS.checked_div(particles) {
            chunk = chunk.min(steps.max(1));
        }
        let particle_bytes = 8 * particles * (3 * nx + 2 * m + 1);
        self.admit(
            "chunk",
            &Cost {
                response_bytes: chunk * row_bytes,
                memory_bytes: 3 * chunk * row_bytes
                    + particle_bytes
                    + eval.work_bytes_per_state(Pass::Step) * particles.max(1),
            },
        )?;
        let (tx, rx) = mpsc::channel(1);
        let app = self.clone();
        let job = Rollout {
            eval,
            inputs: Arc::new(inputs),
            steps,
            dt,
            chunk,
            particles,
        };
        // Every particle starts at x0.
        let x0 = x0.repeat(particles.max(1));
        tokio::spawn(async move { job.stream(&app, x0, tx, until).await });
        Ok(rx)
    }
}

struct Rollout {
    eval: Arc<Evaluator>,
    inputs: Arc<Inputs>,
    steps: usize,
    /// Seconds between states.
    dt: f64,
    chunk: usize,
    /// 0: one rollout of the mean dynamics.
    particles: usize,
}

/// A computed piece: the chunk, the state to continue from, and the error that ended it.
type Piece = (RolloutChunk, Vec<f64>, Option<Error>);

/// A piece's first step, its steps and their seconds.
type Span = (usize, usize, f64);

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
                let (particles, span) = (self.particles, (t, take, self.dt));
                app.streaming
                    .run(move || match particles {
                        0 => compute_piece(&eval, &inputs, start, span, first),
                        _ => particles::piece(&eval, &inputs, start, span, first),
                    })
                    .await
            };
            let (chunk, last, error) = match piece {
                Ok(p) => p,
                Err(e) => {
                    let _ = tx.send(Err(e)).await;
                    return;
                }
            };
            let sent = if chunk.u.data.is_empty() {
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

/// The input of step `t` at state `x`.
fn input_at(inputs: &Inputs, m: usize, t: usize, x: &[f64]) -> Vec<f64> {
    match inputs {
        Inputs::Open(u) => u[t * m..(t + 1) * m].to_vec(),
        Inputs::Policy(p) => p.input(t, x),
    }
}

/// `take` steps of `dt` from state `x` at step `t` (the first piece also carries x0).
fn compute_piece(
    eval: &Evaluator,
    inputs: &Inputs,
    x: Vec<f64>,
    (t, take, dt): Span,
    first: bool,
) -> Piece {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    let mut states = if first { x.clone() } else { vec![] };
    let (mut applied, mut from) = (Vec::with_capacity(take * m), Vec::with_capacity(take * nx));
    let mut last = x.clone();
    let mut error = None;
    let input = |s: usize, x: &[f64]| input_at(inputs, m, t + s, x);
    let mut done = 0;
    eval.rollout(&x, (take, dt), input, |next, u| {
        if next.iter().any(|v| !v.is_finite()) {
            error = Some(diverged(t + done + 1));
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
            x: Array::new(&[states.len() / nx, nx], states),
            u: Array::new(&[done, m], applied),
            max_abs_z,
            x_std: None,
        },
        last,
        error,
    )
}
