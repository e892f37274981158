//! Rigid frames of a URDF: its roll-pitch-yaw rotations and the composition of joint and
//! link frames.

use super::read::Pose;

pub type Rot = [[f64; 3]; 3];

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

fn mul(a: &Rot, b: &Rot) -> Rot {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn apply(a: &Rot, v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

/// A rigid transform (rotation, translation): x ↦ R x + p.
#[derive(Clone, Copy)]
pub struct Frame {
    pub rot: Rot,
    pub pos: [f64; 3],
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
        let p = apply(&self.rot, &o.pos);
        Frame {
            rot: mul(&self.rot, &o.rot),
            pos: std::array::from_fn(|i| self.pos[i] + p[i]),
        }
    }
}
