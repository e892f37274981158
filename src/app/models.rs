//! Trained models: listing, reading, the model file, deletion.

use serde_json::json;

use super::App;
use super::templates::off_executor;
use super::views::{ModelView, Stored};
use crate::error::{Error, Result};
use crate::infer::Evaluator;
use crate::model::ModelConfig;
use crate::model::file::ModelFile;
use crate::model::spec::ModelSpec;
use crate::physics::space::Joint;
use crate::records::DatasetInfo;
use crate::records::JobState;
use crate::store::{ModelRow, NewModel};
use crate::train::budget;

impl App {
    async fn model_row(&self, id: &str) -> Result<ModelRow> {
        self.store
            .get_model(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("model {id}")))
    }

    /// A model by its id, or by the id of the job that trained it (gRPC callers may name
    /// either); a job that has not succeeded is a failed precondition.
    pub async fn resolve_model(&self, id: &str) -> Result<ModelView> {
        self.resolve_model_row(id).await.map(ModelView::from)
    }

    /// `resolve_model` with the coordinates' names (GET /v1/models/{id}): naming them parses
    /// the model's template, off the executor, so only a read that shows them pays for it.
    pub async fn model_with_coordinates(&self, id: &str) -> Result<ModelView> {
        let mut view = self.resolve_model(id).await?;
        let (spec, n) = (view.spec.clone(), view.n.max(0) as usize);
        let (names, configuration) = off_executor(move || Ok(coordinate_names(spec, n))).await?;
        view.coordinates = Some(names);
        view.configuration = configuration;
        Ok(view)
    }

    pub(super) async fn resolve_model_row(&self, id: &str) -> Result<ModelRow> {
        if id.is_empty() {
            return Err(Error::invalid("model_id", "is required"));
        }
        if let Some(m) = self.store.get_model(id).await? {
            return Ok(m);
        }
        match self.store.get_job(id).await? {
            Some(job) if job.state == JobState::Succeeded => match job.info.model_id {
                Some(mid) => self.model_row(&mid).await,
                None => Err(Error::NotFound(format!("model of job {id}"))),
            },
            Some(job) => Err(Error::FailedPrecondition(format!(
                "job {id} is {}; it has no model until it succeeds",
                job.state.as_str()
            ))),
            None => Err(Error::NotFound(format!("model {id}"))),
        }
    }

    /// Stores a model file as it is (POST /v1/models): checked as the evaluator will read
    /// it and against the service's limits, identified by its bytes (the same file again
    /// returns the stored model, `created = false`). A bad file is a 422 naming what is wrong:
    /// `checksum` or `members` for a file that does not prove it is whole, else `body`. A file
    /// written before files carried a checksum is stored with that warning in its metrics
    /// (the upload's answer and every read of the model) and in the log.
    pub async fn upload_model(
        &self,
        name: Option<String>,
        bytes: Vec<u8>,
    ) -> Result<Stored<ModelView>> {
        let (max_dof, max_params) = (self.settings.max_dof, self.settings.max_model_params);
        // Reading checks an embedded template as an upload would: off the async executor.
        let (file, bytes) = super::templates::off_executor(move || {
            let bad = |e: Error| Error::Unprocessable {
                field: "body".into(),
                message: format!("not a usable model file: {e}"),
            };
            // An edited file's error names the field that shows it (`checksum`, `members`).
            let file = ModelFile::from_bytes(&bytes).map_err(|e| match e.field() {
                Some(field) => Error::Unprocessable {
                    field: field.to_string(),
                    message: format!("not a usable model file: {e}"),
                },
                None => bad(e),
            })?;
            check_model_file(&file, max_dof, max_params).map_err(bad)?;
            Ok((file, bytes))
        })
        .await?;
        if let Some(n) = &name {
            crate::names::check_name(n)?;
        }
        let name = name
            .or_else(|| file.report.as_ref().map(|r| r.model.clone()))
            .unwrap_or_else(|| {
                if file.made.is_some() {
                    "W-B"
                } else {
                    "uploaded"
                }
                .into()
            });
        crate::names::check_name_at("report.model", &name)?;
        let unchecked = file.unchecked_warning();
        if let Some(w) = &unchecked {
            tracing::warn!(model = %name, "uploaded model file: {}", w.message);
        }
        let report = match (&file.report, &file.made) {
            (Some(r), _) => {
                let mut r = r.clone();
                r.warnings.extend(unchecked);
                serde_json::to_string(&r).expect("json")
            }
            (None, Some(made)) => match unchecked {
                Some(w) => json!({ "made": made, "warnings": [w] }).to_string(),
                None => json!({ "made": made }).to_string(),
            },
            (None, None) => match unchecked {
                Some(w) => json!({ "warnings": [w] }).to_string(),
                None => "null".into(),
            },
        };
        let spec = serde_json::to_string(&file.config.spec).expect("json");
        let (store, n, nq, m, dt) = (
            self.store.clone(),
            file.config.nv() as i64,
            file.config.nq() as i64,
            file.config.m as i64,
            file.config.dt,
        );
        let (row, created) = super::detached(async move {
            let new = NewModel {
                name: &name,
                n,
                nq,
                m,
                dt,
                spec: &spec,
                report: &report,
                file: &bytes,
            };
            store.insert_model(new).await
        })
        .await?;
        Ok(Stored {
            item: row.into(),
            created,
        })
    }

    pub async fn model_file(&self, id: &str) -> Result<Vec<u8>> {
        self.store
            .model_file(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("model {id}")))
    }

    /// The identified robot of a URDF model (GET /v1/models/{id}/urdf): its template's
    /// document with the learned inertial and joint values written in. Reading the file
    /// parses its robot, and the export reads its result back: off the async executor.
    pub async fn model_urdf(&self, id: &str) -> Result<String> {
        let bytes = self.model_file(id).await?;
        super::templates::off_executor(move || ModelFile::from_bytes(&bytes)?.urdf()).await
    }

    pub async fn list_models(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<ModelView>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("models", token)?;
        let (items, more) = self.store.list_models(before, size).await?;
        let next = super::paging::after("models", &items, more, |m| m.seq);
        Ok((items.into_iter().map(ModelView::from).collect(), next))
    }

    pub async fn list_datasets(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<DatasetInfo>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("datasets", token)?;
        let items = self.store.list_datasets(before, size).await?;
        let next = super::paging::next("datasets", &items, size, |d| d.seq);
        Ok((items.into_iter().map(DatasetInfo::from).collect(), next))
    }
}

