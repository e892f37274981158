//! A trained model as a file describes it, free of Burn: its configuration
//! ([`ModelConfig`]), its spec (`spec`), the `.gbx` file (`file`: config, named parameter
//! arrays and the training report) and the report's types (`report`). The trainable model on
//! Burn is the service's `model` module; inference (`infer`) reads these alone.

pub mod file;
pub mod report;
mod scaling;
pub mod spec;
mod spec_json;

use serde::{Deserialize, Serialize};

use crate::physics::integrator::Integrator;
use crate::physics::scaling::Scaling;
use crate::physics::templates::Template;
use spec::ModelSpec;

/// The names of a model's parameter groups in its file.
pub mod names {
    pub const NAIVE: &str = "naive";
    pub const MASS_NET: &str = "mass_net";
    pub const MASS_CONST: &str = "mass_const";
    pub const POTENTIAL_NET: &str = "potential_net";
    pub const POTENTIAL_QUAD: &str = "potential_quad";
    pub const FORCE_NET: &str = "force_net";
    pub const B_NET: &str = "b_net";
    pub const DAMPING_NET: &str = "damping_net";
    pub const B_CONST: &str = "b_const";
    pub const ETA: &str = "eta";
    pub const PHYSICAL: &str = "physical";
    /// The template's physical values as they are, for a model that trains nothing
    /// (`ModelFile::from_template`): a URDF's massless link or point mass stays what the
    /// file says, where the trainable form needs floors.
    pub const PHYSICAL_VALUES: &str = "physical_values";
}

/// One parameter array as a file and a checkpoint store it: f32 → f64 → f32 is lossless,
/// so values round-trip exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NamedArray {
    /// The value's name in the file, e.g. "mass_net.layers.0.weight" (see `names`).
    pub name: String,
    pub shape: Vec<usize>,
    pub values: Vec<f64>,
}

/// Everything that defines a model apart from its trainable values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelConfig {
    pub spec: ModelSpec,
    pub n: usize,
    pub m: usize,
    pub dt: f64,
    pub integrator: Integrator,
    /// Weight of the velocity error in the loss.
    pub lambda: f64,
    pub scaling: Scaling,
    /// Which coordinates are angles (empty: none, as in every file before this field): the
    /// networks see (sin q, cos q) for them and the loss compares them on the circle.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub periodic: Vec<bool>,
}

impl ModelConfig {
    pub fn template(&self) -> Option<&Template> {
        self.spec.template()
    }

    /// `periodic` as a file stores it: none marked is empty, as in every file before the field.
    pub fn stored_periodic(angles: Vec<bool>) -> Vec<bool> {
        if angles.contains(&true) {
            angles
        } else {
            vec![]
        }
    }

    /// Whether coordinate k is an angle.
    pub fn is_periodic(&self, k: usize) -> bool {
        self.periodic.get(k).copied().unwrap_or(false)
    }

    /// The width of a network input made of q: one per coordinate, two per angle.
    pub fn q_inputs(&self) -> usize {
        self.n + (0..self.n).filter(|&k| self.is_periodic(k)).count()
    }

    /// The width of a network input made of [q, q̇, u].
    pub fn full_inputs(&self) -> usize {
        self.q_inputs() + self.n + self.m
    }
}
