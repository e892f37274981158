//! A URDF template's base parameters (docs/robots.md#base-parameters) by name and value, for
//! reports: `multibody::base` over the robot at its physical values.

use super::parameters::PER_BODY;
use super::template::{BASE_PARAMETERS_MAX_BODIES, UrdfTemplate};
use crate::physics::multibody;
use crate::physics::multibody::spatial::STANDARD_NAMES;

impl UrdfTemplate {
    /// The base parameters at these physical values (docs/robots.md#base-parameters): each a
    /// combination of the standard parameters `<link>.mass`, `<link>.mx|my|mz` (m c) and
    /// `<link>.Ixx|Ixy|Ixz|Iyy|Iyz|Izz` (about the link frame's origin), named by its formula,
    /// with its value. `gravity`: whether V is the template's (else the data sees no weight).
    /// Empty for a robot of over `BASE_PARAMETERS_MAX_BODIES` moving bodies.
    pub fn base_parameters(&self, physical: &[f64], gravity: bool) -> Vec<(String, f64)> {
        use multibody::regressor::standard_parameters;
        if self.nb() > BASE_PARAMETERS_MAX_BODIES {
            return vec![];
        }
        let model = self.multibody_model(physical, gravity);
        let pi = standard_parameters(&model);
        let name = |k: usize| match self.tree.bodies.get(k / PER_BODY) {
            Some(b) => format!("{}.{}", b.link, STANDARD_NAMES[k % PER_BODY]),
            None => {
                let c = self.tree.coordinates[k - PER_BODY * self.nb()];
                format!("{}.armature", self.tree.bodies[c].joint)
            }
        };
        multibody::base::base_parameters(&model)
            .into_iter()
            .map(|b| {
                let mut text = String::new();
                for &(k, c) in &b.terms {
                    // Six significant digits: link lengths and their squares, not rounding.
                    let c: f64 = format!("{c:.5e}").parse().expect("a number");
                    let sign = if c < 0.0 { " − " } else { " + " };
                    if !text.is_empty() || c < 0.0 {
                        text.push_str(if text.is_empty() { "−" } else { sign });
                    }
                    if c.abs() != 1.0 {
                        text.push_str(&format!("{}·", c.abs()));
                    }
                    text.push_str(&name(k));
                }
                (text, b.value(&pi))
            })
            .collect()
    }
}
