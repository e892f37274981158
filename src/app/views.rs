//! What the core hands to adapters: views of stored records, so that REST bodies and gRPC
//! messages never depend on the store's rows (which carry keys, leases and blobs).
//! `JobState` is the queue's own vocabulary, re-exported as part of the core's.

use serde::Serialize;
use serde_json::{Value, json};

pub use crate::store::JobState;
use crate::store::{DatasetRow, JobRow, MetricRow, ModelRow};

/// A dataset's metadata.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Dataset {
    pub id: String,
    pub name: Option<String>,
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    pub count: i64,
    pub sha256: String,
    pub created_at: String,
}

impl From<DatasetRow> for Dataset {
    fn from(r: DatasetRow) -> Self {
        Self {
            id: r.id,
            name: r.name,
            n: r.n,
            m: r.m,
            dt: r.dt,
            count: r.count,
            sha256: r.sha256,
            created_at: r.created_at,
        }
    }
}

/// A training job and its progress.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Job {
    pub id: String,
    pub state: JobState,
    /// Last completed epoch, counting from 1 (0 before the first).
    pub epoch: i64,
    pub epochs: i64,
    /// The epoch of the last checkpoint (a job resumes from it after a crash).
    pub checkpoint_epoch: i64,
    pub train_loss: Option<f64>,
    pub val_loss: Option<f64>,
    pub best_val_loss: Option<f64>,
    pub attempt: i64,
    pub error: Option<String>,
    pub model_id: Option<String>,
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
}

impl From<JobRow> for Job {
    fn from(r: JobRow) -> Self {
        Self {
            id: r.id,
            state: r.state,
            epoch: r.epoch,
            epochs: r.epochs,
            checkpoint_epoch: r.checkpoint_epoch,
            train_loss: r.train_loss,
            val_loss: r.val_loss,
            best_val_loss: r.best_val_loss,
            attempt: r.attempt,
            error: r.error,
            model_id: r.model_id,
            dataset_id: r.dataset_id,
            validation_dataset_id: r.validation_dataset_id,
            created_at: r.created_at,
            started_at: r.started_at,
            finished_at: r.finished_at,
        }
    }
}

/// One epoch's losses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Metric {
    pub epoch: i64,
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    pub seconds: f64,
}

impl From<MetricRow> for Metric {
    fn from(r: MetricRow) -> Self {
        Self {
            epoch: r.epoch,
            train_loss: r.train_loss,
            val_loss: r.val_loss,
            seconds: r.seconds,
        }
    }
}

/// A trained model: the one projection REST and gRPC both serve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Model {
    pub id: String,
    pub job_id: String,
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
    pub sha256: String,
    pub created_at: String,
}

impl From<ModelRow> for Model {
    fn from(m: ModelRow) -> Self {
        let report: Value = serde_json::from_str(&m.report).unwrap_or(Value::Null);
        let metrics = json!({
            "epochs": report["epochs"],
            "train_loss": report["train_loss"],
            "val_loss": report["val_loss"],
            "best_epoch": report["best_epoch"],
            "best_val_loss": report["best_val_loss"],
            "seconds": report["seconds"],
            "samples_per_second": report["samples_per_second"],
            "physical_parameters": report["physical_parameters"],
            "identifiable": report["identifiable"],
        });
        Self {
            id: m.id,
            job_id: m.job_id,
            name: m.name,
            spec: serde_json::from_str(&m.spec).unwrap_or(Value::Null),
            n: m.n,
            m: m.m,
            dt: m.dt,
            physical_parameters: report["physical_parameters"].clone(),
            identifiable: report["identifiable"].clone(),
            metrics,
            sha256: m.sha256,
            created_at: m.created_at,
        }
    }
}
