//! What a training run reports: losses, timing, and the learned physical parameters with the
//! combinations of them that the data can identify.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use crate::model::spec::ModelSpec;
use crate::physics::identify;
use crate::physics::params::Part;
use crate::physics::templates::Template;
use crate::records::Warning;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpochMetrics {
    /// Counting from 1.
    pub epoch: usize,
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    /// The validation loss over windows of the run's horizon, for a multi-step run whose
    /// validation data has such windows (`val_loss` stays the one-step loss).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_horizon_loss: Option<f64>,
    /// Wall time of this epoch (training and validation).
    pub seconds: f64,
}

/// The errors after `horizon` steps over every window of that many transitions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct HorizonError {
    pub horizon: usize,
    /// horizon × Δt.
    pub seconds: f64,
    /// Window starts with `horizon` transitions after them in their trajectory.
    pub windows: usize,
    /// Of them, rollouts whose state left the finite numbers (their errors count as ∞).
    pub diverged: usize,
    /// ‖q̂ − q‖₂ after `horizon` steps, angles (the model's periodic coordinates) compared on
    /// the circle (the difference wrapped into (−π, π]). Null without windows, or when the
    /// figure is infinite (JSON has no ∞).
    pub position_median: Option<f64>,
    pub position_mean: Option<f64>,
    /// ‖q̂̇ − q̇‖₂ after `horizon` steps.
    pub velocity_median: Option<f64>,
    pub velocity_mean: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identified {
    pub name: String,
    pub value: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainReport {
    /// The name the model was asked for ("MVF", …) or "custom" for a JSON spec.
    pub model: String,
    pub spec: ModelSpec,
    /// Epochs completed.
    pub epochs: usize,
    /// Final epoch's losses.
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    /// The epoch whose parameters were kept (best validation loss; best training loss when
    /// there is no validation set).
    pub best_epoch: usize,
    pub best_val_loss: Option<f64>,
    /// The steps of the windows `best_val_loss` is taken over: the run's horizon when its
    /// validation set has windows that long (a multi-step run), else 1 (the one-step loss).
    /// Absent in earlier files and without a validation set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub best_val_loss_steps: Option<usize>,
    pub stopped_early: bool,
    pub seconds: f64,
    pub samples_per_second: f64,
    /// Learned white-box values by name (only parameters some white-box part uses).
    pub physical_parameters: BTreeMap<String, f64>,
    pub identifiable: Vec<Identified>,
    /// What the data cannot determine of `physical_parameters` beyond `identifiable` (a URDF
    /// robot's inertial values: only combinations of them); absent in earlier files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identifiability: Option<String>,
    pub history: Vec<EpochMetrics>,
    /// Open-loop error against horizon on the validation trajectories at the end (README
    /// "Multi-step training"); absent without validation trajectories, and in earlier files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub horizon_errors: Vec<HorizonError>,
    /// The training checks' findings (`train::warnings`); absent in earlier files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
    /// An ensemble's members, and its physical values' spread (README "Ensembles and
    /// uncertainty"); the fields above are then the members' means. Absent for one model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ensemble: Option<EnsembleReport>,
    /// Energy drift and passivity on the training data (README "Energy and power"); absent
    /// for a naive model and in earlier files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<EnergyReport>,
}

/// Whether a model keeps, creates or loses energy where it has data (README "Energy and
/// power"), measured once on states drawn from a dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EnergyReport {
    /// The dataset it was measured on when asked for (`POST /v1/models/{id}/energy-report`);
    /// absent when measured on the training data as the job finished.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset_id: Option<String>,
    /// The figures in a sentence, e.g. "creates energy in 12.0 % of states; unforced rollouts
    /// drift by 0.4 % (median) and up to 1.0e4 % (the worst of 64) of the energy scale in 1000
    /// steps".
    pub summary: String,
    /// Unforced rollouts (u = 0, `switched_off` parts removed) from this many states.
    pub rollouts: usize,
    /// The parts of F named damping or friction, switched off in the rollouts, so that a
    /// conservative rest must conserve E.
    pub switched_off: Vec<String>,
    /// The states' mean kinetic energy plus the range of V over them: what drift is a share
    /// of (a potential's constant does not change it). Null when it is 0, and drift is then
    /// absolute.
    pub energy_scale: Option<f64>,
    pub drift: Vec<EnergyDrift>,
    pub passivity: Passivity,
}

/// |E(t) − E(0)| / energy scale after `steps` steps of the unforced rollouts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EnergyDrift {
    pub steps: usize,
    /// steps × Δt.
    pub seconds: f64,
    /// Over the rollouts that stayed finite; null when none did.
    pub median: Option<f64>,
    pub max: Option<f64>,
    /// Rollouts whose state or energy left the finite numbers.
    pub diverged: usize,
}

/// Where the unforced generalized force F(q, q̇, 0) injects energy: q̇ᵀF > 0 beyond rounding
/// (1e-9 · ‖q̇‖‖F‖). A passive system never does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Passivity {
    pub states: usize,
    pub injecting: usize,
    /// injecting / states.
    pub share: f64,
    /// The largest q̇ᵀF(q, q̇, 0) among them (0 when none injects).
    pub max_power: f64,
}

/// What an ensemble's report adds: each member's own figures and the physical values'
/// spread across members.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnsembleReport {
    pub members: Vec<MemberReport>,
    /// The members' own training seconds summed. Members trained side by side time epochs
    /// that overlap, so this is up to K times the report's `seconds`, the run's wall time;
    /// absent in earlier files, whose `seconds` is this sum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub member_seconds: Option<f64>,
    /// Each physical parameter's mean and standard deviation across the members: bootstrap
    /// error bars when the members trained on resamples.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub physical_parameters: BTreeMap<String, Spread>,
}

