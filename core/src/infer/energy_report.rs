//! The energy report (docs/energy.md#the-energy-report): does the model keep, create or lose
//! energy where it has data? Drift: unforced rollouts (u = 0, F's damping and friction
//! switched off, so that a conservative rest must conserve E) from states drawn from the data,
//! |E(t) − E(0)| against a scale the potential's constant does not change. Passivity: the
//! share of data states where the unforced F (every part on) injects energy, q̇ᵀF(q, q̇, 0) > 0.

use super::Evaluator;
use crate::error::Result;
use crate::model::report::{EnergyDrift, EnergyReport, Passivity};
use crate::rng::Rng;

/// Which data states a report draws unless told otherwise: fixed, so a report is
/// reproducible, and training's and `graybox energy --report`'s agree on the same data.
pub const REPORT_SEED: u64 = 0xE4E2_6A11;

/// Rollouts from this many states: enough for a median and a worst case, 1000 steps of them
/// ~0.3 s for MVF.
pub const DRIFT_ROLLOUTS: usize = 64;
/// Where drift is read: 100 steps separate a model's own energy balance from the
/// integrator's (RK4's error grows with the steps), 1000 show what accumulates.
pub const DRIFT_STEPS: [usize; 2] = [100, 1000];
/// States the passivity share is measured on.
pub const PASSIVITY_STATES: usize = 4096;
/// q̇ᵀF counts as injecting beyond this share of ‖q̇‖‖F‖: a dot product of n terms rounds
/// to ~n·1e-16 of it, and any injection worth naming is far above 1e-9.
const POWER_TOLERANCE: f64 = 1e-9;

impl Evaluator {
    /// This model without the parts of F its spec names damping or friction.
    pub fn without_damping(&self) -> Evaluator {
        let mut e = self.clone();
        e.without_damping = true;
        if let Some(members) = &self.members {
            let each = members.iter().map(Evaluator::without_damping);
            e.members = Some(each.collect::<Vec<_>>().into());
        }
        e
    }

