//! A trained model as a file describes it, free of Burn: its configuration
//! ([`ModelConfig`]), its spec (`spec`), the `.gbx` file (`file`: config, named parameter
//! arrays and the training report) and the report's types (`report`). The trainable model on
//! Burn is the service's `model` module; inference (`infer`) reads these alone.

pub mod file;
pub mod report;
mod scaling;
pub mod spec;
mod spec_json;
mod stored;

use serde::{Deserialize, Serialize};

use crate::physics::integrator::Integrator;
use crate::physics::scaling::Scaling;
use crate::physics::space::Space;
use crate::physics::templates::Template;
use crate::physics::urdf::delay::lags;
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
#[serde(try_from = "stored::Stored", into = "stored::Stored")]
pub struct ModelConfig {
    pub spec: ModelSpec,
    /// The configuration space: nq configuration values, nv velocities (`physics::space`).
    pub space: Space,
    pub m: usize,
    pub dt: f64,
    pub integrator: Integrator,
    /// Weight of the velocity error in the loss.
    pub lambda: f64,
    pub scaling: Scaling,
}

impl ModelConfig {
    pub fn template(&self) -> Option<&Template> {
        self.spec.template()
    }

    /// Configuration values: q's width.
    pub fn nq(&self) -> usize {
        self.space.nq()
    }

    /// Velocities: v's width, and that of every force, acceleration and tangent.
    pub fn nv(&self) -> usize {
        self.space.nv()
    }

    /// A state's width, nq + nv.
    pub fn nx(&self) -> usize {
        self.nq() + self.nv()
    }

    /// A tangent state's width, 2·nv: the rows and columns of a linearization.
    pub fn ndx(&self) -> usize {
        2 * self.nv()
    }

    /// The earlier effort samples a torque row carries: those a URDF robot's effort delay may
    /// reach back to at this step (`urdf::delay`); 0 without a delay.
    pub fn effort_lags(&self) -> usize {
        (self.spec.effort_delay()).map_or(0, |bound| lags(bound, self.dt))
    }

    /// Whether velocity k is an angle's.
    pub fn is_periodic(&self, k: usize) -> bool {
        self.space.is_angle(k)
    }

    /// The width of a network input made of q (`Space::q_features`).
    pub fn q_inputs(&self) -> usize {
        self.space.q_features()
    }

    /// Data of (nq, nv, m) widths fits the model; else an error naming `field` and both.
    pub fn check_data(
        &self,
        field: &str,
        (nq, nv, m): (usize, usize, usize),
    ) -> crate::error::Result<()> {
        let own = (self.nq(), self.nv(), self.m);
        if (nq, nv, m) == own {
            return Ok(());
        }
        Err(crate::error::Error::invalid(
            field,
            format!(
                "has nq = {nq}, nv = {nv}, m = {m} but the model has nq = {}, nv = {}, m = {}",
                own.0, own.1, own.2
            ),
        ))
    }

    /// The width of a network input made of [q, v, u].
    pub fn full_inputs(&self) -> usize {
        self.q_inputs() + self.nv() + self.m
    }
}
