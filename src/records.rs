//! What the service keeps about datasets and jobs, as every layer sees it: the store reads
//! and writes these records (its rows add keys, leases and blobs around them), the core hands
//! them to adapters as they are. `JobState` is the queue's vocabulary.

use serde::Serialize;

// The arrays themselves are a `data::Dataset`; the API schema keeps the name clients know.
/// A dataset's metadata.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema, sqlx::FromRow)]
#[schema(as = Dataset)]
pub struct DatasetInfo {
    pub id: String,
    pub name: Option<String>,
    /// Configuration values per row (q, q_next).
    pub nq: i64,
    /// Velocities per row (qdot, qdot_next): nq unless a joint's configuration is not its
    /// velocity (a rotation kept as a unit complex number).
    pub nv: i64,
    /// Deprecated: `nv` (equal to nq and nv for a dataset whose q and qdot are one width).
    pub n: i64,
    pub m: i64,
    pub dt: f64,
    pub count: i64,
    pub sha256: String,
    pub created_at: String,
    /// What the sanity checks at upload found (see README, "Dataset warnings").
    #[sqlx(json)]
    pub warnings: Vec<Warning>,
}

impl DatasetInfo {
    /// Configuration values per row (q, q_next).
    pub fn nq(&self) -> usize {
        self.nq as usize
    }

    /// Velocities per row (qdot, qdot_next).
    pub fn nv(&self) -> usize {
        self.nv as usize
    }
}

pub use graybox_core::records::Warning;

// `model` and `training` are not columns: `store::jobs` reads them from the stored request.
/// A training job and its progress.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema, sqlx::FromRow)]
pub struct Job {
    pub id: String,
    #[sqlx(try_from = "String")]
    pub state: JobState,
    /// The name it was given (its model takes it); null when none was.
    #[sqlx(skip)]
    pub name: Option<String>,
    /// The model as submitted: a paper name ("MVF"), or "custom" for a spec object.
    #[sqlx(skip)]
    pub model: String,
    /// The training settings it runs with (epochs, batch_size, lr, …), defaults filled in.
    #[schema(value_type = Object)]
    #[sqlx(skip)]
    pub training: serde_json::Value,
    /// Last completed epoch, counting from 1 (0 before the first).
    pub epoch: i64,
    pub epochs: i64,
    /// The epoch of the last checkpoint: a job resumes from it after a crash. Checkpoints are
    /// taken every `--checkpoint-every` epochs (10) before the last (the finished model is
    /// stored whole instead), so a finished 20-epoch job says 10.
    pub checkpoint_epoch: i64,
    pub train_loss: Option<f64>,
    pub val_loss: Option<f64>,
    /// A multi-step job's last validation loss over windows of its horizon (README
    /// "Multi-step training"); `val_loss` is the one-step loss.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub val_horizon_loss: Option<f64>,
    /// The best validation loss so far: over windows of `best_val_loss_steps` steps (a
    /// multi-step job whose validation set has trajectories that long; see `val_horizon_loss`),
    /// else the one-step loss (`best_val_loss_steps` 1).
    pub best_val_loss: Option<f64>,
    #[sqlx(skip)]
    pub best_val_loss_steps: Option<i64>,
    pub attempt: i64,
    pub error: Option<String>,
    pub model_id: Option<String>,
    pub dataset_id: String,
    pub validation_dataset_id: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    /// The training checks' findings, set when the job finishes (see README, "Training
    /// warnings").
    #[sqlx(json)]
    pub warnings: Vec<Warning>,
}

/// One epoch's losses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema, sqlx::FromRow)]
pub struct Metric {
    pub epoch: i64,
    pub train_loss: f64,
    pub val_loss: Option<f64>,
    /// The validation loss over windows of a multi-step job's horizon.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub val_horizon_loss: Option<f64>,
    pub seconds: f64,
    /// An ensemble's: the members' standard deviation of `train_loss` and `val_loss`, which
    /// are then the members' means (README "Ensembles and uncertainty").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub train_loss_std: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub val_loss_std: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 5] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|j| j.as_str() == s)
    }

    pub fn is_final(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }
}

/// A stored job's `state` column.
impl TryFrom<String> for JobState {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Self::parse(&s).ok_or_else(|| format!("unknown job state {s}"))
    }
}