/// One member's figures in an ensemble's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MemberReport {
    pub best_epoch: usize,
    pub best_val_loss: Option<f64>,
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub physical_parameters: BTreeMap<String, f64>,
}

/// A mean and a standard deviation across an ensemble's members.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    pub mean: f64,
    pub std: f64,
}

impl Spread {
    /// The mean and the sample standard deviation (divided by K − 1: K is small, and the
    /// members are K draws of what training could have given; 0 for one value).
    pub fn of(values: &[f64]) -> Self {
        let k = values.len() as f64;
        let mean = values.iter().sum::<f64>() / k;
        let ss: f64 = values.iter().map(|v| (v - mean).powi(2)).sum();
        let std = if values.len() > 1 {
            (ss / (k - 1.0)).sqrt()
        } else {
            0.0
        };
        Self { mean, std }
    }
}

/// The parameters that the white-box parts use, by name.
pub fn used_physical(
    t: &Template,
    parts: &[Part],
    values: &[(String, f64)],
) -> BTreeMap<String, f64> {
    t.params()
        .iter()
        .zip(values)
        .filter(|(info, _)| info.used_by.iter().any(|p| parts.contains(p)))
        .map(|(_, (name, v))| (name.clone(), *v))
        .collect()
}

/// The identifiable combinations whose parts are all white-box, evaluated at `values`.
pub fn identifiable(t: &Template, parts: &[Part], values: &[(String, f64)]) -> Vec<Identified> {
    let lookup = |name: &str| -> f64 {
        values
            .iter()
            .find(|(n, _)| n == name)
            .map_or(f64::NAN, |(_, v)| *v)
    };
    let mut out: Vec<Identified> = t
        .combinations()
        .iter()
        .filter(|c| c.needs.iter().all(|p| parts.contains(p)))
        .map(|c| Identified {
            name: c.name.to_string(),
            value: (c.eval)(&lookup),
        })
        .collect();
    // A formula template's, from the sensitivity of its dynamics (all of it white-box).
    if let Template::Formula(_) = t
        && [Part::Mass, Part::Potential, Part::Forces]
            .iter()
            .all(|p| parts.contains(p))
    {
        out.extend(formula_products(t, values));
    }
    // A robot's are computed from its kinematics: its base parameters.
    if let Template::Urdf(u) = t
        && parts.contains(&Part::Mass)
    {
        let physical: Vec<f64> = values.iter().map(|(_, v)| *v).collect();
        let gravity = parts.contains(&Part::Potential);
        out.extend(
            (u.base_parameters(&physical, gravity).into_iter())
                .map(|(name, value)| Identified { name, value }),
        );
    }
    out
}

/// Sampled states at which a formula template's sensitivities are taken: generic ones (q over
/// a turn, moderate velocities and inputs), seeded, so a report is reproducible.
const SENSITIVITY_STATES: usize = 32;

/// The identifiable products of a formula template's trained parameters (fixed ones are known
/// and drop out; one at 0 has no logarithm and is left out), from ∂q̈/∂ log θ by central
/// differences at `SENSITIVITY_STATES` states (docs/dynamics.md#identifiability-of-formula-templates).
fn formula_products(t: &Template, values: &[(String, f64)]) -> Vec<Identified> {
    let infos = t.params();
    let theta: Vec<f64> = values.iter().map(|(_, v)| *v).collect();
    let trained: Vec<usize> = (0..infos.len())
        .filter(|&j| !infos[j].fixed && !infos[j].used_by.is_empty() && theta[j] != 0.0)
        .collect();
    // The differences alone cost 2p rollouts of the document: none beyond the search's limit.
    if trained.len() > identify::MAX_PARAMS {
        return vec![];
    }
    let mut rng = crate::rng::Rng::new(0x1D_E7);
    let states: Vec<[Vec<f64>; 3]> = (0..SENSITIVITY_STATES)
        .map(|_| {
            let mut draw = |k: usize, r: f64| (0..k).map(|_| rng.uniform_in(-r, r)).collect();
            [
                draw(t.n(), std::f64::consts::PI),
                draw(t.n(), 2.0),
                draw(t.m(), 1.0),
            ]
        })
        .collect();
    let accelerations = |theta: Vec<f64>| -> Vec<f64> {
        let sys = crate::sim::TemplateSystem::new(t.clone(), theta);
        (states.iter())
            .flat_map(|[q, qd, u]| sys.acceleration(q, qd, u))
            .collect()
    };
    // Central differences in log θ: an O(h²) error of ~1e-8, far below identifiable effects.
    let h = 1e-4;
    let columns: Vec<Vec<f64>> = (trained.iter())
        .map(|&j| {
            let at = |s: f64| {
                let mut th = theta.clone();
                th[j] *= s.exp();
                accelerations(th)
            };
            let (up, down) = (at(h), at(-h));
            up.iter()
                .zip(&down)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        })
        .collect();
    let rows: Vec<Vec<f64>> = (0..columns.first().map_or(0, Vec::len))
        .map(|r| columns.iter().map(|c| c[r]).collect())
        .collect();
    let names: Vec<&str> = trained.iter().map(|&j| values[j].0.as_str()).collect();
    let picked: Vec<f64> = trained.iter().map(|&j| theta[j]).collect();
    let (products, _) = identify::identifiable_products(&rows, trained.len());
    products
        .iter()
        .map(|p| Identified {
            name: p.name(&names),
            value: p.value(&picked),
        })
        .collect()
}