/// A model file the service can serve: a valid spec for its dimensions, finite scalings and
/// values, a Δt in range, at most `max_params` trainable parameters (`--max-model-params`, as
/// for a job), and every value its spec needs in the shape the spec gives it (what
/// `Evaluator::from_file` reads).
fn check_model_file(file: &ModelFile, max_dof: usize, max_params: usize) -> Result<()> {
    let c = &file.config;
    c.spec.validate()?;
    let (nq, nv) = (c.nq(), c.nv());
    if nv == 0 || c.m == 0 || nv > max_dof {
        return Err(Error::invalid(
            "config",
            format!(
                "nv = {nv} and m = {} must be ≥ 1 (nv ≤ {max_dof}, --max-dof)",
                c.m
            ),
        ));
    }
    c.spec.check_dims(&c.space, c.m)?;
    let (lo, hi) = crate::data::DT_RANGE;
    if !(c.dt.is_finite() && (lo..=hi).contains(&c.dt)) {
        return Err(Error::invalid(
            "config.dt",
            format!("must be in [{lo:e}, {hi}] s"),
        ));
    }
    file.to_bytes()?; // finite scalings and values
    let sc = &c.scaling;
    let per_velocity = [
        &sc.qdot_mean,
        &sc.qdot_std,
        &sc.acc_mean,
        &sc.acc_std,
        &sc.force_scale,
    ];
    let sized = [&sc.q_mean, &sc.q_std].iter().all(|v| v.len() == nq)
        && per_velocity.iter().all(|v| v.len() == nv)
        && [&sc.u_mean, &sc.u_std].iter().all(|v| v.len() == c.m);
    let spreads = [&sc.q_std, &sc.qdot_std, &sc.u_std, &sc.acc_std];
    // The evaluator divides by the spreads: a zero would make every answer non-finite.
    if !sized || spreads.iter().any(|v| v.iter().any(|s| *s <= 0.0)) {
        return Err(Error::invalid(
            "config.scaling",
            "needs nq values per configuration statistic (q_mean, q_std), nv per velocity one, \
             m per input one, standard deviations > 0",
        ));
    }
    // Counted from the spec, before the evaluator copies the weights; the evaluator then
    // holds the file to the spec, so this is the file's count too.
    let params = trainable_params(c);
    if params > max_params {
        return Err(Error::invalid(
            "config.spec",
            format!(
                "the model has {params} trainable parameters, over the limit of {max_params} \
                 (--max-model-params)"
            ),
        ));
    }
    Evaluator::from_file(file)?; // every value the spec needs, each of its shape
    Ok(())
}

/// Trainable parameters of a model of this configuration, counted as a job's are
/// (`train::budget`): its networks' and other learned values, and its template's physical
/// values when some part is white-box.
fn trainable_params(c: &ModelConfig) -> usize {
    let physical = match c.spec.template() {
        Some(t) if !c.spec.white_box_parts().is_empty() => t.params().len(),
        _ => 0,
    };
    let dims = budget::Dims {
        n: c.nv(),
        m: c.m,
        angles: c.q_inputs() - c.nv(),
    };
    budget::estimate(&c.spec, dims, 0, 0, physical).params
}

/// The names of a stored spec's n coordinates: its template's, else q1 … qn (a spec that no
/// longer reads is named like one without a template); and where its template's space has a
/// joint of nq ≠ nv, the names of q's nq values (a rotation θ's as cos(θ) and sin(θ)).
fn coordinate_names(spec: serde_json::Value, n: usize) -> (Vec<String>, Option<Vec<String>>) {
    let template = serde_json::from_value::<ModelSpec>(spec)
        .ok()
        .and_then(|s| s.template().cloned());
    let names = (template.as_ref())
        .map(|t| t.coordinates())
        .filter(|names| names.len() == n)
        .unwrap_or_else(|| (1..=n).map(|i| format!("q{i}")).collect());
    let space = template
        .map(|t| t.space())
        .filter(|s| !s.is_flat() && s.nv() == n);
    let configuration = space.map(|s| {
        (s.placed())
            .flat_map(|p| match p.joint {
                Joint::Circle => {
                    let name = &names[p.v];
                    vec![format!("cos({name})"), format!("sin({name})")]
                }
                Joint::Real | Joint::Angle => vec![names[p.v].clone()],
            })
            .collect()
    });
    (names, configuration)
}
