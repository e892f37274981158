//! Joint models (docs/robots.md#joint-models): how a body moves against its parent. Each
//! variant owns its transform X_J X_T (the joint's motion after the fixed placement in the
//! parent), its motion subspace S and the projections through it that the algorithms use.
//! Today's joints are 1-DoF; a spherical or free-flyer joint is a new variant whose value and
//! rate are several coordinates (see the docs for what else it touches).

use super::spatial::six::V6;
use super::spatial::{M3, V3, Xform, affine, lift3, mm, mv};
use crate::physics::scalar::Scalar;

/// How a body's joint value follows the coordinates: multiplier · q[coordinate] + offset. A
/// coordinate's own joint has (1, 0); a mimic joint follows the joint it mimics (through any
/// chain of mimics), so it is not a coordinate, its velocity and acceleration are the
/// multiplier's times the coordinate's, and its forces enter that coordinate times the
/// multiplier (the chain rule, as Pinocchio's mimic joints have it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drive {
    pub coordinate: usize,
    pub multiplier: f64,
    pub offset: f64,
}

impl Drive {
    /// A coordinate's own joint.
    pub fn own(coordinate: usize) -> Self {
        Self {
            coordinate,
            multiplier: 1.0,
            offset: 0.0,
        }
    }

    /// Whether the joint follows another's coordinate (a mimic joint).
    pub fn follows(&self) -> bool {
        (self.multiplier, self.offset) != (1.0, 0.0)
    }

    /// The joint's value from the coordinates.
    pub fn value<S: Scalar>(&self, q: &[S]) -> S {
        let x = &q[self.coordinate];
        if self.follows() {
            x.scale(self.multiplier).shift(self.offset)
        } else {
            x.clone()
        }
    }

    /// The joint's velocity (or acceleration) from the coordinates' (no offset).
    pub fn rate<S: Scalar>(&self, qd: &[S]) -> S {
        let x = &qd[self.coordinate];
        if self.multiplier != 1.0 {
            x.scale(self.multiplier)
        } else {
            x.clone()
        }
    }
}

/// Where a joint sits on its parent: its frame's axes (columns in the parent's axes) and its
/// origin in the parent's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub rot: M3<f64>,
    pub pos: V3<f64>,
}

/// A 1-DoF joint about or along a unit `axis` of its own frame, with its placement folded
/// into constants: E(x) = e0 + cos x · ec + sin x · es (revolute) or E = e0 (prismatic).
#[derive(Debug, Clone)]
pub struct Axial {
    pub axis: V3<f64>,
    e0: M3<f64>,
    ec: M3<f64>,
    es: M3<f64>,
    /// The joint frame's origin in the parent frame, and (prismatic) the axis in parent axes.
    pos: V3<f64>,
    slide: V3<f64>,
}

/// The joint models. URDF's `continuous` is `Revolute` (limits are not dynamics), a `fixed`
/// joint is merged into its parent body by the producer (the model never sees it), and a
/// `mimic` joint is any joint with a following [`Drive`].
#[derive(Debug, Clone)]
pub enum JointModel {
    Revolute(Axial),
    Prismatic(Axial),
}

impl JointModel {
    pub fn revolute(placement: &Placement, axis: V3<f64>) -> Self {
        let a = axis;
        let rt: M3<f64> = transpose(&placement.rot);
        // The rotation by q about a, transposed: a aᵀ + cos q (𝟙 − a aᵀ) − sin q [a]×;
        // E = R_qᵀ rotᵀ, each part times rotᵀ.
        let p: M3<f64> = std::array::from_fn(|i| std::array::from_fn(|j| a[i] * a[j]));
        let id = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
        let q: M3<f64> = std::array::from_fn(|i| std::array::from_fn(|j| id(i, j) - p[i][j]));
        let k: M3<f64> = [[0.0, a[2], -a[1]], [-a[2], 0.0, a[0]], [a[1], -a[0], 0.0]];
        let times_rt = |m: &M3<f64>| mm(m, &rt);
        Self::Revolute(Axial {
            axis: a,
            e0: times_rt(&p),
            ec: times_rt(&q),
            es: times_rt(&k),
            pos: placement.pos,
            slide: slide(placement, &a),
        })
    }

    pub fn prismatic(placement: &Placement, axis: V3<f64>) -> Self {
        Self::Prismatic(Axial {
            axis,
            e0: transpose(&placement.rot),
            ec: [[0.0; 3]; 3],
            es: [[0.0; 3]; 3],
            pos: placement.pos,
            slide: slide(placement, &axis),
        })
    }

    fn axial(&self) -> &Axial {
        match self {
            Self::Revolute(j) | Self::Prismatic(j) => j,
        }
    }

    /// The unit axis in the body's (= the joint's) frame.
    pub fn axis(&self) -> &V3<f64> {
        &self.axial().axis
    }

    /// X_J X_T: parent to body coordinates at joint value `x`.
    pub fn xform<S: Scalar>(&self, x: &S, zero: &S) -> Xform<S> {
        match self {
            Self::Prismatic(j) => Xform {
                e: j.e0.map(|r| lift3(&r, zero)),
                r: std::array::from_fn(|k| affine(j.pos[k], [(x, j.slide[k]), (x, 0.0)], zero)),
            },
            Self::Revolute(j) => {
                let (s, c) = (x.sin(), x.cos());
                Xform {
                    e: std::array::from_fn(|i| {
                        std::array::from_fn(|k| {
                            affine(j.e0[i][k], [(&c, j.ec[i][k]), (&s, j.es[i][k])], zero)
                        })
                    }),
                    r: lift3(&j.pos, zero),
                }
            }
        }
    }

    /// S: the body's motion (ω, v) in its own frame for a unit joint rate.
    pub fn subspace(&self) -> V6 {
        let [a0, a1, a2] = *self.axis();
        match self {
            Self::Prismatic(_) => [0.0, 0.0, 0.0, a0, a1, a2],
            Self::Revolute(_) => [a0, a1, a2, 0.0, 0.0, 0.0],
        }
    }
}

fn transpose(m: &M3<f64>) -> M3<f64> {
    std::array::from_fn(|i| std::array::from_fn(|j| m[j][i]))
}

/// The axis in the parent's axes.
fn slide(placement: &Placement, a: &V3<f64>) -> V3<f64> {
    mv(&placement.rot, a)
}
