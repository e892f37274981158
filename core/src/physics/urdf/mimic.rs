//! Mimic joints (docs/robots.md#kinematic-tree): which coordinate each body's joint follows.

use std::collections::HashMap;

use super::read;
use super::tree::{Drive, Tree, bad};
use crate::error::Result;

impl Tree {
    /// Numbers the coordinates (the bodies whose joint is not a mimic joint, in body order)
    /// and resolves each mimic joint to the coordinate it follows, through chains of mimics.
    pub(super) fn drives(&mut self, robot: &read::Robot) -> Result<()> {
        let body_of: HashMap<String, usize> = (self.bodies.iter().enumerate())
            .map(|(i, b)| (b.joint.clone(), i))
            .collect();
        let line_of: HashMap<&str, usize> = (robot.joints.iter())
            .map(|j| (j.name.as_str(), j.line))
            .collect();
        for (i, b) in self.bodies.iter_mut().enumerate() {
            if b.mimic.is_none() {
                b.drive.coordinate = self.coordinates.len();
                self.coordinates.push(i);
            }
        }
        for i in 0..self.bodies.len() {
            let (mut at, mut multiplier, mut offset) = (i, 1.0, 0.0);
            // A chain of mimics visits each body at most once; more steps are a circle.
            for _ in 0..=self.bodies.len() {
                let Some(m) = &self.bodies[at].mimic else {
                    break;
                };
                let label = format!(
                    "joint '{}' (line {})",
                    self.bodies[at].joint,
                    line_of[self.bodies[at].joint.as_str()]
                );
                let Some(&next) = body_of.get(&m.joint) else {
                    return Err(bad(format!(
                        "{label}: <mimic joint=\"{}\">: the robot has no revolute, \
                         continuous or prismatic joint of that name",
                        m.joint
                    )));
                };
                (multiplier, offset) = (multiplier * m.multiplier, multiplier * m.offset + offset);
                at = next;
            }
            if self.bodies[at].mimic.is_some() {
                return Err(bad(format!(
                    "joint '{}': its <mimic> joints form a circle",
                    self.bodies[i].joint
                )));
            }
            self.bodies[i].drive = Drive {
                coordinate: self.bodies[at].drive.coordinate,
                multiplier,
                offset,
            };
        }
        Ok(())
    }
}
