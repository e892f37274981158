//! Checks on a finished training run: findings a person should read before trusting the
//! model (it does no better than q̈ = 0, its loss never went down, its physical parameters
//! never moved). They never fail a job. Thresholds in README ("Training warnings").

use std::collections::BTreeMap;

use super::windows::Windows;
use crate::data::Dataset;
use crate::model::report::EpochMetrics;
use crate::physics::space::{Joint, Space};
use crate::records::Warning;

/// Runs shorter than this are not judged on progress (loss, parameters).
pub const MIN_EPOCHS: usize = 5;
/// "Not decreasing": no later epoch's training loss is below this fraction of the first's.
pub const DECREASE_FACTOR: f64 = 0.99;
/// "Never moved": every used physical value within this relative change of its initial one.
pub const MOVED_REL: f64 = 1e-6;

/// The loss of predicting q̈ = 0 (every integrator then gives q′ = q + q̇Δt, q̇′ = q̇) on `ds`,
/// with the model's velocity weight λ: the bar a model must clear to have learned anything.
/// Configurations are compared as the model's loss compares them: an angle by 2(1 − cos Δ),
/// so that wrapped data (a jump of 2π) does not make the bar too easy, and a rotation kept as
/// a unit complex number by |z′ − z|².
pub fn zero_acceleration_loss(ds: &Dataset, lambda: f64, space: &Space) -> f64 {
    zero_acceleration_window_loss(ds, &Windows::one_step(ds.count()), lambda, space)
}

/// The same bar over `windows`, as a multi-step run's loss is taken: from each window's first
/// state, v̇ = 0 rolled out for the window's steps (step k: integrate(q, (k+1)Δt·v), v), each
/// step's error against the data weighted as the run weighs it. One-step windows give
/// [`zero_acceleration_loss`].
pub fn zero_acceleration_window_loss(
    ds: &Dataset,
    windows: &Windows,
    lambda: f64,
    space: &Space,
) -> f64 {
    let (nq, nv) = (ds.nq(), ds.nv());
    let mut total = 0.0;
    let mut ahead_q = Vec::with_capacity(nq);
    for &start in &windows.starts {
        let (q, v) = (&ds.q[start * nq..][..nq], &ds.qdot[start * nv..][..nv]);
        for (k, w) in windows.weights.iter().enumerate() {
            let row = start + k;
            let ahead = match &ds.steps {
                None => (k + 1) as f64 * ds.dt,
                Some(s) => s[start..=row].iter().sum(),
            };
            ahead_q.clear();
            space.integrate_into(q, ahead, v, &mut ahead_q);
            let (q_next, v_next) = (
                &ds.q_next[row * nq..][..nq],
                &ds.qdot_next[row * nv..][..nv],
            );
            for p in space.placed() {
                let dq = |i: usize| q_next[i] - ahead_q[i];
                let position = match p.joint {
                    Joint::Real => dq(p.q.start) * dq(p.q.start),
                    Joint::Angle => 2.0 * (1.0 - dq(p.q.start).cos()),
                    Joint::Circle => p.q.clone().map(|i| dq(i) * dq(i)).sum(),
                };
                let dv = v_next[p.v] - v[p.v];
                total += w * (position + lambda * dv * dv);
            }
        }
    }
    total / windows.count().max(1) as f64
}

/// What a run's checks look at.
pub struct RunSummary<'a> {
    pub history: &'a [EpochMetrics],
    /// The kept model's loss on the validation set (training set without one): over windows
    /// of the run's horizon when the set has them, else one-step.
    pub best_loss: f64,
    /// The zero-acceleration loss on the same set and the same windows, and the steps of
    /// those windows (1: the one-step loss); none when the loss is not the states'.
    pub baseline: Option<(f64, usize)>,
    /// Used physical values at the start and now, by name.
    pub initial_physical: Option<&'a BTreeMap<String, f64>>,
    pub physical: &'a BTreeMap<String, f64>,
    /// The parameters that appear in some identifiable combination the report lists; None
    /// when no combinations are known for the model (then none can be called unidentifiable).
    pub identified: Option<&'a [String]>,
}

pub fn training_warnings(r: &RunSummary) -> Vec<Warning> {
    let mut out = vec![];
    if r.history.is_empty() {
        return out;
    }
    if let Some((baseline, steps)) = r.baseline
        && r.best_loss >= baseline
    {
        out.push(Warning::new(
            "no_better_than_zero_acceleration",
            None,
            format!(
                "the best {}loss {:.4e} is not below {:.4e}, the loss of predicting no \
                 acceleration at all (q' = q + qdot·dt, qdot' = qdot){}: the model has learned \
                 nothing usable; check the data's units and dt, or train longer",
                if steps > 1 {
                    format!("{steps}-step ")
                } else {
                    String::new()
                },
                r.best_loss,
                baseline,
                if steps > 1 {
                    " over the same windows"
                } else {
                    ""
                },
            ),
        ));
    }
    if r.history.len() >= MIN_EPOCHS {
        out.extend(not_decreasing(r.history));
        if let Some(initial) = r.initial_physical {
            out.extend(unmoved(initial, r.physical, r.identified, r.history.len()));
        }
    }
    out
}

