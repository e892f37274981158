//! A formula template's JSON document, as it is stored and embedded in model files.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::Error;

/// A formula template as its JSON document (kept whole: a model file embeds it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormulaDoc {
    pub kind: String,
    pub name: String,
    pub coordinates: Vec<String>,
    /// Empty: no coordinate is an angle.
    #[serde(default)]
    pub periodic: Vec<bool>,
    #[serde(default)]
    pub inputs: Vec<String>,
    /// By name; trained in this (alphabetical) order.
    #[serde(default)]
    pub parameters: BTreeMap<String, ParamDoc>,
    pub mass: Vec<Vec<String>>,
    pub potential: String,
    pub forces: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamDoc {
    pub value: f64,
    /// Trained in log space (masses, lengths): it cannot turn negative.
    #[serde(default)]
    pub positive: bool,
    /// Known, not trained (g, a measured length): it keeps its value (or the job's `init`).
    /// Left out of documents when false, which so read and hash as before.
    #[serde(default, skip_serializing_if = "is_false")]
    pub fixed: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

pub(super) fn bad(field: impl Into<String>, message: impl std::fmt::Display) -> Error {
    Error::Unprocessable {
        field: field.into(),
        message: message.to_string(),
    }
}
