//! What a run's loss compares (docs/training.md#torque-loss): the states its one-step (or
//! window) prediction reaches against the recorded ones (`step`, the paper's loss), the
//! torques its manipulator equation asks for against the recorded inputs (`torque`, the
//! inverse-dynamics loss of identification), or both, each with its weight.

use serde::{Deserialize, Serialize};

use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::model::spec::ModelSpec;
use crate::physics::space::Space;
use crate::physics::urdf::delay::input_width;

/// The loss's weights: `"step"` is {step: 1, torque: 0}, `"torque"` {step: 0, torque: 1};
/// an object gives both (a weight left out is 0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "serde_json::Value", into = "serde_json::Value")]
pub struct Objective {
    pub step: f64,
    pub torque: f64,
}

const FORMS_CLI: &str = "step, torque or weights such as step=1,torque=0.01";
const FORMS: &str = "\"step\", \"torque\" or weights {\"step\": w, \"torque\": w}";

impl TryFrom<serde_json::Value> for Objective {
    type Error = String;

    fn try_from(v: serde_json::Value) -> std::result::Result<Self, String> {
        use serde_json::Value;
        match v {
            Value::String(s) if s == "step" => Ok(Self::STEP),
            Value::String(s) if s == "torque" => Ok(Self::TORQUE),
            Value::Object(map) => {
                let mut o = Self {
                    step: 0.0,
                    torque: 0.0,
                };
                for (key, w) in map {
                    let slot = match key.as_str() {
                        "step" => &mut o.step,
                        "torque" => &mut o.torque,
                        _ => return Err(format!("unknown weight `{key}`: expected {FORMS}")),
                    };
                    *slot = w
                        .as_f64()
                        .ok_or(format!("weight `{key}` must be a number"))?;
                }
                Ok(o)
            }
            other => Err(format!("expected {FORMS}, got {other}")),
        }
    }
}

impl From<Objective> for serde_json::Value {
    fn from(o: Objective) -> Self {
        if o == Objective::STEP {
            "step".into()
        } else if o == Objective::TORQUE {
            "torque".into()
        } else {
            serde_json::json!({"step": o.step, "torque": o.torque})
        }
    }
}

impl Default for Objective {
    fn default() -> Self {
        Self::STEP
    }
}

impl Objective {
    pub const STEP: Self = Self {
        step: 1.0,
        torque: 0.0,
    };
    pub const TORQUE: Self = Self {
        step: 0.0,
        torque: 1.0,
    };

    /// The command line's form: `step`, `torque` or weights such as `step=1,torque=0.01`.
    pub fn parse(s: &str) -> Result<Self> {
        let bad = |m: String| Error::invalid("loss", m);
        let value = match s.trim() {
            name @ ("step" | "torque") => serde_json::Value::from(name),
            pairs => {
                let mut map = serde_json::Map::new();
                for pair in pairs.split(',') {
                    let (k, v) = (pair.split_once('='))
                        .ok_or_else(|| bad(format!("`{pair}`: expected {FORMS_CLI}")))?;
                    let w: f64 =
                        (v.trim().parse()).map_err(|_| bad(format!("`{v}` is not a number")))?;
                    map.insert(k.trim().to_string(), w.into());
                }
                serde_json::Value::Object(map)
            }
        };
        Self::try_from(value).map_err(bad)
    }

    pub fn is_step(&self) -> bool {
        *self == Self::STEP
    }

