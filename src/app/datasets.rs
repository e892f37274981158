//! Dataset uploads in the three accepted forms, validated and deduplicated by content.

use serde::Deserialize;
use serde_json::Value;

use super::App;
use super::views::Dataset as DatasetView;
use crate::data::Dataset;
use crate::error::{Error, Result};

/// One trajectory: T+1 states and T inputs.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Trajectory {
    q: Vec<Vec<f64>>,
    qdot: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
}

/// What a POST /v1/datasets body was.
pub enum Upload {
    Json(Value),
    Csv { text: String, dt: Option<f64> },
}

/// Trajectories `{"dt", "trajectories": [{"q", "qdot", "u"}]}` → transitions (x_t, u_t, x_{t+1}).
fn from_trajectories(value: &Value) -> Result<Dataset> {
    let dt = value
        .get("dt")
        .ok_or_else(|| Error::invalid("dt", "is required"))?
        .as_f64()
        .ok_or_else(|| Error::invalid("dt", "must be a number"))?;
    let trajs = value["trajectories"]
        .as_array()
        .ok_or_else(|| Error::invalid("trajectories", "must be an array of {q, qdot, u}"))?;
    let mut fields: [Vec<Value>; 5] = Default::default();
    for (k, t) in trajs.iter().enumerate() {
        let tr: Trajectory = serde_json::from_value(t.clone()).map_err(|e| {
            Error::invalid(
                format!("trajectories[{k}]"),
                format!("expected {{q, qdot, u}} arrays of number rows: {e}"),
            )
        })?;
        let steps = tr.u.len();
        if tr.q.len() != steps + 1 || tr.qdot.len() != steps + 1 {
            return Err(Error::invalid(
                format!("trajectories[{k}]"),
                format!(
                    "needs T+1 states for T inputs: q has {}, qdot {}, u {}",
                    tr.q.len(),
                    tr.qdot.len(),
                    steps
                ),
            ));
        }
        for t in 0..steps {
            let push = |f: &mut Vec<Value>, r: &Vec<f64>| f.push(Value::from(r.clone()));
            push(&mut fields[0], &tr.q[t]);
            push(&mut fields[1], &tr.qdot[t]);
            push(&mut fields[2], &tr.u[t]);
            push(&mut fields[3], &tr.q[t + 1]);
            push(&mut fields[4], &tr.qdot[t + 1]);
        }
    }
    let mut obj = serde_json::Map::new();
    obj.insert("dt".into(), Value::from(dt));
    for (name, f) in crate::data::FIELDS.iter().zip(fields) {
        obj.insert((*name).into(), Value::Array(f));
    }
    Dataset::from_json_value(&Value::Object(obj))
}

/// Names are shown to people in listings and logs: at most 200 characters (not bytes), and
/// no control characters (NUL, newlines) or bidirectional overrides, which can make a name
/// display as something it is not.
pub fn check_name(name: &str) -> Result<()> {
    const MAX: usize = 200;
    if name.chars().count() > MAX {
        return Err(Error::invalid(
            "name",
            format!("must be at most {MAX} characters"),
        ));
    }
    let bidi = |c: char| matches!(c, '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}');
    if let Some(c) = name.chars().find(|&c| c.is_control() || bidi(c)) {
        return Err(Error::invalid(
            "name",
            format!(
                "must not contain control or bidirectional-override characters (found U+{:04X})",
                c as u32
            ),
        ));
    }
    Ok(())
}

impl App {
    /// Validates and stores a dataset; the same arrays again return the stored one
    /// (`created = false`).
    pub async fn upload_dataset(
        &self,
        name: Option<String>,
        upload: Upload,
    ) -> Result<(DatasetView, bool)> {
        let (ds, body_name) = match upload {
            Upload::Csv { text, dt } => {
                let dt = dt.ok_or_else(|| Error::invalid("dt", "a CSV upload needs ?dt="))?;
                (Dataset::from_csv(&text, dt)?, None)
            }
            Upload::Json(value) => {
                let body_name = match value.get("name") {
                    None | Some(Value::Null) => None,
                    Some(Value::String(s)) => Some(s.clone()),
                    Some(_) => return Err(Error::invalid("name", "must be a string")),
                };
                let ds = if value.get("trajectories").is_some() {
                    from_trajectories(&value)?
                } else {
                    Dataset::from_json_value(&value)?
                };
                (ds, body_name)
            }
        };
        let name = name.or(body_name);
        if let Some(n) = &name {
            check_name(n)?;
        }
        let (row, created) = self.store.insert_dataset(name.as_deref(), &ds).await?;
        Ok((row.into(), created))
    }

    pub async fn dataset(&self, id: &str) -> Result<DatasetView> {
        self.store
            .get_dataset(id)
            .await?
            .map(DatasetView::from)
            .ok_or_else(|| Error::NotFound(format!("dataset {id}")))
    }

    /// Deletes a dataset unless a queued or running job uses it (409).
    pub async fn delete_dataset(&self, id: &str) -> Result<()> {
        self.store.delete_dataset(id).await
    }
}
