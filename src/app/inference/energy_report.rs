//! `POST /v1/models/{id}/energy-report`: a model's energy report (`infer::energy_report`)
//! measured against a stored dataset, for a model with no training data here (an uploaded
//! file) or on other data than it trained on; stored with the model, and shown in its view.

use serde::Deserialize;

use super::Class;
use crate::app::App;
use crate::app::requests::deadline;
use crate::error::{Error, Result};
use crate::infer::energy_report::REPORT_SEED;
use crate::model::report::EnergyReport;

/// How long a report may compute unless the request says otherwise, and at most: 64
/// rollouts of 1000 steps and 4096 states take well under a second for MVF, minutes only for
/// a large robot.
const DEFAULT_SECONDS: f64 = 120.0;
const MAX_SECONDS: f64 = 600.0;

#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EnergyReportRequest {
    /// A stored dataset of the model's n and m whose states the report draws.
    pub dataset_id: String,
    /// Seconds the report may compute (default 120, at most 600): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

impl App {
    /// The model's energy report on a dataset's states, stored with the model.
    pub async fn energy_report(&self, id: &str, req: EnergyReportRequest) -> Result<EnergyReport> {
        let deadline = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let eval = self.evaluator(id).await?;
        eval.check_energy()?;
        let model = self.resolve_model_row(id).await?;
        let info = self
            .dataset_for_model(&req.dataset_id, &eval.config)
            .await?;
        // The report's work is fixed (64 rollouts of 1000 steps, at most 4096 states): only
        // the dataset's memory needs admitting, which reading it does.
        let loaded = self.read_dataset(&info).await?;
        let mut report = self
            .heavy_until(Class::Long, "energy report", Some(deadline), move |stop| {
                let (states, _) = loaded.ds().states();
                eval.energy_report(&states, REPORT_SEED, stop).transpose()
            })
            .await??;
        report.dataset_id = Some(req.dataset_id);
        let json = serde_json::to_string(&report).expect("reports serialize");
        if !self.store.set_model_energy(&model.id, &json).await? {
            return Err(Error::NotFound(format!("model {}", model.id)));
        }
        Ok(report)
    }
}
