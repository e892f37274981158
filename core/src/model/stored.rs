//! A model's configuration as its file stores it (docs/model-file.md): a space whose every
//! joint is one number (every file before nq and nv) as `n` and `periodic`, exactly as those
//! files wrote it; any other as its `joints`, with `n` its velocities.

use serde::{Deserialize, Serialize};

use super::ModelConfig;
use super::spec::ModelSpec;
use crate::physics::integrator::Integrator;
use crate::physics::scaling::Scaling;
use crate::physics::space::{Joint, Space};

#[derive(Serialize, Deserialize)]
pub(super) struct Stored {
    spec: ModelSpec,
    /// nv (nq too when `joints` is absent).
    n: usize,
    m: usize,
    dt: f64,
    integrator: Integrator,
    lambda: f64,
    scaling: Scaling,
    /// Which coordinates are angles (empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    periodic: Vec<bool>,
    /// The joints of a space that has one of nq ≠ nv (empty otherwise).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    joints: Vec<Joint>,
}

impl TryFrom<Stored> for ModelConfig {
    type Error = String;

    fn try_from(s: Stored) -> Result<Self, String> {
        let space = if s.joints.is_empty() {
            if !s.periodic.is_empty() && s.periodic.len() != s.n {
                return Err(format!(
                    "periodic has {} values for n = {}",
                    s.periodic.len(),
                    s.n
                ));
            }
            Space::flat(s.n, &s.periodic)
        } else {
            if s.joints.len() != s.n || !s.periodic.is_empty() {
                return Err(format!(
                    "joints has {} values for n = {} (and periodic must be absent)",
                    s.joints.len(),
                    s.n
                ));
            }
            Space::new(s.joints)
        };
        Ok(ModelConfig {
            spec: s.spec,
            space,
            m: s.m,
            dt: s.dt,
            integrator: s.integrator,
            lambda: s.lambda,
            scaling: s.scaling,
        })
    }
}

impl From<ModelConfig> for Stored {
    fn from(c: ModelConfig) -> Self {
        let flat = c.space.is_flat();
        Stored {
            n: c.space.nv(),
            periodic: if flat { c.space.periodic() } else { vec![] },
            joints: if flat {
                vec![]
            } else {
                c.space.joints().to_vec()
            },
            spec: c.spec,
            m: c.m,
            dt: c.dt,
            integrator: c.integrator,
            lambda: c.lambda,
            scaling: c.scaling,
        }
    }
}
