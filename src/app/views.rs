//! What the core hands to adapters, so that REST bodies and gRPC messages never depend on
//! the store's rows (which carry keys, leases and blobs): the records every layer shares
//! (`crate::records`), and the one projection of a trained model.

use serde::Serialize;
use serde_json::{Value, json};

pub use crate::records::{Dataset, Job, JobState, Metric, Warning};
use crate::store::ModelRow;

/// A model: the one projection REST and gRPC both serve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Model {
    pub id: String,
    /// The job that trained it; `None` for an uploaded model.
    pub job_id: Option<String>,
    /// "trained" or "uploaded".
    pub origin: String,
    pub name: String,
    /// The model spec (JSON).
    pub spec: Value,
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    /// The training report's figures: epochs, losses, time, throughput, physical
    /// parameters and their identifiable combinations.
    pub metrics: Value,
    pub physical_parameters: Value,
    pub identifiable: Value,
    /// What the data cannot determine of the physical parameters beyond `identifiable`
    /// (null when the combinations say it all).
    pub identifiability: Value,
    pub sha256: String,
    pub created_at: String,
}

impl From<ModelRow> for Model {
    fn from(m: ModelRow) -> Self {
        let report: Value = serde_json::from_str(&m.report).unwrap_or(Value::Null);
        let mut metrics = json!({
            "epochs": report["epochs"],
            "train_loss": report["train_loss"],
            "val_loss": report["val_loss"],
            "best_epoch": report["best_epoch"],
            "best_val_loss": report["best_val_loss"],
            "seconds": report["seconds"],
            "samples_per_second": report["samples_per_second"],
            "physical_parameters": report["physical_parameters"],
            "identifiable": report["identifiable"],
            "warnings": report.get("warnings").cloned().unwrap_or_else(|| json!([])),
        });
        if let Some(made) = report.get("made") {
            // Not trained: how it was made instead of losses.
            metrics["made"] = made.clone();
        }
        Self {
            id: m.id,
            job_id: m.job_id,
            origin: m.origin,
            name: m.name,
            spec: serde_json::from_str(&m.spec).unwrap_or(Value::Null),
            n: m.n,
            m: m.m,
            dt: m.dt,
            // A model made from a template (no training) states its values in "made".
            physical_parameters: match &report["physical_parameters"] {
                Value::Null => report["made"]["physical_parameters"].clone(),
                p => p.clone(),
            },
            identifiable: report["identifiable"].clone(),
            identifiability: report["identifiability"].clone(),
            metrics,
            sha256: m.sha256,
            created_at: m.created_at,
        }
    }
}
