//! Recursive rigid-body algorithms over the URDF tree (docs/robots.md#recursive-algorithms;
//! Featherstone, "Rigid Body Dynamics Algorithms", 2008): the recursive Newton–Euler
//! algorithm for inverse dynamics, gravity and Coriolis torques (`rnea`), the composite
//! rigid-body algorithm for M(q) (`crba`), the articulated-body algorithm for forward dynamics
//! (`aba`), the derivatives of forward dynamics (`derivatives`), and the kinetic and potential
//! energies (`energy`). Each is O(n) or O(n·depth) per state, generic over `Scalar` (f64 for
//! speed, dual numbers for exact derivatives), with the joints' constant frames precomputed
//! once in a [`RigidBodyModel`]. The f64 evaluator runs them for URDF models (`infer::rigid`).
//!
//! Mimic joints (`tree::Drive`): joint values are G q + offset with G = ∂(joint values)/∂q,
//! so joint velocities and accelerations are G q̇ and G q̈, forces on the coordinates are
//! Gᵀ τ_joints, and M = Gᵀ M_joints G.

pub mod aba;
pub mod adjoint;
pub mod base;
pub mod derivatives;
pub mod energy;
pub mod regressor;
pub mod rnea;
pub mod spatial;

pub use aba::{aba, crba_forward, forward_dynamics};
pub use derivatives::{
    Derivatives, dual_derivatives, fd_over_jets, forward_dynamics_derivatives, id_partials,
};
pub use energy::{kinetic_energy, potential_energy};
pub use rnea::{bias, coriolis, crba, gravity_torques, inverse_dynamics};

use super::inertia::Inertial;
use super::tree::{JointKind, Tree};
use crate::physics::scalar::Scalar;
use spatial::{Force, Motion, V3, Xform, affine, cdot, cscale, lift3};

type Mat = [[f64; 3]; 3];

/// One moving body and its joint, with the constants of its transform.
#[derive(Debug, Clone)]
pub struct Joint {
    pub parent: Option<usize>,
    pub prismatic: bool,
    /// The unit axis in the body's (= the joint's) frame.
    pub axis: [f64; 3],
    /// Joint value = multiplier · q[coordinate] + offset.
    pub coordinate: usize,
    pub multiplier: f64,
    pub offset: f64,
    /// The body's spatial inertia about its frame's origin.
    pub inertia: spatial::Inertia<f64>,
    /// E(q) = e0 + cos q · ec + sin q · es for a revolute joint; E = e0 for a prismatic one.
    e0: Mat,
    ec: Mat,
    es: Mat,
    /// The joint frame's origin in the parent frame, and (prismatic) the axis in parent axes.
    pos: [f64; 3],
    slide: [f64; 3],
}

/// The robot as the recursive algorithms take it: joints in the tree's (depth-first) order,
/// so that every parent comes before its children.
#[derive(Debug, Clone)]
pub struct RigidBodyModel {
    pub joints: Vec<Joint>,
    /// Coordinates (joints that are not mimic joints).
    pub n: usize,
    /// In the root frame, m/s².
    pub gravity: [f64; 3],
    /// Whether some joint follows another (then `forward_dynamics` solves with CRBA).
    pub mimic: bool,
}

impl RigidBodyModel {
    /// The tree with its bodies' URDF inertias.
    pub fn new(tree: &Tree, gravity: [f64; 3]) -> Self {
        let inertials: Vec<Inertial> = tree.bodies.iter().map(|b| b.inertial.clone()).collect();
        Self::with_inertias(tree, &inertials, gravity)
    }

