//! The one record of the service's that the model and data code make: a warning. The
//! service's other records (datasets, jobs, metrics) are its own (`records` there), and it
//! hands this one out by that same path.

use serde::{Deserialize, Serialize};

/// Something in the data or in a training run a person should look at. Warnings never block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Warning {
    /// A stable identifier, e.g. `coordinate_span`.
    pub code: String,
    /// What it concerns, e.g. `q[0]` (coordinate 0 of q), when it is one field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
    pub message: String,
}

impl Warning {
    pub fn new(code: &str, field: Option<String>, message: String) -> Self {
        Self {
            code: code.to_string(),
            field,
            message,
        }
    }
}
