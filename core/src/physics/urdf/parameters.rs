//! A URDF template's parameters (docs/robots.md#physically-consistent-inertia): a body's ten
//! physical values and a joint's two, named after the link and joint (the conversions between
//! a body's forms are `multibody::spatial`'s).

use std::borrow::Cow;

use super::tree::Tree;
use crate::physics::params::{ParamInfo, Part};

pub use crate::physics::multibody::PER_BODY;

/// Parameters per joint.
pub(super) const PER_JOINT: usize = 2;

pub(super) const BODY_FIELDS: [&str; PER_BODY] = [
    "mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz",
];

pub(super) fn params_of(tree: &Tree) -> Vec<ParamInfo> {
    use Part::{Forces, Mass, Potential};
    const MV: &[Part] = &[Mass, Potential];
    const M: &[Part] = &[Mass];
    const F: &[Part] = &[Forces];
    let mut out = vec![];
    for b in &tree.bodies {
        let i = &b.inertial;
        let c = i.com();
        let ic = i.inertia_at_com();
        let values = [
            i.mass, c[0], c[1], c[2], ic[0][0], ic[0][1], ic[0][2], ic[1][1], ic[1][2], ic[2][2],
        ];
        for (k, (field, v)) in BODY_FIELDS.iter().zip(values).enumerate() {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.{field}", b.link)),
                default: v,
                positive: k == 0,
                min: None,
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
                fixed: false,
                used_by: Cow::Borrowed(F),
            });
        }
    }
    out
}
