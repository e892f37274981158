//! A URDF template's parameters (docs/robots.md#physically-consistent-inertia): a body's ten
//! physical values and a joint's two, named after the link and joint (the conversions between
//! a body's forms are `multibody::spatial`'s), then the optional groups a robot may ask for,
//! each coordinate's armature (docs/robots.md#armature) and each input's effort gain and
//! offset: last, so a robot without keeps its layout.

use std::borrow::Cow;

use super::tree::Tree;
use crate::physics::params::{ParamInfo, Part};

pub use crate::physics::multibody::PER_BODY;

/// Parameters per joint.
pub(super) const PER_JOINT: usize = 2;

pub(super) const BODY_FIELDS: [&str; PER_BODY] = [
    "mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz",
];

/// Which optional groups a robot's parameters have.
#[derive(Debug, Clone, Copy)]
pub(super) struct Groups {
    pub armature: bool,
    pub effort_gain: bool,
    pub effort_offset: bool,
    /// The bound of the efforts' delay, seconds, when the robot has one.
    pub effort_delay: Option<f64>,
}

/// Every parameter of `tree` with the optional `groups`; `inputs` the actuated joints.
pub(super) fn params_of(tree: &Tree, groups: Groups, inputs: &[&str]) -> Vec<ParamInfo> {
    use Part::{Forces, Mass, Potential};
    const MV: &[Part] = &[Mass, Potential];
    const M: &[Part] = &[Mass];
    const F: &[Part] = &[Forces];
    let mut out = vec![];
    for b in &tree.bodies {
        for (k, (field, v)) in BODY_FIELDS.iter().zip(b.inertial.physical()).enumerate() {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.{field}", b.link)),
                default: v,
                positive: k == 0,
                min: None,
                max: None,
                fixed: false,
                used_by: Cow::Borrowed(if k < 4 { MV } else { M }),
            });
        }
    }
    for b in &tree.bodies {
        for (field, v) in [("damping", b.damping), ("friction", b.friction)] {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.{field}", b.joint)),
                default: v,
                positive: false,
                // Trained as themselves and kept ≥ 0 by projection: both often start at
                // exactly 0, where a logarithm cannot start and a square has no gradient.
                min: Some(0.0),
                max: None,
                fixed: false,
                used_by: Cow::Borrowed(F),
            });
        }
    }
    if groups.armature {
        for &b in &tree.coordinates {
            let b = &tree.bodies[b];
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.armature", b.joint)),
                default: b.armature.unwrap_or(0.0),
                positive: false,
                // As damping: a rotor that is not there starts at exactly 0.
                min: Some(0.0),
                max: None,
                fixed: false,
                used_by: Cow::Borrowed(M),
            });
        }
    }
    // A gain is a scale, kept ≥ 0 by projection as damping is (a URDF template's values
    // beyond the bodies are trained as they are); an offset any force.
    for (on, field, default, min) in [
        (groups.effort_gain, "effort_gain", 1.0, Some(0.0)),
        (groups.effort_offset, "effort_offset", 0.0, None),
    ] {
        for joint in inputs.iter().filter(|_| on) {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{joint}.{field}")),
                default,
                positive: false,
                min,
                max: None,
                fixed: false,
                used_by: Cow::Borrowed(F),
            });
        }
    }
    if let Some(bound) = groups.effort_delay {
        out.push(ParamInfo {
            name: Cow::Borrowed(DELAY),
            default: 0.0,
            positive: false,
            // Trained as itself within its bounds: no delay is where a log without one rests.
            min: Some(0.0),
            max: Some(bound),
            fixed: false,
            used_by: Cow::Borrowed(F),
        });
    }
    out
}

/// The name of a robot's effort delay (one for the robot: its log's clocks, not a joint's).
pub const DELAY: &str = "effort_delay";
