//! The caller's scratch for the evaluator's calls (MuJoCo's `mjData`, Pinocchio's `Data`):
//! an [`Arena`] every intermediate vector of a call lives in, emptied at the start of each
//! unit of work (one state, or one chunk of a batch), and the buffer an ensemble's members
//! write into before their mean. Sized once per model and largest batch
//! ([`Workspace::for_model`]), a call reaches the system allocator no more.
//!
//! The `_into` entry points write into the caller's buffers; the batched `Vec` entry points
//! (`calls.rs`) are wrappers over them with this thread's workspace.

use std::cell::RefCell;
use std::ops::Range;

use super::Evaluator;
use super::limits::Pass;
use crate::arena::Arena;
use crate::physics::multibody::{Lent, lending};

/// A unit's states, inputs and step in seconds.
type Call<'c> = (&'c [f64], &'c [f64], f64);

/// Per-call scratch for one thread at a time: reused call after call.
#[derive(Default)]
pub struct Workspace {
    arena: Arena,
    /// An ensemble's member outputs before they join the mean.
    spare: Vec<f64>,
    /// The multibody algorithms' scratch (`multibody::Data`), lent to the thread that runs a
    /// call of a model on them.
    data: Lent,
}

/// A thread's workspace shrinks back after a call that grew it beyond this (a huge batch's
/// chunk), so idle service threads do not each keep the largest call's scratch.
const KEPT_BYTES: usize = 16 << 20;

/// What one unit of a batch may take from the arena (it frees nothing until the unit ends):
/// its states share the networks' matrix products, which gain little beyond 64 states.
const UNIT_BYTES: usize = 8 << 20;
/// A Linearize unit's estimated work: its states' jets (a dual number per direction on every
/// value) stay within a core's L2 cache. Measured on the double-pendulum MVF (one core, TVLQR
/// of 200 states): 8.3 ms a state at a time, 6.6 ms in units of 4 (this), 7.4 of 16, 8.8 of 64.
const LINEARIZE_UNIT_BYTES: usize = 512 << 10;
const UNIT_ROWS: usize = 64;
// A unit's states fill whole packs.
const _: () = assert!(UNIT_ROWS.is_multiple_of(super::pack::PACK));

thread_local! {
    static WORKSPACE: RefCell<Workspace> = RefCell::new(Workspace::default());
}

/// `f` with this thread's workspace; a fresh one when it is in use further up the stack.
pub fn with_workspace<R>(f: impl FnOnce(&mut Workspace) -> R) -> R {
    WORKSPACE.with(|cell| match cell.try_borrow_mut() {
        Ok(mut ws) => {
            let out = f(&mut ws);
            if ws.arena.allocated_bytes() > KEPT_BYTES {
                *ws = Workspace::default();
            }
            out
        }
        Err(_) => f(&mut Workspace::default()),
    })
}

impl Workspace {
    /// A workspace in which `eval`'s Predict (with q̈), Linearize and Rollout of up to
    /// `max_batch` states allocate nothing: each call's largest use, measured by running it
    /// once on zeros, in one block. A call's scratch is one unit's (at most `UNIT_ROWS`
    /// states), so a batch beyond that costs no more, and neither does a huge `max_batch` here.
    pub fn for_model(eval: &Evaluator, max_batch: usize) -> Self {
        let c = &eval.config;
        let (nx, ndx, nv, m, b) = (c.nx(), c.ndx(), c.nv(), c.m, max_batch.clamp(1, UNIT_ROWS));
        let mut ws = Workspace::default();
        let mut most = 0;
        // States at the space's origin (a rotation's (1, 0)), where every model evaluates.
        let x0 = c.space.origin_state();
        let x: Vec<f64> = x0.iter().copied().cycle().take(b * nx).collect();
        let u = vec![0.0; b * m];
        let (mut next, mut acc) = (vec![0.0; b * nx], vec![0.0; b * nv]);
        let (mut ja, mut jb) = (vec![0.0; b * ndx * ndx], vec![0.0; b * ndx * m]);
        // One state runs alone, more in narrow packs, a unit's whole rows in one wide pack:
        // the largest of each way, and the most.
        for batch in [1, 2, 3, b - 1, b]
            .into_iter()
            .filter(|&k| 1 <= k && k <= b)
        {
            let (x, u) = (&x[..batch * nx], &u[..batch * m]);
            let never = &|| false;
            let next = &mut next[..batch * nx];
            let acc = Some(&mut acc[..batch * nv]);
            eval.predict_into(&mut ws, x, u, c.dt, next, acc, never);
            most = most.max(ws.arena.allocated_bytes());
            let (ja, jb) = (&mut ja[..batch * ndx * ndx], &mut jb[..batch * ndx * m]);
            eval.linearize_into(&mut ws, x, u, ja, jb, never);
            most = most.max(ws.arena.allocated_bytes());
        }
        ws.arena = Arena::with_capacity(most);
        ws
    }

