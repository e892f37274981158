//! What a run starts from, checked before any training: its settings, its initial physical
//! values and its data split (the service runs the same checks at submission).

use serde::{Deserialize, Serialize};

use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::model::spec::ModelSpec;
use crate::physics::integrator::Integrator;
use crate::physics::params::{Part, physical_problem};
use crate::physics::scaling::Scaling;
use crate::physics::space::Space;
use crate::sim::unknown_param;

use super::objective::Objective;

/// Training hyper-parameters; every field has the CLI's default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    pub epochs: usize,
    pub batch_size: usize,
    pub lr: f64,
    /// Weight of the velocity error in the loss.
    pub lambda: f64,
    /// Share of the data held out for validation when no validation set is given.
    pub val_fraction: f64,
    pub seed: u64,
    pub integrator: Integrator,
    /// Stop after this many epochs without a better validation loss (off when `None`).
    pub patience: Option<usize>,
    /// Which coordinates are angles (README "Periodic coordinates"); empty: the template's
    /// own `periodic`, else none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub periodic: Vec<bool>,
    /// Transitions per training window (README "Multi-step training"): the loss compares the
    /// model's own rollout of this many steps from a window's first state with the recorded
    /// states. 1 is the one-step loss (and is left out of files, which stay as they were).
    #[serde(skip_serializing_if = "is_one")]
    pub horizon: usize,
    /// Weight γ of each further step of a window (step k counts γ^(k−1)); 1 counts all alike.
    #[serde(skip_serializing_if = "is_unit")]
    pub discount: f64,
    /// Epochs trained on the one-step loss before windows of `horizon` take over (a
    /// curriculum: one-step epochs cost a `horizon`-th of a window epoch); 0 trains on windows
    /// from the start (and is left out of files).
    #[serde(skip_serializing_if = "is_zero")]
    pub one_step_epochs: usize,
    /// The learning rate of the epochs on windows of `horizon` > 1 (None: `lr`), so that a
    /// curriculum can take smaller steps once its loss runs through rollouts (left out of
    /// files when unset).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window_lr: Option<f64>,
    /// Members of an ensemble (README "Ensembles and uncertainty"), trained together from
    /// seeds derived from `seed`; 1 trains one model (and is left out of files).
    #[serde(skip_serializing_if = "is_one")]
    pub ensemble: usize,
    /// Whether each member of an ensemble trains on its own bootstrap resample of the
    /// training windows (left out of files when true, the default).
    #[serde(skip_serializing_if = "is_true")]
    pub bootstrap: bool,
    /// What the loss compares: the predicted states (`"step"`, the default, left out of
    /// files), the torques (`"torque"`) or both with weights (docs/training.md#torque-loss).
    #[serde(skip_serializing_if = "Objective::is_step")]
    pub loss: Objective,
    /// Start from the least-squares solution of the torque equation on the training data
    /// (a URDF robot's M; docs/robots.md#least-squares), nearest the initial values (left out
    /// of files when false, the default).
    #[serde(skip_serializing_if = "is_false")]
    pub least_squares: bool,
}

/// The most members an ensemble may have: each costs a model's training and inference. One
/// limit with what a model file may hold (a reader refuses a file over it).
pub const MAX_ENSEMBLE: usize = crate::model::file::MAX_MEMBERS;

fn is_true(b: &bool) -> bool {
    *b
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn is_one(h: &usize) -> bool {
    *h == 1
}

fn is_unit(g: &f64) -> bool {
    *g == 1.0
}

/// The longest training window: each step of a window keeps its integrator stages for the
/// backward pass, so memory grows with it (the job budget counts it), and beyond a few
/// hundred steps gradients through a rollout of a learned model explode.
pub const MAX_HORIZON: usize = 1000;

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            epochs: 500,
            batch_size: 256,
            lr: 1e-3,
            lambda: 1.0,
            val_fraction: 0.2,
            seed: 0,
            integrator: Integrator::Rk4,
            patience: None,
            periodic: vec![],
            horizon: 1,
            discount: 1.0,
            one_step_epochs: 0,
            window_lr: None,
            ensemble: 1,
            bootstrap: true,
            loss: Objective::STEP,
            least_squares: false,
        }
    }
}

impl TrainConfig {
    /// The learning rate of the epoch after `done` epochs: `window_lr` on windows.
    pub fn lr_at(&self, done: usize) -> f64 {
        match self.window_lr {
            Some(lr) if self.horizon_at(done) > 1 => lr,
            _ => self.lr,
        }
    }

    /// The horizon of the epoch after `done` epochs: 1 during the one-step epochs.
    pub fn horizon_at(&self, done: usize) -> usize {
        if done < self.one_step_epochs {
            1
        } else {
            self.horizon
        }
    }

