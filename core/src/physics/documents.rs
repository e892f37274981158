//! Template documents: a user's formula template or URDF robot read from JSON (a request, a
//! job spec, a model file), each checked within the service's limits before it is used.

use std::sync::Arc;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::MAX_DOF;
use super::formula_template::{FormulaDoc, FormulaTemplate};
use super::templates::{DOCUMENT_KINDS, Template};
use super::urdf::template::{KIND as URDF, UrdfDoc, UrdfTemplate};
use crate::error::{Error, Result};

impl Serialize for Template {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Template::Formula(f) => f.doc.serialize(s),
            Template::Urdf(u) => u.doc.serialize(s),
            t => s.serialize_str(t.name()),
        }
    }
}

impl<'de> Deserialize<'de> for Template {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::String(n) => Template::parse(&n),
            doc => Template::from_document(&doc),
        }
        .map_err(serde::de::Error::custom)
    }
}

/// A document's fields from JSON; errors name the field ("template" for the whole).
fn document<T: serde::de::DeserializeOwned>(v: &serde_json::Value) -> Result<T> {
    serde_path_to_error::deserialize(v).map_err(|e| {
        let path = e.path().to_string();
        let message = e.inner().to_string();
        // serde reports a missing field at its parent: name the field itself.
        let missing = message
            .strip_prefix("missing field `")
            .and_then(|m| m.split('`').next());
        let root = path == "." || path == "?";
        let field = match (root, missing) {
            (true, Some(m)) => m.to_string(),
            (false, Some(m)) => format!("{path}.{m}"),
            (true, None) => "template".to_string(),
            (false, None) => path,
        };
        Error::Unprocessable { field, message }
    })
}

impl Template {
    /// A template document (JSON, its "kind" says which); errors (422) name the field and,
    /// for an expression, the character offset in it.
    pub fn from_document(doc: &serde_json::Value) -> Result<Self> {
        Self::from_document_within(doc, MAX_DOF)
    }

    /// `from_document` for a service that takes at most `max_dof` coordinates: a larger
    /// document is refused before its expressions or its robot are read.
    pub fn from_document_within(doc: &serde_json::Value, max_dof: usize) -> Result<Self> {
        let kind = doc.get("kind").and_then(|k| k.as_str());
        match kind {
            Some("formula") => Ok(Template::Formula(Arc::new(FormulaTemplate::from_doc(
                document::<FormulaDoc>(doc)?,
                max_dof,
            )?))),
            Some(URDF) => Ok(Template::Urdf(Arc::new(UrdfTemplate::from_doc(
                document::<UrdfDoc>(doc)?,
                max_dof,
            )?))),
            _ if !doc.is_object() => Err(Error::Unprocessable {
                field: "template".into(),
                message: "must be a template document (a JSON object)".into(),
            }),
            _ => Err(Error::Unprocessable {
                field: "kind".into(),
                message: format!(
                    "must be one of {}, got {}",
                    DOCUMENT_KINDS.map(|k| format!("\"{k}\"")).join(", "),
                    doc.get("kind")
                        .map_or("nothing".to_string(), |k| k.to_string())
                ),
            }),
        }
    }

    /// A template document from JSON text (`from_document`); a syntax error names the field
    /// being read (or "template") and its line and column.
    pub fn from_json(text: &str) -> Result<Self> {
        Self::from_json_within(text, MAX_DOF)
    }

    /// `from_json` for a service that takes at most `max_dof` coordinates.
    pub fn from_json_within(text: &str, max_dof: usize) -> Result<Self> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let doc: serde_json::Value = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            Error::Unprocessable {
                // The field being read when the text went wrong.
                field: if path == "." || path == "?" {
                    "template".into()
                } else {
                    path
                },
                message: e.into_inner().to_string(),
            }
        })?;
        Self::from_document_within(&doc, max_dof)
    }
}