    /// `f` on this workspace, its multibody scratch lent to this thread for `eval`'s calls.
    fn lend<R>(&mut self, eval: &Evaluator, f: impl FnOnce(&mut Self) -> R) -> R {
        if !eval.is_multibody() {
            return f(self);
        }
        let mut data = self.data.take();
        let out = lending(&mut data, || f(self));
        self.data = data;
        out
    }

    /// The arena, emptied for a unit of work.
    pub(super) fn reset(&mut self) -> (&Arena, &mut Vec<f64>) {
        self.arena.reset();
        (&self.arena, &mut self.spare)
    }
}

/// out = the mean of `each(k)` over `members`, summed in member order (as `ensemble::mean`),
/// for a call's two outputs; `each(k, first, second)` writes member k's.
fn mean_into(
    members: usize,
    spare: &mut Vec<f64>,
    (first, second): (&mut [f64], &mut [f64]),
    mut each: impl FnMut(usize, &mut [f64], &mut [f64]),
) {
    each(0, first, second);
    spare.resize(first.len() + second.len(), 0.0);
    let (t1, t2) = spare.split_at_mut(first.len());
    for k in 1..members {
        each(k, t1, t2);
        for (s, v) in first
            .iter_mut()
            .zip(&*t1)
            .chain(second.iter_mut().zip(&*t2))
        {
            *s += v;
        }
    }
    let k = members as f64;
    first.iter_mut().chain(second).for_each(|s| *s /= k);
}

impl Evaluator {
    /// A batch of `rows` states as units of work: states together (their networks one matrix
    /// product) up to what the arena may hold (`limits` estimates a state's live work in the
    /// pass; a unit keeps each RK4 stage's), a Linearize's up to what stays in cache.
    pub(super) fn units(&self, rows: usize, pass: Pass) -> impl Iterator<Item = Range<usize>> {
        let bytes = match pass {
            Pass::Step => UNIT_BYTES / 4,
            Pass::Linearize => LINEARIZE_UNIT_BYTES,
        };
        let per = (bytes / self.work_bytes_per_state(pass).max(1)).clamp(1, UNIT_ROWS);
        (0..rows).step_by(per).map(move |s| s..rows.min(s + per))
    }

    /// x' (`next`, `[B, nq + nv]`) after `dt` seconds (`config.dt`: the model's own) and v̇
    /// when asked (`acc`, `[B, nv]`) for `[B, nq + nv]` states and `[B, m]` inputs, into the
    /// caller's buffers; `None` when `stop` said so before a unit.
    #[allow(clippy::too_many_arguments)]
    pub fn predict_into(
        &self,
        ws: &mut Workspace,
        x: &[f64],
        u: &[f64],
        dt: f64,
        next: &mut [f64],
        mut acc: Option<&mut [f64]>,
        stop: &dyn Fn() -> bool,
    ) -> Option<()> {
        ws.lend(self, |ws| {
            let (nx, nv, m) = (self.config.nx(), self.config.nv(), self.config.m);
            let rows = x.len() / nx;
            for r in self.units(rows, Pass::Step) {
                if stop() {
                    return None;
                }
                let (a, spare) = ws.reset();
                let (x, u) = (&x[nx * r.start..nx * r.end], &u[m * r.start..m * r.end]);
                let next = &mut next[nx * r.start..nx * r.end];
                let acc = (acc.as_deref_mut().map(|v| &mut v[nv * r.start..nv * r.end]))
                    .unwrap_or_default();
                match self.ensemble() {
                    Some(ms) => {
                        mean_into(ms.len(), spare, (next, acc), |k, next, acc| {
                            ms[k].predict_unit(a, (x, u, dt), next, acc)
                        });
                        self.config.space.project_states(next);
                    }
                    None => self.predict_unit(a, (x, u, dt), next, acc),
                }
            }
            Some(())
        })
    }

