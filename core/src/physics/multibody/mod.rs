//! Rigid-body dynamics of a tree of bodies (docs/robots.md#multibody-dynamics; Featherstone,
//! "Rigid Body Dynamics Algorithms", 2008), laid out as Pinocchio's: a [`Model`] (the tree,
//! its joint models, its bodies' inertias, gravity) built once from any source (the URDF
//! reader is one producer: `urdf::Tree::multibody`), one spatial algebra owning every form of
//! a body's inertia and the conversions between them (`spatial`), the joint models (`joint`),
//! and a workspace [`Data`] on which each algorithm is written once, generic over `Scalar`
//! (f64, dual numbers and jets for exact derivatives, batch columns): the state's kinematics
//! in the root frame (`data`: forward kinematics, and CRBA for M(q) and RNEA's passes, whose
//! one-call entry points are in `rnea`), the articulated-body algorithm for forward dynamics
//! (`aba`), the analytic derivatives of forward dynamics (`derivatives`), its
//! vector–Jacobian product (`adjoint`), the energies (`energy`), τ = Y π (`regressor`) and
//! the base parameters (`base`). Each is O(n) or O(n·depth) per state. ARCHITECTURE.md's
//! table names the one file of each.
//!
//! Mimic joints ([`Drive`]): joint values are G q + offset with G = ∂(joint values)/∂q, so
//! joint velocities and accelerations are G q̇ and G q̈, forces on the coordinates are
//! Gᵀ τ_joints, and M = Gᵀ M_joints G.

pub mod aba;
pub mod adjoint;
pub mod base;
pub mod data;
pub mod derivatives;
pub mod energy;
pub mod joint;
pub mod regressor;
pub mod rnea;
pub mod spatial;
pub mod thread_data;

pub use aba::{aba, crba_forward, forward_dynamics, forward_dynamics_in};
pub use data::Data;
pub use derivatives::{Derivatives, fd_over_dual, forward_dynamics_derivatives, id_partials};
pub use energy::{kinetic_energy, potential_energy, potential_energy_of};
pub use joint::{Drive, JointModel, Placement};
pub use rnea::{bias, coriolis, crba, crba_with, gravity_torques, inverse_dynamics};
pub use spatial::{Inertial, PER_BODY};
pub use thread_data::{Lent, lending, with_data};

use crate::physics::scalar::Scalar;
use spatial::Xform;

/// One moving body: where it hangs, how its joint moves it, which coordinate drives that
/// joint, and its inertia about its frame's origin.
#[derive(Debug, Clone)]
pub struct Body {
    pub parent: Option<usize>,
    pub joint: JointModel,
    pub drive: Drive,
    pub inertia: Inertial,
}

/// A robot as the algorithms take it: bodies in an order where every parent comes before
/// its children (a depth-first walk gives one).
#[derive(Debug, Clone)]
pub struct Model {
    pub bodies: Vec<Body>,
    /// Coordinates (joints that are not mimic joints).
    pub n: usize,
    /// In the root frame, m/s².
    pub gravity: [f64; 3],
    /// Whether some joint follows another's coordinate (then `forward_dynamics` solves with
    /// CRBA, since ABA takes one joint per coordinate).
    pub mimic: bool,
    /// Each coordinate's armature, the rotor inertia its gear reflects (kg m² or kg), added
    /// to M's diagonal as Pinocchio's `Model::armature` is; when present it is a parameter
    /// like π (after it in `regressor::standard_parameters`: τ gains a∘q̈).
    pub armature: Option<Vec<f64>>,
}

impl Model {
    /// A model of `bodies` driven by `n` coordinates. Every parent comes before its children
    /// and every coordinate below `n` drives some joint: the producer's promise, checked in
    /// debug builds.
    pub fn new(bodies: Vec<Body>, n: usize, gravity: [f64; 3]) -> Self {
        debug_assert!(
            (bodies.iter().enumerate()).all(|(i, b)| b.parent.is_none_or(|p| p < i)),
            "a parent after its child"
        );
        debug_assert!(bodies.iter().all(|b| b.drive.coordinate < n));
        // Each coordinate has its own joint; any body beyond those is a mimic joint's.
        let mimic = bodies.len() > n;
        Self {
            bodies,
            n,
            gravity,
            mimic,
            armature: None,
        }
    }

    /// The model with these armatures (n of them) as parameters.
    pub fn with_armature(mut self, armature: Vec<f64>) -> Self {
        assert_eq!(armature.len(), self.n, "one armature per coordinate");
        self.armature = Some(armature);
        self
    }

    /// The parameters τ is linear in: ten per body, then the armatures when it has them.
    pub fn parameter_count(&self) -> usize {
        PER_BODY * self.bodies.len() + self.armature.as_ref().map_or(0, Vec::len)
    }

    /// Coordinate c's armature (0 without).
    pub fn armature_of(&self, c: usize) -> f64 {
        self.armature.as_ref().map_or(0.0, |a| a[c])
    }
}

impl Body {
    /// X_J X_T at the coordinates q: parent to body coordinates.
    pub fn placement<S: Scalar>(&self, q: &[S], zero: &S) -> Xform<S> {
        self.joint.xform(&self.drive.value(q), zero)
    }
}