    /// What this model must have for the loss and the start asked for.
    pub fn check_for(&self, spec: &ModelSpec) -> Result<()> {
        self.loss.validate(spec)?;
        if self.least_squares && spec.multibody().is_none() {
            return Err(Error::invalid(
                "training.least_squares",
                "needs a model whose mass matrix is a URDF template's (W-B, or V and F \
                 learned on a robot's M): its torques are linear in the robot's inertias",
            ));
        }
        Ok(())
    }

    pub fn validate(&self) -> Result<()> {
        let bad = |f: &str, m: &str| Err(Error::invalid(format!("training.{f}"), m));
        if self.epochs == 0 || self.epochs > 1_000_000 {
            return bad("epochs", "must be between 1 and 1000000");
        }
        if self.batch_size == 0 || self.batch_size > 1 << 22 {
            return bad("batch_size", "must be between 1 and 4194304");
        }
        for (field, lr) in [("lr", Some(self.lr)), ("window_lr", self.window_lr)] {
            if lr.is_some_and(|lr| !(lr.is_finite() && lr > 0.0 && lr <= 10.0)) {
                return bad(field, "must be a finite number in (0, 10]");
            }
        }
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return bad("lambda", "must be a finite number ≥ 0");
        }
        if !(self.val_fraction.is_finite() && (0.0..1.0).contains(&self.val_fraction)) {
            return bad("val_fraction", "must be in [0, 1)");
        }
        if !(1..=MAX_HORIZON).contains(&self.horizon) {
            return bad("horizon", &format!("must be between 1 and {MAX_HORIZON}"));
        }
        if !(self.discount.is_finite() && self.discount > 0.0 && self.discount <= 1.0) {
            return bad("discount", "must be a number in (0, 1]");
        }
        if self.one_step_epochs > 0 && self.one_step_epochs >= self.epochs {
            return bad(
                "one_step_epochs",
                "must be less than epochs (the epochs after it train on windows of horizon)",
            );
        }
        if !(1..=MAX_ENSEMBLE).contains(&self.ensemble) {
            return bad(
                "ensemble",
                &format!("must be between 1 and {MAX_ENSEMBLE} members"),
            );
        }
        if self.patience == Some(0) {
            return bad(
                "patience",
                "must be at least 1 (omit it to train every epoch)",
            );
        }
        Ok(())
    }
}

/// The (train, validation) sets for a model of `spec`: `val` when given, else a seeded split
/// of `data`.
pub(super) fn split_data(
    data: &Dataset,
    val: Option<&Dataset>,
    (cfg, spec): (&TrainConfig, &ModelSpec),
) -> Result<(Dataset, Option<Dataset>)> {
    if let Some(v) = val {
        if (v.nq, v.nv, v.m) != (data.nq, data.nv, data.m) {
            return Err(Error::invalid(
                "validation_data",
                "must have the same nq, nv and m as the training data",
            ));
        }
        // Steps of their own are integrated as they are (`HostData`): only uniform data must
        // share the rate.
        let uniform = v.steps.is_none() && data.steps.is_none();
        if uniform && (v.dt - data.dt).abs() > 1e-12 * data.dt {
            return Err(Error::invalid(
                "validation_data",
                format!("dt {} differs from the training data's {}", v.dt, data.dt),
            ));
        }
        return Ok((data.clone(), Some(v.clone())));
    }
    if cfg.val_fraction > 0.0 && data.count() > 1 {
        // Windows need whole trajectories, and so do the efforts before each step that a
        // delay reads: a row split would break every chain.
        let (t, v) = if cfg.horizon > 1 || spec.effort_delay().is_some() {
            data.split_by_trajectories(cfg.val_fraction, cfg.seed)
        } else {
            data.split(cfg.val_fraction, cfg.seed)
        };
        return Ok((t, Some(v)));
    }
    Ok((data.clone(), None))
}

/// Template parameter values from name=value pairs over the defaults.
pub fn physical_init(spec: &ModelSpec, init: &[(String, f64)]) -> Result<Option<Vec<f64>>> {
    let Some(t) = spec.template() else {
        if let Some((name, _)) = init.first() {
            return Err(Error::invalid(
                format!("init.{name}"),
                "initial values need a model with a template",
            ));
        }
        return Ok(None);
    };
    let mut values = t.defaults();
    for (name, v) in init {
        let i = t
            .index_of(name)
            .ok_or_else(|| unknown_param(t, name, &format!("init.{name}")))?;
        if let Some(m) = physical_problem(*v, t.params()[i].positive) {
            return Err(Error::invalid(format!("init.{name}"), m));
        }
        values[i] = *v;
    }
    // Positive parameters must start positive (they are trained in log space).
    crate::model::raw_physical(t, &values)?;
    Ok(Some(values))
}

