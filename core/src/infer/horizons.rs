//! Open-loop error against horizon: a model rolled out from every window start of a
//! trajectory dataset under the recorded inputs, its error against the recorded states after
//! h steps, summarized per horizon. What `graybox eval --horizons`, `POST
//! /v1/models/{id}/evaluate` and the multi-step experiments report.

use super::Evaluator;
use crate::data::Dataset;
use crate::data::trajectories::Segment;
use crate::error::{Error, Result};
use crate::model::file::ModelFile;
pub use crate::model::report::HorizonError;
use crate::physics::space::Joint;

/// Where a training's end looks, in steps (those its validation trajectories are long enough
/// for).
pub const END_OF_TRAINING: [usize; 4] = [1, 10, 50, 100];

/// The most horizons one evaluation reports.
pub const MAX_HORIZONS: usize = 32;

/// Horizons must be 1 or more (at most `max_steps`: the service's `--max-rollout-steps`;
/// `usize::MAX` for no bound), at most [`MAX_HORIZONS`] of them; returned sorted, each once.
pub fn check_horizons(horizons: &[usize], max_steps: usize) -> Result<Vec<usize>> {
    if horizons.is_empty() || horizons.len() > MAX_HORIZONS {
        return Err(Error::invalid(
            "horizons",
            format!("give 1 to {MAX_HORIZONS} horizons (steps), e.g. 1,10,50,100"),
        ));
    }
    if let Some(h) = horizons.iter().find(|h| !(1..=max_steps).contains(*h)) {
        return Err(Error::invalid(
            "horizons",
            match max_steps {
                usize::MAX => format!("{h} is not a number of steps: each must be 1 or more"),
                _ => format!(
                    "{h} is not a number of steps in 1..={max_steps} (at most the service's \
                     --max-rollout-steps)"
                ),
            },
        ));
    }
    let mut sorted = horizons.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    Ok(sorted)
}

/// How many model steps [`horizon_errors`] takes: each window start rolled out as far as the
/// longest horizon its trajectory allows.
pub fn cost(ds: &Dataset, longest: usize) -> usize {
    segments_cost(&ds.segments(), longest)
}

/// [`cost`] from the trajectories' boundaries alone (known without the rows when uploaded).
pub fn segments_cost(segments: &[Segment], longest: usize) -> usize {
    segments
        .iter()
        .flat_map(|s| (0..s.length).map(move |i| (s.length - i).min(longest)))
        .fold(0usize, usize::saturating_add)
}

