//! Templates as a resource: a user's mechanism uploaded once (POST /v1/templates) and named by
//! jobs by id. A job's spec embeds the whole template, so a model never depends on the row.

use std::sync::Arc;

use serde::Serialize;
use serde_json::Value;

use super::App;
use crate::error::{Error, Result};
use crate::model::templates::Template;
use crate::model::urdf::UrdfTemplate;
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
    pub coordinates: Vec<String>,
    pub inputs: Vec<String>,
    pub periodic: Vec<bool>,
    /// `{name, value, positive}`: the physical values a job starts from (`init` sets them by
    /// name).
    #[schema(value_type = Vec<Object>)]
    pub parameters: Vec<Value>,
    /// What motion data can and cannot determine of these values (URDF robots).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identifiability: Option<String>,
    /// The document as stored (canonical: sorted parameters, defaults filled in).
    #[schema(value_type = Object)]
    pub document: Value,
    pub sha256: String,
    pub created_at: String,
}

impl TryFrom<TemplateRow> for TemplateView {
    type Error = Error;

    fn try_from(r: TemplateRow) -> Result<Self> {
        let t = Template::from_json(&r.document)
            .map_err(|e| Error::corrupt(format!("template {}", r.id), e))?;
        let n = t.n();
        let periodic = t.periodic();
        Ok(Self {
            parameters: t
                .params()
                .iter()
                .map(|p| {
                    serde_json::json!({"name": p.name, "value": p.default, "positive": p.positive})
                })
                .collect(),
            coordinates: t.coordinates(),
            inputs: t.inputs(),
            periodic: if periodic.is_empty() {
                vec![false; n]
            } else {
                periodic
            },
            identifiability: t.identifiability_note().map(str::to_string),
            document: serde_json::to_value(&t).expect("template documents serialize"),
            id: r.id,
            kind: r.kind,
            name: r.name,
            n: r.n,
            m: r.m,
            sha256: r.sha256,
            created_at: r.created_at,
        })
    }
}

/// A template document from a request body: JSON of either kind, or a raw URDF (XML, every
/// default) when the content type says XML or the body is one; errors name the field (under
/// `prefix`, "" for a document of its own) and, for an expression, the character offset.
pub fn parse_document(body: &str, xml: bool, prefix: &str) -> Result<Template> {
    let xml = xml || body.trim_start().starts_with('<');
    let t = if xml {
        UrdfTemplate::from_urdf(body).map(|u| Template::Urdf(Arc::new(u)))
    } else {
        Template::from_json(body)
    };
    t.map_err(|e| match e {
        Error::Unprocessable { field, message } => Error::Unprocessable {
            field: match (prefix, field.as_str()) {
                ("", _) => field,
                (p, "template") => p.to_string(),
                (p, f) => format!("{p}.{f}"),
            },
            message,
        },
        other => other,
    })
}

impl App {
    /// Stores a template document (POST /v1/templates): checked as a job would check it,
    /// identified by its canonical form (the same document again returns the stored one,
    /// `created = false`).
    pub async fn upload_template(&self, body: &[u8], xml: bool) -> Result<(TemplateView, bool)> {
        let text = std::str::from_utf8(body).map_err(|e| Error::Unprocessable {
            field: "template".into(),
            message: format!("not UTF-8: {e}"),
        })?;
        let t = parse_document(text, xml, "")?;
        if t.n() > self.settings.max_dof {
            return Err(Error::Unprocessable {
                field: "coordinates".into(),
                message: format!(
                    "{} coordinates; this service takes at most {} (--max-dof)",
                    t.n(),
                    self.settings.max_dof
                ),
            });
        }
        let document = serde_json::to_string(&t).expect("template documents serialize");
        let (row, created) = self
            .store
            .insert_template(NewTemplate {
                kind: t.kind(),
                name: t.name(),
                n: t.n() as i64,
                m: t.m() as i64,
                document: &document,
            })
            .await?;
        Ok((row.try_into()?, created))
    }

    pub async fn template(&self, id: &str) -> Result<TemplateView> {
        self.store
            .get_template(id)
            .await?
            .ok_or_else(|| Error::NotFound(format!("template {id}")))?
            .try_into()
    }

    pub async fn list_templates(
        &self,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<(Vec<TemplateView>, Option<String>)> {
        let size = super::paging::size(size)?;
        let before = super::paging::decode("templates", token)?;
        let rows = self.store.list_templates(before, size).await?;
        let next = super::paging::next("templates", &rows, size, |t| t.seq);
        let items = rows
            .into_iter()
            .map(TemplateView::try_from)
            .collect::<Result<_>>()?;
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
        Template::from_json(&row.document)
            .map(Some)
            .map_err(|e| Error::corrupt(format!("template {id}"), e))
    }
}