    /// One unit's x' and (unless `acc` is empty) v̇.
    fn predict_unit(&self, a: &Arena, call: Call, next: &mut [f64], acc: &mut [f64]) {
        let (x, u, dt) = call;
        next.copy_from_slice(&self.step_in(a, x, u, dt));
        if !acc.is_empty() {
            acc.copy_from_slice(&self.evaluate_in(a, self.rows(x, u), false));
        }
    }

    /// A `[B, 2nv, 2nv]` and B `[B, 2nv, m]` (as `linearize_batch`) into the caller's
    /// buffers; `None` when `stop` said so before a unit.
    pub fn linearize_into(
        &self,
        ws: &mut Workspace,
        x: &[f64],
        u: &[f64],
        ja: &mut [f64],
        jb: &mut [f64],
        stop: &dyn Fn() -> bool,
    ) -> Option<()> {
        ws.lend(self, |ws| {
            let (nx, ndx, m) = (self.config.nx(), self.config.ndx(), self.config.m);
            let rows = x.len() / nx;
            for r in self.units(rows, Pass::Linearize) {
                if stop() {
                    return None;
                }
                let (a, spare) = ws.reset();
                let (x, u) = (&x[nx * r.start..nx * r.end], &u[m * r.start..m * r.end]);
                let ja = &mut ja[ndx * ndx * r.start..ndx * ndx * r.end];
                let jb = &mut jb[ndx * m * r.start..ndx * m * r.end];
                match self.ensemble() {
                    Some(ms) => mean_into(ms.len(), spare, (ja, jb), |k, ja, jb| {
                        ms[k].linearize_unit(a, x, u, ja, jb)
                    }),
                    None => self.linearize_unit(a, x, u, ja, jb),
                }
            }
            Some(())
        })
    }

    /// A unit's A and B: per state and tangent coordinate of x', the row
    /// [∂x'_i/∂δx, ∂x'_i/∂u] cut in its A and B parts.
    fn linearize_unit(&self, a: &Arena, x: &[f64], u: &[f64], ja: &mut [f64], jb: &mut [f64]) {
        let (ndx, m) = (self.config.ndx(), self.config.m);
        let rows = self.jacobian_rows(a, x, u);
        for (i, row) in rows.chunks(ndx + m).enumerate() {
            ja[i * ndx..(i + 1) * ndx].copy_from_slice(&row[..ndx]);
            jb[i * m..(i + 1) * m].copy_from_slice(&row[ndx..]);
        }
    }

    /// `steps` states after x0, `dt` seconds apart, under the inputs `u` (`[steps, m]`) into
    /// `xs` (`[steps + 1, nq + nv]`, x0 first); the steps taken: fewer when `stop` said so
    /// after a step (the states so far are in `xs`).
    pub fn rollout_into(
        &self,
        ws: &mut Workspace,
        x0: &[f64],
        u: &[f64],
        dt: f64,
        xs: &mut [f64],
        stop: &dyn Fn() -> bool,
    ) -> usize {
        let (nx, m) = (self.config.nx(), self.config.m);
        xs[..nx].copy_from_slice(x0);
        let steps = xs.len() / nx - 1;
        for t in 0..steps {
            let (done, rest) = xs.split_at_mut((t + 1) * nx);
            let u = &u[t * m..(t + 1) * m];
            let next = &mut rest[..nx];
            self.predict_into(ws, &done[t * nx..], u, dt, next, None, &|| false);
            if stop() {
                return t + 1;
            }
        }
        steps
    }
}