/// The errors at each of `horizons` (checked, sorted), or None when `stop` says so between
/// steps. All window starts step together as one batch; a start leaves the batch when its
/// trajectory ends.
pub fn horizon_errors(
    e: &Evaluator,
    ds: &Dataset,
    horizons: &[usize],
    stop: &dyn Fn() -> bool,
) -> Option<Vec<HorizonError>> {
    let (nq, nv, m) = (ds.nq, ds.nv, ds.m);
    let nx = nq + nv;
    let longest = *horizons.last().expect("checked: at least one horizon");
    // (start row, transitions left in its trajectory), and each start's current state.
    let mut alive: Vec<(usize, usize)> = (ds.segments().iter())
        .flat_map(|s| (0..s.length).map(move |i| (s.start + i, s.length - i)))
        .collect();
    let mut x: Vec<f64> = (alive.iter())
        .flat_map(|&(r, _)| {
            ds.q[r * nq..(r + 1) * nq]
                .iter()
                .chain(&ds.qdot[r * nv..(r + 1) * nv])
        })
        .copied()
        .collect();
    let mut found: Vec<Vec<(f64, f64)>> = vec![vec![]; horizons.len()];
    for k in 0..longest {
        let u: Vec<f64> = (alive.iter())
            .flat_map(|&(r, _)| ds.u[(r + k) * m..(r + k + 1) * m].iter().copied())
            .collect();
        x = match &ds.steps {
            None => e.predict_until(&x, &u, e.config.dt, false, stop)?.0,
            // Transitions of their own Δt: each start steps its row's.
            Some(steps) => (x.chunks(nx).zip(u.chunks(m)).zip(&alive))
                .map(|((x, u), &(r, _))| e.predict_until(x, u, steps[r + k], false, stop))
                .collect::<Option<Vec<_>>>()?
                .into_iter()
                .flat_map(|(x, _)| x)
                .collect(),
        };
        let step = k + 1;
        if let Some(slot) = horizons.iter().position(|&h| h == step) {
            found[slot] = (alive.iter().enumerate())
                .map(|(b, &(r, _))| errors(e, ds, &x[b * nx..(b + 1) * nx], r + k))
                .collect();
        }
        // Keep the starts whose trajectory goes on.
        let keep: Vec<bool> = alive.iter().map(|&(_, left)| left > step).collect();
        x = (x.chunks(nx).zip(&keep))
            .filter(|(_, k)| **k)
            .flat_map(|(row, _)| row.iter().copied())
            .collect();
        alive.retain(|&(_, left)| left > step);
        if alive.is_empty() {
            break;
        }
    }
    let summary = |h: usize, errs: &[(f64, f64)]| HorizonError {
        horizon: h,
        seconds: h as f64 * ds.dt,
        windows: errs.len(),
        diverged: errs.iter().filter(|e| !e.0.is_finite()).count(),
        position_median: median(errs.iter().map(|e| e.0)),
        position_mean: mean(errs.iter().map(|e| e.0)),
        velocity_median: median(errs.iter().map(|e| e.1)),
        velocity_mean: mean(errs.iter().map(|e| e.1)),
    };
    Some(
        (horizons.iter().zip(&found))
            .map(|(&h, f)| summary(h, f))
            .collect(),
    )
}

/// (position, velocity) error of predicted state `x` against the next state of row `r`: the
/// norm of difference(q′, q̂′) per joint (an angle's wrapped to (−π, π], a rotation's the angle
/// between them) and of v̂′ − v′.
fn errors(e: &Evaluator, ds: &Dataset, x: &[f64], r: usize) -> (f64, f64) {
    let (nq, nv) = (ds.nq, ds.nv);
    let wrap = |d: f64| d.sin().atan2(d.cos());
    let norm = |it: &mut dyn Iterator<Item = f64>| {
        let s: f64 = it.map(|d| d * d).sum::<f64>().sqrt();
        if s.is_finite() { s } else { f64::INFINITY }
    };
    let space = &e.config.space;
    let q_next = &ds.q_next[r * nq..(r + 1) * nq];
    let q = norm(&mut space.placed().map(|p| match p.joint {
        Joint::Real => x[p.q.start] - q_next[p.q.start],
        Joint::Angle => wrap(x[p.q.start] - q_next[p.q.start]),
        Joint::Circle => space.difference(q_next, &x[..nq])[p.v],
    }));
    let v = norm(&mut (0..nv).map(|i| x[nq + i] - ds.qdot_next[r * nv + i]));
    (q, v)
}

fn median(values: impl Iterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    let k = v.len();
    let mid = match k {
        0 => return None,
        _ if k % 2 == 1 => v[k / 2],
        _ => 0.5 * (v[k / 2 - 1] + v[k / 2]),
    };
    mid.is_finite().then_some(mid)
}

fn mean(values: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.collect();
    let s = v.iter().sum::<f64>() / v.len() as f64;
    (!v.is_empty() && s.is_finite()).then_some(s)
}

/// The errors a finished training reports on its validation trajectories: at
/// [`END_OF_TRAINING`]'s horizons their longest trajectory reaches; none when no trajectory
/// has two transitions (independent samples).
pub fn end_of_training(file: &ModelFile, val: &Dataset) -> Result<Vec<HorizonError>> {
    let longest = val.segments().iter().map(|s| s.length).max().unwrap_or(0);
    if longest < 2 {
        return Ok(vec![]);
    }
    let horizons: Vec<usize> = END_OF_TRAINING
        .into_iter()
        .filter(|&h| h <= longest)
        .collect();
    let e = Evaluator::from_file(file)?;
    Ok(horizon_errors(&e, val, &horizons, &|| false).expect("never stopped"))
}
