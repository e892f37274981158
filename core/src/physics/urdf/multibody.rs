//! The URDF reader as one producer of a [`multibody::Model`]: each movable body of the tree
//! (fixed joints already merged into it) becomes a body with its joint model, drive and
//! inertia, in the tree's depth-first order.

use super::tree::{JointKind, Tree};
use crate::physics::multibody::{self, Inertial, JointModel, Placement};

impl Tree {
    /// The robot with its bodies' URDF inertias.
    pub fn multibody(&self, gravity: [f64; 3]) -> multibody::Model {
        let inertials: Vec<Inertial> = self.bodies.iter().map(|b| b.inertial.clone()).collect();
        self.multibody_with(&inertials, gravity)
    }

    /// The robot with other inertias (one per body, in its frame).
    pub fn multibody_with(&self, inertials: &[Inertial], gravity: [f64; 3]) -> multibody::Model {
        let bodies = (self.bodies.iter().zip(inertials))
            .map(|(b, i)| {
                let at = Placement {
                    rot: b.rot,
                    pos: b.pos,
                };
                multibody::Body {
                    parent: b.parent,
                    joint: match b.kind {
                        JointKind::Prismatic => JointModel::prismatic(&at, b.axis),
                        JointKind::Revolute | JointKind::Continuous => {
                            JointModel::revolute(&at, b.axis)
                        }
                    },
                    drive: b.drive,
                    inertia: i.clone(),
                }
            })
            .collect();
        multibody::Model::new(bodies, self.coordinates.len(), gravity)
    }
}
