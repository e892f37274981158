//! What the core hands to adapters besides the records every layer shares (`crate::records`),
//! so that REST bodies and gRPC messages never depend on the store's rows (which carry keys,
//! leases and blobs): the one projection of a trained model, and what a submission stored.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::model::file::Made;
use crate::model::report::{EnergyReport, EnsembleReport, HorizonError, Identified, TrainReport};
use crate::records::Warning;
use crate::store::ModelRow;

/// What a submission or an upload stored: the item, and whether this request created it
/// (false: an earlier request with the same idempotency key, or the same bytes, had).
#[derive(Debug, Clone, PartialEq)]
pub struct Stored<T> {
    pub item: T,
    pub created: bool,
}

/// A model: the one projection REST and gRPC both serve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelView {
    pub id: String,
    /// The job that trained it; `None` for an uploaded model.
    pub job_id: Option<String>,
    /// "trained" or "uploaded".
    pub origin: String,
    pub name: String,
    /// The model spec (JSON).
    pub spec: Value,
    /// Configuration values: a state is [q, v], nq + nv values.
    pub nq: i64,
    /// Velocities (the degrees of freedom): accelerations and forces are nv wide, Linearize's
    /// A 2nv × 2nv.
    pub nv: i64,
    /// Deprecated: `nv` (equal to nq and nv for a model whose every joint is one number).
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    /// The training report's figures: epochs, losses, time, throughput, physical
    /// parameters and their identifiable combinations (see [`Metrics`]).
    pub metrics: Value,
    pub physical_parameters: Option<BTreeMap<String, f64>>,
    pub identifiable: Option<Vec<Identified>>,
    /// What the data cannot determine of the physical parameters beyond `identifiable`
    /// (null when the combinations say it all).
    pub identifiability: Option<String>,
    pub sha256: String,
    pub created_at: String,
    /// The coordinates' names (a URDF's joints, a formula's coordinates, else q1, q2, …):
    /// one model's read only, since naming them parses its template.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coordinates: Option<Vec<String>>,
    /// The names of q's nq values where they are not the coordinates (nq ≠ nv: a rotation θ
    /// kept as cos(θ) and sin(θ)); read with `coordinates`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub configuration: Option<Vec<String>>,
}

/// What a model row's report holds: a trained model's report, or how a model that was not
/// trained was made, or neither (the text "null"); the latter two with the warnings of its
/// upload (a file without a checksum, `App::upload_model`).
#[derive(Deserialize)]
#[serde(untagged)]
enum StoredReport {
    Trained(Box<TrainReport>),
    Made {
        made: Made,
        #[serde(default)]
        warnings: Vec<Warning>,
    },
    Uploaded {
        warnings: Vec<Warning>,
    },
}

/// A model's `metrics`: every key present (null when the model has no such figure), and
/// `made` only for a model made rather than trained. Kept a JSON value in the view: its keys
/// come out sorted, as clients have always read them.
#[derive(Serialize, Default)]
struct Metrics<'a> {
    epochs: Option<usize>,
    train_loss: Option<f64>,
    val_loss: Option<f64>,
    best_epoch: Option<usize>,
    best_val_loss: Option<f64>,
    best_val_loss_steps: Option<usize>,
    seconds: Option<f64>,
    samples_per_second: Option<f64>,
    physical_parameters: Option<&'a BTreeMap<String, f64>>,
    identifiable: Option<&'a [Identified]>,
    /// Open-loop error against horizon on the validation trajectories (README "Multi-step
    /// training"); empty without them.
    horizon_errors: &'a [HorizonError],
    warnings: &'a [Warning],
    #[serde(skip_serializing_if = "Option::is_none")]
    made: Option<&'a Made>,
    /// An ensemble's members (their validation losses, physical values) and its physical
    /// values' mean and spread; absent for a single model.
    #[serde(skip_serializing_if = "Option::is_none")]
    ensemble: Option<&'a EnsembleReport>,
    /// Energy drift and passivity on the training data (README "Energy and power"), or the
    /// report last measured on request against a dataset; null for a naive model and one
    /// trained before the report existed, until asked for.
    energy: Option<&'a EnergyReport>,
}

impl<'a> Metrics<'a> {
    fn of(report: Option<&'a StoredReport>) -> Self {
        match report {
            None => Self::default(),
            Some(StoredReport::Made { made, warnings }) => Self {
                made: Some(made),
                warnings,
                ..Self::default()
            },
            Some(StoredReport::Uploaded { warnings }) => Self {
                warnings,
                ..Self::default()
            },
            Some(StoredReport::Trained(r)) => Self {
                epochs: Some(r.epochs),
                train_loss: Some(r.train_loss),
                val_loss: r.val_loss,
                best_epoch: Some(r.best_epoch),
                best_val_loss: r.best_val_loss,
                best_val_loss_steps: r.best_val_loss_steps,
                seconds: Some(r.seconds),
                samples_per_second: Some(r.samples_per_second),
                physical_parameters: Some(&r.physical_parameters),
                identifiable: Some(&r.identifiable),
                horizon_errors: &r.horizon_errors,
                warnings: &r.warnings,
                made: None,
                ensemble: r.ensemble.as_ref(),
                energy: r.energy.as_ref(),
            },
        }
    }
}

impl From<ModelRow> for ModelView {
    fn from(m: ModelRow) -> Self {
        // The store writes what it was given: a report that does not read is no report.
        let report: Option<StoredReport> = serde_json::from_str(&m.report).unwrap_or(None);
        let mut metrics =
            serde_json::to_value(Metrics::of(report.as_ref())).expect("metrics serialize");
        // A report measured on request (against a dataset it names) is the latest word.
        let asked: Option<EnergyReport> =
            (m.energy.as_deref()).and_then(|e| serde_json::from_str(e).ok());
        if let Some(energy) = asked {
            metrics["energy"] = serde_json::to_value(energy).expect("reports serialize");
        }
        let (physical_parameters, identifiable, identifiability) = match report {
            None | Some(StoredReport::Uploaded { .. }) => (None, None, None),
            // A model made from a template (no training) states its values in "made".
            Some(StoredReport::Made { made, .. }) => (Some(made.physical_parameters), None, None),
            Some(StoredReport::Trained(r)) => (
                Some(r.physical_parameters),
                Some(r.identifiable),
                r.identifiability,
            ),
        };
        Self {
            id: m.id,
            job_id: m.job_id,
            origin: m.origin,
            name: m.name,
            spec: serde_json::from_str(&m.spec).unwrap_or(Value::Null),
            nq: m.nq.unwrap_or(m.n),
            nv: m.n,
            n: m.n,
            m: m.m,
            dt: m.dt,
            metrics,
            physical_parameters,
            identifiable,
            identifiability,
            sha256: m.sha256,
            created_at: m.created_at,
            coordinates: None,
            configuration: None,
        }
    }
}
