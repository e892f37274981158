//! POST /v1/models/{id}/evaluate: a model's open-loop error against horizon on a stored
//! trajectory dataset (`infer::horizons`), its cost (window starts × horizon) admitted before
//! it computes, stopped at its deadline.

use serde::{Deserialize, Serialize};

use super::{Class, Cost};
use crate::app::App;
use crate::app::requests::deadline;
use crate::data::trajectories;
use crate::error::{Error, Result};
use crate::infer::horizons::{HorizonError, check_horizons, cost, horizon_errors, segments_cost};
use crate::infer::limits::Pass;

/// How long an evaluation may compute unless the request says otherwise, and at most.
const DEFAULT_SECONDS: f64 = 60.0;
const MAX_SECONDS: f64 = 600.0;

/// Model steps one evaluation may take, per step of `--max-rollout-steps` (100 000 steps
/// by default: 10⁷ steps, ~10 s of MVF on one core).
const STEPS_PER_ROLLOUT_STEP: usize = 100;

#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EvaluateRequest {
    /// A stored dataset with trajectories (uploaded in trajectory form, or chained rows).
    pub dataset_id: String,
    /// Horizons in steps, e.g. [1, 10, 50, 100] (at most 32, each ≤ --max-rollout-steps).
    pub horizons: Vec<usize>,
    /// Seconds the evaluation may compute (default 60, at most 600): past it, 504.
    #[serde(default)]
    pub timeout_seconds: Option<f64>,
}

#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct Evaluation {
    pub model_id: String,
    pub dataset_id: String,
    /// One per horizon, shortest first.
    pub items: Vec<HorizonError>,
}

impl App {
    pub async fn evaluate(&self, model_id: &str, req: EvaluateRequest) -> Result<Evaluation> {
        let deadline = deadline(req.timeout_seconds, DEFAULT_SECONDS, MAX_SECONDS)?;
        let max_steps = self.settings.max_rollout_steps;
        let horizons = check_horizons(&req.horizons, max_steps)?;
        let eval = self.evaluator(model_id).await?;
        let (nx, m) = (eval.config.nx(), eval.config.m);
        let id = req.dataset_id.clone();
        let info = self.dataset_for_model(&id, &eval.config).await?;
        let longest = *horizons.last().expect("checked: at least one");
        let rows = info.count as usize;
        // Every start's state and inputs, its errors at each horizon, and the work of the
        // chunks being stepped (as Predict counts it): admitted before any row is read.
        let row_bytes = 8 * (2 * nx + m) + 16 * horizons.len();
        let work =
            rows.min(2 * eval.chunk_states(Pass::Step)) * eval.work_bytes_per_state(Pass::Step);
        self.admit(
            "horizons",
            &Cost {
                response_bytes: 100 * horizons.len(),
                memory_bytes: rows.saturating_mul(row_bytes) + work,
            },
        )?;
        // Cheap bound first: every row rolled out to the longest horizon; then the windows'
        // own count, from uploaded boundaries without the rows, else from the rows' chains.
        let limit = max_steps.saturating_mul(STEPS_PER_ROLLOUT_STEP);
        let mut loaded = None;
        if rows.saturating_mul(longest) > limit {
            let steps = match self.store.dataset_trajectories(&id).await?.flatten() {
                Some(lengths) => segments_cost(&trajectories::from_lengths(&lengths), longest),
                None => {
                    let read = self.read_dataset(&info).await?;
                    let (read, steps) = tokio::task::spawn_blocking(move || {
                        let steps = cost(read.ds(), longest);
                        (read, steps)
                    })
                    .await
                    .map_err(|e| Error::Internal(format!("costing the evaluation: {e}")))?;
                    loaded = Some(read);
                    steps
                }
            };
            if steps > limit {
                return Err(Error::ResourceExhausted(format!(
                    "{steps} model steps (window starts × horizon) is over the limit of {limit} \
                     (100 × --max-rollout-steps): fewer or shorter horizons, or less data"
                )));
            }
        }
        let loaded = match loaded {
            Some(read) => read,
            None => self.read_dataset(&info).await?,
        };
        let items = self
            .heavy_until(Class::Long, "evaluation", Some(deadline), move |stop| {
                horizon_errors(&eval, loaded.ds(), &horizons, stop)
            })
            .await?;
        Ok(Evaluation {
            model_id: model_id.into(),
            dataset_id: req.dataset_id,
            items,
        })
    }
}
