//! What a run reports: the training report (losses, best epoch, the physical values and
//! their identifiability, the training checks) and the model file of the best parameters.
//! Both only read the trainer, so they can be taken at any point of a run.

use std::collections::BTreeMap;

use super::Trainer;
use crate::infer::Evaluator;
use crate::infer::energy_report::REPORT_SEED;
use crate::infer::horizons::end_of_training;
use crate::model::Model;
use crate::model::file::{ModelFile, stiffness_of};
use crate::model::params_io::import;
use crate::model::report::{Identified, TrainReport, identifiable, used_physical};
use crate::records::Warning;
use crate::train::warnings::{RunSummary, training_warnings};

/// The physical values the model's white-box parts use and training moves (a fixed one
/// stays put by design), by name.
pub(super) fn used_physical_values(model: &Model) -> Option<BTreeMap<String, f64>> {
    let t = model.config.template()?;
    let mut used = used_physical(t, &model.white_box_parts(), &model.physical_values()?);
    used.retain(|name, _| !t.params().iter().any(|p| p.fixed && p.name == *name));
    Some(used)
}

/// The physical parameters named in some identifiable combination (a name's tokens that are
/// parameter names), or None when no combination is known.
fn identified_parameters(
    physical: &BTreeMap<String, f64>,
    ident: &[Identified],
) -> Option<Vec<String>> {
    if ident.is_empty() {
        return None;
    }
    let named = |p: &str| {
        ident.iter().any(|c| {
            c.name
                .split(|ch: char| !(ch.is_alphanumeric() || ch == '_' || ch == '.'))
                .any(|token| token == p)
        })
    };
    Some(physical.keys().filter(|p| named(p)).cloned().collect())
}

impl Trainer {
    /// The report for the run so far.
    pub fn report(&self) -> TrainReport {
        let last = self.state.history.last();
        let seconds: f64 = self.state.history.iter().map(|h| h.seconds).sum();
        let parts = self.model.white_box_parts();
        let best = Model::from_parts(
            self.model.config.clone(),
            import(
                self.model.params.clone(),
                &self.state.best_params,
                &self.model.device(),
            )
            .expect("same structure"),
            &self.model.device(),
        );
        let best_values = best.physical_values();
        let (physical_parameters, ident) = match (self.model.config.template(), &best_values) {
            (Some(t), Some(values)) => (
                used_physical(t, &parts, values),
                identifiable(t, &parts, values),
            ),
            _ => Default::default(),
        };
        let identified = identified_parameters(&physical_parameters, &ident);
        let mut warnings = self.warnings(identified.as_deref());
        warnings.extend(best_values.and_then(|v| self.stiffness_at(&v)));
        TrainReport {
            model: self.state.model_name.clone(),
            spec: self.model.config.spec.clone(),
            epochs: self.state.epoch,
            train_loss: last.map_or(f64::NAN, |h| h.train_loss),
            val_loss: last.and_then(|h| h.val_loss),
            best_epoch: self.state.best_epoch,
            best_val_loss: self.best_val_loss(),
            best_val_loss_steps: self.best_val_loss_steps(),
            stopped_early: self.stopped_early(),
            seconds,
            samples_per_second: if self.state.train_seconds > 0.0 {
                self.state.samples_seen as f64 / self.state.train_seconds
            } else {
                0.0
            },
            physical_parameters,
            identifiable: ident,
            identifiability: self
                .model
                .config
                .template()
                .filter(|_| !self.model.white_box_parts().is_empty())
                .and_then(|t| t.identifiability_note())
                .map(str::to_string),
            history: self.state.history.clone(),
            horizon_errors: vec![],
            warnings,
            ensemble: None,
            energy: None,
        }
    }

    /// Whether the model's template forces, at its values now, are too stiff for its step
    /// (docs/robots.md#joint-forces): the CLI and the worker say so when a run starts, and
    /// the report at the values it ends with.
    pub fn stiffness_warning(&self) -> Option<Warning> {
        self.stiffness_at(&self.model.physical_values()?)
    }

    /// At q = 0 and the first few states of the training data.
    fn stiffness_at(&self, values: &[(String, f64)]) -> Option<Warning> {
        let values: Vec<f64> = values.iter().map(|(_, v)| *v).collect();
        stiffness_of(
            &self.model.config,
            &values,
            &self.data.train.configurations(8),
        )
    }

    /// The training checks on the run so far; `identified`: the parameters in some
    /// identifiable combination, when any are known.
    fn warnings(&self, identified: Option<&[String]>) -> Vec<Warning> {
        let physical = used_physical_values(&self.model).unwrap_or_default();
        training_warnings(&RunSummary {
            history: &self.state.history,
            best_loss: self.state.best_loss,
            baseline: self.data.baseline,
            initial_physical: self.state.initial_physical.as_ref(),
            physical: &physical,
            identified,
        })
    }

    /// The best parameters as a model file, with the report.
    pub fn best_file(&self) -> ModelFile {
        ModelFile::new(
            self.model.config.clone(),
            self.state.best_params.clone(),
            Some(self.report()),
        )
    }

    /// The best parameters as a model file, with the report: with validation trajectories,
    /// the report includes the model's open-loop error against horizon on them.
    pub fn model_file(&self) -> ModelFile {
        let mut file = self.best_file();
        self.add_horizon_errors(&mut file);
        self.add_energy_report(&mut file);
        file
    }

    /// A structured model's energy report on the training states, in `file`'s report (an
    /// ensemble's measured once, on its mean, like `add_horizon_errors`).
    pub(crate) fn add_energy_report(&self, file: &mut ModelFile) {
        let Ok(eval) = Evaluator::from_file(file) else {
            return;
        };
        if eval.check_energy().is_err() {
            return;
        }
        let found = eval.energy_report(self.data.train.states(), REPORT_SEED, &|| false);
        if let (Ok(Some(energy)), Some(report)) = (found, file.report.as_mut()) {
            report.energy = Some(energy);
        }
    }

    /// With validation trajectories, `file`'s open-loop error against horizon on them in its
    /// report: an ensemble's file (which this run's data is shared with) measured once, on its
    /// mean dynamics.
    pub(crate) fn add_horizon_errors(&self, file: &mut ModelFile) {
        let errors = (self.data.val.as_ref()).map(|v| end_of_training(file, &v.ds));
        if let (Some(Ok(errors)), Some(report)) = (errors, file.report.as_mut()) {
            report.horizon_errors = errors;
        }
    }
}