/// The scalings training derives from `data` at the initial physical values; not finite
/// (data near the f64 range) is an error naming "data". The service checks a submission's
/// whole dataset with it, without copying the data into a split.
pub fn scaling(spec: &ModelSpec, physical: Option<&[f64]>, data: &Dataset) -> Result<Scaling> {
    let white_box_mass = spec.white_box_parts().contains(&Part::Mass);
    let mass = match (white_box_mass, spec.template(), physical) {
        (true, Some(t), Some(p)) => Some((t, p)),
        _ => None,
    };
    let scaling = Scaling::from_data(data, mass);
    if !scaling.is_finite() {
        return Err(Error::invalid(
            "data",
            "the data's statistics (means, spreads, accelerations) are not finite: values or \
             differences near the limits of f64; check units and dt",
        ));
    }
    Ok(scaling)
}

/// What [`prepare`] returns: the model configuration, the initial physical values, and the
/// training and validation data.
pub type Prepared = (ModelConfig, Option<Vec<f64>>, Dataset, Option<Dataset>);

/// A run's model configuration, initial physical values and data split, checked: what a new
/// run needs before its model exists (the service calls it at submission too). A scaling
/// that is not finite (data near the f64 range) is an error naming "data".
pub fn prepare(
    spec: &ModelSpec,
    init: &[(String, f64)],
    data: &Dataset,
    val: Option<&Dataset>,
    cfg: &TrainConfig,
) -> Result<Prepared> {
    cfg.validate()?;
    spec.validate()?;
    cfg.check_for(spec)?;
    spec.check_trainable()?;
    let space = run_space(spec, cfg, (data.nq, data.nv))?;
    spec.check_dims(&space, data.m)?;
    check_effort_lags(spec, data.dt)?;
    let physical = physical_init(spec, init)?;
    let (train_ds, val_ds) = split_data(data, val, (cfg, spec))?;
    crate::train::windows::check(&train_ds, cfg.horizon)?;
    let scaling = scaling(spec, physical.as_deref(), &train_ds)?;
    let config = ModelConfig {
        spec: spec.clone(),
        space,
        m: data.m,
        dt: data.dt,
        integrator: cfg.integrator,
        lambda: cfg.lambda,
        scaling,
    };
    Ok((config, physical, train_ds, val_ds))
}

/// A robot's effort delay spans at most `MAX_LAGS` of the data's steps: its torque rows carry
/// that many earlier samples each (checked before any row is built).
fn check_effort_lags(spec: &ModelSpec, dt: f64) -> Result<()> {
    use crate::physics::urdf::delay::{MAX_LAGS, lags};
    let Some(bound) = spec.effort_delay() else {
        return Ok(());
    };
    if lags(bound, dt) <= MAX_LAGS {
        return Ok(());
    }
    Err(Error::invalid(
        "template.effort_delay",
        format!(
            "a bound of {bound} s spans {} of the data's {dt} s steps; it may span at most \
             {MAX_LAGS} (a bound of {:.3e} s here): give the delay's real bound",
            lags(bound, dt),
            (MAX_LAGS - 1) as f64 * dt / 1.25
        ),
    ))
}

/// The run's configuration space for data of (nq, nv) widths: its template's when that has a
/// joint of nq ≠ nv (a rotation kept as a unit complex number), else n coordinates with the
/// run's angles (`periodic`). Data of other widths is refused naming what the space takes.
pub fn run_space(spec: &ModelSpec, cfg: &TrainConfig, (nq, nv): (usize, usize)) -> Result<Space> {
    let space = match spec.template().map(|t| t.space()) {
        Some(own) if !own.is_flat() => own,
        _ => Space::flat(nv, &periodic(spec, cfg, nv)?),
    };
    if (space.nq(), space.nv()) != (nq, nv) {
        return Err(Error::invalid(
            "dataset_id",
            format!(
                "the dataset has nq = {nq}, nv = {nv} (q and qdot's widths); the model's \
                 configuration space takes nq = {}, nv = {}",
                space.nq(),
                space.nv()
            ),
        ));
    }
    Ok(space)
}

/// The run's angles: the job's `periodic`, else its template's, one per coordinate; none
/// marked is stored as empty (the model of a run without angles is what it always was).
pub fn periodic(spec: &ModelSpec, cfg: &TrainConfig, n: usize) -> Result<Vec<bool>> {
    let (given, field) = if cfg.periodic.is_empty() {
        let own = spec.template().map(|t| t.periodic()).unwrap_or_default();
        (own, "template.periodic")
    } else {
        (cfg.periodic.clone(), "periodic")
    };
    if !given.is_empty() && given.len() != n {
        return Err(Error::invalid(
            field,
            format!(
                "expected {n} values (one per coordinate), got {}",
                given.len()
            ),
        ));
    }
    Ok(Space::flat(n, &given).periodic())
}