    /// The tree with other inertias (one per body, in its frame).
    pub fn with_inertias(tree: &Tree, inertials: &[Inertial], gravity: [f64; 3]) -> Self {
        let joints = tree
            .bodies
            .iter()
            .zip(inertials)
            .map(|(b, i)| {
                let a = b.axis;
                let rt: Mat = std::array::from_fn(|i| std::array::from_fn(|j| b.rot[j][i]));
                // The rotation by q about a, transposed: a aᵀ + cos q (𝟙 − a aᵀ) − sin q [a]×;
                // E = R_qᵀ rotᵀ, each part times rotᵀ.
                let p: Mat = std::array::from_fn(|i| std::array::from_fn(|j| a[i] * a[j]));
                let id = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
                let q: Mat = std::array::from_fn(|i| std::array::from_fn(|j| id(i, j) - p[i][j]));
                let k: Mat = [[0.0, a[2], -a[1]], [-a[2], 0.0, a[0]], [a[1], -a[0], 0.0]];
                let times_rt = |m: &Mat| -> Mat {
                    std::array::from_fn(|i| {
                        std::array::from_fn(|j| (0..3).map(|l| m[i][l] * rt[l][j]).sum())
                    })
                };
                let prismatic = b.kind == JointKind::Prismatic;
                Joint {
                    parent: b.parent,
                    prismatic,
                    axis: a,
                    coordinate: b.drive.coordinate,
                    multiplier: b.drive.multiplier,
                    offset: b.drive.offset,
                    inertia: spatial::Inertia::rigid(i.mass, &i.h, &i.inertia),
                    e0: if prismatic { rt } else { times_rt(&p) },
                    ec: times_rt(&q),
                    es: times_rt(&k),
                    pos: b.pos,
                    slide: std::array::from_fn(|i| (0..3).map(|l| b.rot[i][l] * a[l]).sum()),
                }
            })
            .collect();
        Self {
            joints,
            n: tree.coordinates.len(),
            gravity,
            mimic: tree.bodies.iter().any(|b| b.mimic.is_some()),
        }
    }
}

impl Joint {
    fn follows(&self) -> bool {
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

    /// X_J X_T: parent to body coordinates at joint value `x`.
    pub fn xform<S: Scalar>(&self, x: &S, zero: &S) -> Xform<S> {
        if self.prismatic {
            Xform {
                e: self.e0.map(|r| lift3(&r, zero)),
                r: std::array::from_fn(|k| {
                    affine(self.pos[k], [(x, self.slide[k]), (x, 0.0)], zero)
                }),
            }
        } else {
            let (s, c) = (x.sin(), x.cos());
            Xform {
                e: std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        affine(
                            self.e0[i][j],
                            [(&c, self.ec[i][j]), (&s, self.es[i][j])],
                            zero,
                        )
                    })
                }),
                r: lift3(&self.pos, zero),
            }
        }
    }

    /// S x: the body's motion for joint rate x.
    pub fn motion<S: Scalar>(&self, x: &S, zero: &S) -> Motion<S> {
        let along = cscale(&self.axis, x, zero);
        let none: V3<S> = [zero.clone(), zero.clone(), zero.clone()];
        if self.prismatic {
            Motion { w: none, v: along }
        } else {
            Motion { w: along, v: none }
        }
    }

    /// Sᵀ f: the force's component along the joint.
    pub fn project<S: Scalar>(&self, f: &Force<S>, zero: &S) -> S {
        cdot(&self.axis, if self.prismatic { &f.f } else { &f.n }, zero)
    }

    /// I S for an inertia over S.
    pub fn inertia_column<S: Scalar>(&self, i: &spatial::Inertia<S>, zero: &S) -> Force<S> {
        let col = |m: &spatial::M3<S>, transpose: bool| -> V3<S> {
            std::array::from_fn(|r| {
                let row: V3<S> = if transpose {
                    [m[0][r].clone(), m[1][r].clone(), m[2][r].clone()]
                } else {
                    m[r].clone()
                };
                cdot(&self.axis, &row, zero)
            })
        };
        if self.prismatic {
            // (B a, C a)
            Force {
                n: col(&i.b, false),
                f: col(&i.c, false),
            }
        } else {
            // (A a, Bᵀ a)
            Force {
                n: col(&i.a, false),
                f: col(&i.b, true),
            }
        }
    }
}
