//! Rigid frames of a URDF: its roll-pitch-yaw rotations and the composition of joint and
//! link frames.

use super::read::Pose;
use crate::physics::multibody::spatial::{M3, V3, mm, mv};

pub type Rot = M3<f64>;

/// R = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed-axis roll-pitch-yaw.
pub fn rpy(r: [f64; 3]) -> Rot {
    let (sr, cr) = r[0].sin_cos();
    let (sp, cp) = r[1].sin_cos();
    let (sy, cy) = r[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

/// A rigid transform (rotation, translation): x ↦ R x + p.
#[derive(Clone, Copy)]
pub struct Frame {
    pub rot: Rot,
    pub pos: V3<f64>,
}

impl Frame {
    pub const IDENTITY: Frame = Frame {
        rot: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        pos: [0.0; 3],
    };

    pub fn of(pose: &Pose) -> Frame {
        Frame {
            rot: rpy(pose.rpy),
            pos: pose.xyz,
        }
    }

    pub fn then(&self, o: &Frame) -> Frame {
        let p = mv(&self.rot, &o.pos);
        Frame {
            rot: mm(&self.rot, &o.rot),
            pos: std::array::from_fn(|i| self.pos[i] + p[i]),
        }
    }
}
