//! Templates as a resource: a user's mechanism uploaded once (POST /v1/templates) and named by
//! jobs by id. A job's spec embeds the whole template, so a model never depends on the row.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::App;
use super::views::Stored;
use crate::error::{Error, Result};
use crate::physics::templates::Template;
use crate::physics::urdf::UrdfTemplate;
use crate::store::{NewTemplate, TemplateRow};

/// A stored template as REST serves it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct TemplateView {
    pub id: String,
    /// "formula" or "urdf".
    pub kind: String,
    pub name: String,
    pub n: i64,
    pub m: i64,
    #[serde(flatten)]
    pub summary: Summary,
    /// The document as stored (canonical: sorted parameters, defaults filled in); only on
    /// `GET /v1/templates/{id}` and uploads, not in lists.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub document: Option<Value>,
    pub sha256: String,
    pub created_at: String,
}

/// What a template is to a user choosing one: its coordinates, inputs and starting values.
/// Stored beside the document when it is uploaded, so a list needs neither.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Summary {
    pub coordinates: Vec<String>,
    pub inputs: Vec<String>,
    pub periodic: Vec<bool>,
    /// `{name, value, positive}`: the physical values a job starts from (`init` sets them by
    /// name).
    #[schema(value_type = Vec<Object>)]
    pub parameters: Vec<Value>,
    /// What motion data can and cannot determine of these values (URDF robots).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identifiability: Option<String>,
}

impl Summary {
    fn of(t: &Template) -> Self {
        let n = t.n();
        let periodic = t.periodic();
        Self {
            coordinates: t.coordinates(),
            inputs: t.inputs(),
            periodic: if periodic.is_empty() {
                vec![false; n]
            } else {
                periodic
            },
            parameters: t
                .params()
                .iter()
                .map(|p| {
                    let mut v = json!({"name": p.name, "value": p.default, "positive": p.positive});
                    // A bounded parameter (a joint's damping and friction, a delay) says its bounds.
                    if let Some(min) = p.min {
                        v["min"] = json!(min);
                    }
                    if let Some(max) = p.max {
                        v["max"] = json!(max);
                    }
                    if p.fixed {
                        v["fixed"] = json!(true);
                    }
                    v
                })
                .collect(),
            identifiability: t.identifiability_note().map(str::to_string),
        }
    }
}

impl TemplateView {
    /// The row's view, with its document or without; a row stored before summaries has its
    /// summary computed from the document (slow: off the async executor).
    fn of(r: TemplateRow, with_document: bool) -> Result<Self> {
        let corrupt = |e: &dyn std::fmt::Display| Error::corrupt(format!("template {}", r.id), e);
        let summary = match (&r.summary, &r.document) {
            (Some(s), _) => serde_json::from_str(s).map_err(|e| corrupt(&e))?,
            (None, Some(doc)) => Summary::of(&Template::from_json(doc).map_err(|e| corrupt(&e))?),
            (None, None) => return Err(corrupt(&"neither a summary nor a document")),
        };
        let document = match r.document {
            Some(doc) if with_document => {
                Some(serde_json::from_str(&doc).map_err(|e| corrupt(&e))?)
            }
            _ => None,
        };
        Ok(Self {
            id: r.id,
            kind: r.kind,
            name: r.name,
            n: r.n,
            m: r.m,
            summary,
            document,
            sha256: r.sha256,
            created_at: r.created_at,
        })
    }
}

/// A template document from a request body: JSON of either kind, or a raw URDF (XML, every
/// default) when the content type says XML or the body is one; errors name the field and,
/// for an expression, the character offset.
fn parse_document(body: &str, xml: bool, max_dof: usize) -> Result<Template> {
    if xml || body.trim_start().starts_with('<') {
        UrdfTemplate::from_urdf_within(body, max_dof).map(|u| Template::Urdf(Arc::new(u)))
    } else {
        Template::from_json_within(body, max_dof)
    }
}

impl App {
    /// Stores a template document (POST /v1/templates): checked as a job would check it,
    /// identified by its canonical form (the same document again returns the stored one,
    /// `created = false`).
    pub async fn upload_template(
        &self,
        body: impl AsRef<[u8]> + Send + 'static,
        xml: bool,
    ) -> Result<Stored<TemplateView>> {
        let max_dof = self.settings.max_dof;
        // The checks evaluate the document (M at random points, a robot's tree): off the
        // async executor, whose threads answer every other request.
        let (t, document, summary) = off_executor(move || {
            let text = std::str::from_utf8(body.as_ref()).map_err(|e| Error::Unprocessable {
                field: "template".into(),
                message: format!("not UTF-8: {e}"),
            })?;
            let t = parse_document(text, xml, max_dof)?;
            let document = serde_json::to_string(&t).expect("template documents serialize");
            let summary = serde_json::to_string(&Summary::of(&t)).expect("summaries serialize");
            Ok((t, document, summary))
        })
        .await?;
        let (row, created) = self
            .store
            .insert_template(NewTemplate {
                kind: t.kind(),
                name: t.name(),
                n: t.n() as i64,
                m: t.m() as i64,
                document: &document,
                summary: &summary,
            })
            .await?;
        Ok(Stored {
            item: TemplateView::of(row, true)?,
            created,
        })
    }

    pub async fn template(&self, id: &str) -> Result<TemplateView> {
        let row = self
            .store
            .get_template(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("template {id}")))?;
        off_executor(move || TemplateView::of(row, true)).await
    }

    /// A page of templates, newest first, as summaries (the documents are on
    /// `GET /v1/templates/{id}`).
    pub async fn list_templates(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<TemplateView>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("templates", token)?;
        let (rows, more) = self.store.list_templates(before, size).await?;
        let next = super::paging::after("templates", &rows, more, |t| t.seq);
        let items = off_executor(move || {
            rows.into_iter()
                .map(|r| TemplateView::of(r, false))
                .collect::<Result<_>>()
        })
        .await?;
        Ok((items, next))
    }

    /// Deletes a stored template (409 while a queued or running job uses it).
    pub async fn delete_template(&self, id: &str) -> Result<()> {
        self.store.delete_template(id).await
    }

    /// A stored template by id, for a job that names it; None when `id` names none.
    pub(super) async fn stored_template(&self, id: &str) -> Result<Option<Template>> {
        let Some(row) = self.store.get_template(id).await? else {
            return Ok(None);
        };
        let id = id.to_string();
        off_executor(move || {
            let document = row.document.unwrap_or_default();
            Template::from_json(&document)
                .map(Some)
                .map_err(|e| Error::corrupt(format!("template {id}"), e))
        })
        .await
    }
}

/// Runs a check that may take long (parsing and evaluating a document) on the blocking pool,
/// so that the async executor's threads keep answering other requests meanwhile; its cost is
/// bounded by the document limits (`MAX_DOF`, `formula::MAX_NODES`, `urdf::xml`).
pub(super) async fn off_executor<T: Send + 'static>(
    f: impl FnOnce() -> Result<T> + Send + 'static,
) -> Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Error::Internal(format!("a check failed: {e}")))?
}