    /// Weights that are finite, not negative and not both zero; a torque term only for a
    /// model with a mass matrix to form τ with.
    pub fn validate(&self, spec: &ModelSpec) -> Result<()> {
        let bad = |m: &str| Err(Error::invalid("training.loss", m));
        let weights = [self.step, self.torque];
        if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return bad("weights must be finite numbers ≥ 0");
        }
        if weights == [0.0, 0.0] {
            return bad("at least one of step and torque must have a weight above 0");
        }
        if self.step > 0.0 && spec.effort_delay().is_some() {
            return bad(
                "the robot's effort_delay is learnt from the torque loss, whose rows carry the \
                 efforts before each step: train it on \"torque\" (the model predicts under the \
                 effort as it acts, without the log's delay)",
            );
        }
        if self.torque > 0.0 && matches!(spec, ModelSpec::Naive { .. }) {
            return bad(
                "a naive model has no mass matrix to form the torque M q̈ + c + ∂V/∂q − F with; \
                 train it on \"step\", or choose a structured model",
            );
        }
        Ok(())
    }
}

/// Each transition's row of the torque loss, [q̄, q̇̄, q̈̄, inputs]: the midpoint of its step
/// (q ⊕ ½(q' ⊖ q), (q̇ + q̇')/2) and its mean acceleration (q̇' − q̇)/Δt_i, under the input
/// held over the step as the one-step loss reads it, or with `lags` > 0 the step's and that
/// many earlier samples of its trajectory with their times (`urdf::delay`'s block; a
/// trajectory's first sample stands for those before it). The midpoint's residual differs
/// from the equation's mean over the step by O(Δt²): 2e-4 relative at 100 Hz for a 1 Hz
/// motion.
pub fn torque_rows(ds: &Dataset, space: &Space, lags: usize) -> Vec<f64> {
    let (nq, nv, m) = (ds.nq, ds.nv, ds.m);
    let mut rows = Vec::with_capacity(ds.count() * (nq + 2 * nv + input_width(m, lags)));
    let mut first = 0;
    let starts = ds.segments();
    let mut segment = starts.iter().peekable();
    for i in 0..ds.count() {
        while let Some(s) = segment.next_if(|s| s.start <= i) {
            first = s.start;
        }
        let (q0, q1) = (&ds.q[i * nq..][..nq], &ds.q_next[i * nq..][..nq]);
        let (v0, v1) = (&ds.qdot[i * nv..][..nv], &ds.qdot_next[i * nv..][..nv]);
        let half: Vec<f64> = space.difference(q0, q1).iter().map(|d| 0.5 * d).collect();
        space.integrate_into(q0, 1.0, &half, &mut rows);
        rows.extend(v0.iter().zip(v1).map(|(a, b)| 0.5 * (a + b)));
        let dt = ds.step(i);
        rows.extend(v0.iter().zip(v1).map(|(a, b)| (b - a) / dt));
        if lags > 0 {
            // Sample k's age: the steps between it and this one's start.
            let sample = |k: usize| i.saturating_sub(k).max(first);
            rows.push(dt);
            let mut age = 0.0;
            for k in 1..=lags {
                age += ds.step(sample(k));
                rows.push(age);
            }
            (0..=lags).for_each(|k| rows.extend_from_slice(&ds.u[sample(k) * m..][..m]));
            continue;
        }
        rows.extend_from_slice(&ds.u[i * m..][..m]);
    }
    rows
}

/// The physical values a run with `least_squares` starts from: the robot's least-squares
/// solution on `ds`'s torque rows nearest `physical` (its defaults when none are given).
pub fn least_squares_start(
    config: &ModelConfig,
    physical: Option<Vec<f64>>,
    ds: &Dataset,
) -> Result<Vec<f64>> {
    let (urdf, gravity) = (config.spec.multibody()).ok_or_else(|| {
        Error::invalid(
            "training.least_squares",
            "needs a URDF template's mass matrix",
        )
    })?;
    let start = physical.unwrap_or_else(|| urdf.params().iter().map(|p| p.default).collect());
    let lags = config.effort_lags();
    let rows = torque_rows(ds, &config.space, lags);
    let ls = urdf.least_squares(&start, gravity, (&rows, lags), &|| false)?;
    tracing::info!(
        rank = ls.rank,
        projected = ?ls.projected,
        "least-squares start from {} transitions",
        ds.count()
    );
    Ok(ls.physical)
}