    /// The report on states `[N ≥ 1, nq + nv]` drawn from a dataset (`seed` picks them), or `None`
    /// when `stop` says so.
    pub fn energy_report(
        &self,
        states: &[f64],
        seed: u64,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<EnergyReport>> {
        self.check_energy()?;
        let nx = self.config.nx();
        let mut rng = Rng::new(seed);
        let Some((scale, drift, switched_off)) =
            self.drift(&sample(states, nx, DRIFT_ROLLOUTS, &mut rng), stop)?
        else {
            return Ok(None);
        };
        let Some(passivity) =
            self.passivity(&sample(states, nx, PASSIVITY_STATES, &mut rng), stop)?
        else {
            return Ok(None);
        };
        let rollouts = states.len().div_ceil(nx).min(DRIFT_ROLLOUTS);
        Ok(Some(EnergyReport {
            dataset_id: None,
            summary: summary(&passivity, drift.last(), rollouts),
            rollouts,
            switched_off,
            energy_scale: (scale > 0.0).then_some(scale),
            drift,
            passivity,
        }))
    }

    /// The energy scale, the drift at each of [`DRIFT_STEPS`], and the parts switched off.
    #[allow(clippy::type_complexity)]
    fn drift(
        &self,
        starts: &[f64],
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<(f64, Vec<EnergyDrift>, Vec<String>)>> {
        let (nx, m) = (self.config.nx(), self.config.m);
        let b = starts.len() / nx;
        let idle = vec![0.0; b * m];
        let Some(e0) = self.energy_until(starts, &idle, stop)? else {
            return Ok(None);
        };
        let switched_off = (e0.parts.iter())
            .filter(|p| p.dissipation)
            .map(|p| p.name.to_string())
            .collect();
        let mean_t = e0.kinetic.iter().sum::<f64>() / b as f64;
        let (lo, hi) = (e0.potential.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        let scale = mean_t + (hi - lo);
        // States all at rest at one V have no scale: their drift is then absolute.
        let denom = if scale > 0.0 { scale } else { 1.0 };
        let conservative = self.without_damping();
        let (mut x, mut drift) = (starts.to_vec(), vec![]);
        for step in 1..=DRIFT_STEPS[DRIFT_STEPS.len() - 1] {
            let Some((next, _)) =
                conservative.predict_until(&x, &idle, self.config.dt, false, stop)
            else {
                return Ok(None);
            };
            x = next;
            if !DRIFT_STEPS.contains(&step) {
                continue;
            }
            let Some(e) = self.energy_until(&x, &idle, stop)? else {
                return Ok(None);
            };
            let rel: Vec<f64> = (e.total.iter().zip(&e0.total))
                .map(|(e, e0)| (e - e0).abs() / denom)
                .collect();
            drift.push(drift_at(step, step as f64 * self.config.dt, rel));
        }
        Ok(Some((scale, drift, switched_off)))
    }

    fn passivity(&self, states: &[f64], stop: &dyn Fn() -> bool) -> Result<Option<Passivity>> {
        let (nq, nv, m) = (self.config.nq(), self.config.nv(), self.config.m);
        let b = states.len() / (nq + nv);
        let Some(e) = self.energy_until(states, &vec![0.0; b * m], stop)? else {
            return Ok(None);
        };
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let injecting: Vec<f64> = (0..b)
            .filter_map(|k| {
                let qd = &states[k * (nq + nv) + nq..(k + 1) * (nq + nv)];
                let f = &e.applied[k * nv..(k + 1) * nv];
                let p = e.power[k];
                (p > POWER_TOLERANCE * norm(qd) * norm(f)).then_some(p)
            })
            .collect();
        Ok(Some(Passivity {
            states: b,
            injecting: injecting.len(),
            share: injecting.len() as f64 / b as f64,
            max_power: injecting.iter().copied().fold(0.0, f64::max),
        }))
    }
}

/// Up to `count` distinct rows of `[N, width]`, drawn without replacement.
fn sample(rows: &[f64], width: usize, count: usize, rng: &mut Rng) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..rows.len() / width).collect();
    rng.shuffle(&mut idx);
    idx.truncate(count);
    idx.sort_unstable();
    (idx.iter())
        .flat_map(|&i| rows[i * width..(i + 1) * width].iter().copied())
        .collect()
}

fn drift_at(steps: usize, seconds: f64, rel: Vec<f64>) -> EnergyDrift {
    let mut finite: Vec<f64> = rel.iter().copied().filter(|v| v.is_finite()).collect();
    finite.sort_by(f64::total_cmp);
    EnergyDrift {
        steps,
        seconds,
        median: (!finite.is_empty()).then(|| finite[finite.len() / 2]),
        max: finite.last().copied(),
        diverged: rel.len() - finite.len(),
    }
}

/// The report in one plain sentence.
/// The median drift beside the worst: one rollout far off is what a controller would meet.
fn summary(p: &Passivity, drift: Option<&EnergyDrift>, rollouts: usize) -> String {
    let creates = match p.injecting {
        0 => "never creates energy where it has data".to_string(),
        _ => format!("creates energy in {:.0} % of states", 100.0 * p.share),
    };
    let drifts = match drift {
        Some(EnergyDrift {
            steps,
            median: Some(m),
            max,
            diverged,
            ..
        }) => {
            let lost = match diverged {
                0 => String::new(),
                d => format!(" ({d} diverged)"),
            };
            format!(
                "; unforced rollouts drift by {} (median) and up to {} (the worst of {rollouts}) \
                 of the energy scale in {steps} steps{lost}",
                percent(*m),
                percent(max.unwrap_or(*m)),
            )
        }
        Some(d) => format!("; every unforced rollout diverged within {} steps", d.steps),
        None => String::new(),
    };
    format!("{creates}{drifts}")
}

/// A share as a percentage with the digits that matter (1e-9, 0.4 and 2e4 alike).
fn percent(share: f64) -> String {
    let p = 100.0 * share;
    if (0.1..1000.0).contains(&p) {
        format!("{p:.1} %")
    } else {
        format!("{p:.1e} %")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sentence says the worst rollout's drift beside the median's, which alone hid a
    /// rollout that ran away.
    #[test]
    fn the_sentence_names_the_median_and_the_worst_drift() {
        let p = Passivity {
            states: 100,
            injecting: 12,
            share: 0.12,
            max_power: 3.0,
        };
        let d = drift_at(1000, 10.0, vec![0.002, 0.004, 0.006, 100.0, f64::INFINITY]);
        assert_eq!(
            summary(&p, Some(&d), 5),
            "creates energy in 12 % of states; unforced rollouts drift by 0.6 % (median) and up \
             to 1.0e4 % (the worst of 5) of the energy scale in 1000 steps (1 diverged)"
        );
    }
}