fn not_decreasing(history: &[EpochMetrics]) -> Option<Warning> {
    let first = history[0].train_loss;
    let best_later = history[1..]
        .iter()
        .map(|h| h.train_loss)
        .fold(f64::INFINITY, f64::min);
    (best_later >= DECREASE_FACTOR * first).then(|| {
        Warning::new(
            "loss_not_decreasing",
            None,
            format!(
                "the training loss did not decrease over {} epochs (epoch 1: {first:.4e}, best \
                 since: {best_later:.4e}); try another learning rate, or check the data",
                history.len()
            ),
        )
    })
}

fn unmoved(
    initial: &BTreeMap<String, f64>,
    now: &BTreeMap<String, f64>,
    identified: Option<&[String]>,
    epochs: usize,
) -> Option<Warning> {
    let moved = |name: &String, v0: f64| {
        now.get(name)
            .is_none_or(|v| (v - v0).abs() > MOVED_REL * v0.abs().max(f64::MIN_POSITIVE))
    };
    let stuck: Vec<&str> = initial
        .iter()
        .filter(|(name, v0)| !moved(name, **v0))
        .map(|(name, _)| name.as_str())
        .collect();
    // Those in no identifiable combination: the data cannot tell their values apart, so not
    // moving is no sign of a unit error.
    let (blind, stuck): (Vec<&str>, Vec<&str>) = stuck
        .into_iter()
        .partition(|name| identified.is_some_and(|ids| !ids.iter().any(|i| i == name)));
    let mut parts = vec![];
    if !stuck.is_empty() {
        parts.push(format!(
            "the physical parameters {} did not change in {epochs} epochs: their gradients \
             vanish or the loss is dominated by something they cannot fit (check units)",
            stuck.join(", ")
        ));
    }
    if !blind.is_empty() {
        parts.push(format!(
            "{} did not change in {epochs} epochs and are not identifiable from this data (they \
             are in no identifiable combination: read the combinations, not these values)",
            blind.join(", ")
        ));
    }
    (!parts.is_empty()).then(|| Warning::new("physical_parameters_unmoved", None, parts.join("; ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn history(losses: &[f64]) -> Vec<EpochMetrics> {
        losses
            .iter()
            .enumerate()
            .map(|(i, &l)| EpochMetrics {
                epoch: i + 1,
                train_loss: l,
                val_loss: Some(l),
                val_horizon_loss: None,
                seconds: 0.1,
            })
            .collect()
    }

    fn codes(r: &RunSummary) -> Vec<String> {
        training_warnings(r).into_iter().map(|w| w.code).collect()
    }

    fn values(v: &[(&str, f64)]) -> BTreeMap<String, f64> {
        v.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    }

    /// Under a constant acceleration a from rest at t = 0, q̈ = 0 rolled out from t₀ for
    /// k + 1 steps misses q by a((k+1)Δt)²/2 and q̇ by a(k+1)Δt, wherever the window starts:
    /// the H-step bar is Σ_k w_k (that² + λ·that²), and the one-step bar is its k = 0 term.
    #[test]
    fn the_zero_acceleration_bar_over_windows_matches_constant_acceleration() {
        let (a, dt, lambda, rows) = (2.0, 0.1, 0.5, 20);
        let t = |k: usize| k as f64 * dt;
        let ds = Dataset {
            nq: 1,
            nv: 1,
            m: 1,
            dt,
            q: (0..rows).map(|k| 0.5 * a * t(k) * t(k)).collect(),
            qdot: (0..rows).map(|k| a * t(k)).collect(),
            u: vec![0.0; rows],
            q_next: (1..=rows).map(|k| 0.5 * a * t(k) * t(k)).collect(),
            qdot_next: (1..=rows).map(|k| a * t(k)).collect(),
            trajectories: Some(vec![rows]),
            steps: None,
        };
        let miss = |k: usize| {
            let s = (k + 1) as f64 * dt;
            (0.5 * a * s * s).powi(2) + lambda * (a * s).powi(2)
        };
        let one = zero_acceleration_loss(&ds, lambda, &Space::flat(1, &[]));
        assert!((one - miss(0)).abs() < 1e-12, "{one}");
        let windows = Windows::of(&ds, 5, 0.9);
        assert_eq!(windows.count(), rows - 4);
        let want: f64 = (0..5).map(|k| windows.weights[k] * miss(k)).sum();
        let got = zero_acceleration_window_loss(&ds, &windows, lambda, &Space::flat(1, &[]));
        // Sums of a few hundred terms of size ~1: equal to rounding.
        assert!((got - want).abs() < 1e-12 * want, "{got} vs {want}");
        assert!(got > 5.0 * one, "the longer windows set a higher bar");
    }

    #[test]
    fn a_learning_run_raises_nothing() {
        let h = history(&[1.0, 0.5, 0.2, 0.1, 0.05]);
        let (p0, p1) = (values(&[("m1", 10.0)]), values(&[("m1", 9.0)]));
        let r = RunSummary {
            history: &h,
            best_loss: 0.05,
            baseline: Some((3.0, 1)),
            initial_physical: Some(&p0),
            physical: &p1,
            identified: None,
        };
        assert!(codes(&r).is_empty());
    }

    #[test]
    fn each_check_fires_on_its_case() {
        let h = history(&[1.0, 1.0, 0.995, 1.2, 1.0]);
        let p0 = values(&[("m1", 10.0), ("l1", 1.0)]);
        let r = RunSummary {
            history: &h,
            best_loss: 4.0,
            baseline: Some((3.0, 1)),
            initial_physical: Some(&p0),
            physical: &p0,
            identified: None,
        };
        assert_eq!(
            codes(&r),
            [
                "no_better_than_zero_acceleration",
                "loss_not_decreasing",
                "physical_parameters_unmoved"
            ]
        );
    }

    /// A parameter in no identifiable combination is called unidentifiable, not a unit
    /// problem; one in a combination keeps the old advice; unknown combinations, the old text.
    #[test]
    fn unmoved_parameters_the_data_cannot_identify_are_named_so() {
        let h = history(&[1.0, 0.5, 0.2, 0.1, 0.05]);
        let p0 = values(&[("g", 9.8), ("l", 1.0), ("b", 0.1)]);
        let ids = ["g/l".to_string(), "g".to_string(), "l".to_string()];
        let message = |identified| {
            let r = RunSummary {
                history: &h,
                best_loss: 0.05,
                baseline: Some((3.0, 1)),
                initial_physical: Some(&p0),
                physical: &p0,
                identified,
            };
            training_warnings(&r).remove(0).message
        };
        let known = message(Some(&ids[1..]));
        assert!(known.contains("parameters g, l did not change"), "{known}");
        assert!(known.contains("b did not change") && known.contains("not identifiable"));
        let unknown = message(None);
        assert!(
            !unknown.contains("not identifiable") && unknown.contains("b, g, l"),
            "{unknown}"
        );
    }

    #[test]
    fn short_runs_are_not_judged_on_progress() {
        let h = history(&[1.0, 1.0]);
        let p0 = values(&[("m1", 10.0)]);
        let r = RunSummary {
            history: &h,
            best_loss: 1.0,
            baseline: Some((3.0, 1)),
            initial_physical: Some(&p0),
            physical: &p0,
            identified: None,
        };
        assert!(codes(&r).is_empty());
    }

    #[test]
    fn the_baseline_is_the_loss_of_no_acceleration() {
        // q' = q + q̇dt exactly, q̇' = q̇ + 1: only the velocity error counts, λ-weighted.
        let ds = Dataset::new(
            0.1,
            (1, 1),
            1,
            [
                vec![0.0, 1.0],
                vec![2.0, 3.0],
                vec![0.0; 2],
                vec![0.2, 1.3],
                vec![3.0, 4.0],
            ],
        )
        .unwrap();
        let l = zero_acceleration_loss(&ds, 0.5, &Space::flat(ds.nv, &[]));
        assert!((l - 0.5).abs() < 1e-12, "{l}");
    }

    #[test]
    fn the_baseline_compares_angles_on_the_circle() {
        // Sample 0 wraps from just below π to just above −π: Δ = −2π + 0.1 for the angle,
        // 2(1 − cos 0.1) on the circle; sample 1 moves 0.1 off the zero-acceleration guess.
        let ds = Dataset::new(
            0.1,
            (1, 1),
            1,
            [
                vec![3.1, 0.0],
                vec![0.0, 0.0],
                vec![0.0; 2],
                vec![3.1 + 0.1 - 2.0 * std::f64::consts::PI, 0.1],
                vec![0.0, 0.0],
            ],
        )
        .unwrap();
        let on_circle = 2.0 * (1.0 - 0.1f64.cos());
        let l = zero_acceleration_loss(&ds, 1.0, &Space::flat(1, &[true]));
        assert!((l - on_circle).abs() < 1e-12, "{l}");
        assert!(
            zero_acceleration_loss(&ds, 1.0, &Space::flat(1, &[])) > 15.0,
            "not wrapped: ~(2π)²/2"
        );
    }
}
