//! Robots from URDF (design.md §9): the rigid-body tree's M(q) and V(q) with trainable,
//! physically consistent inertial parameters.

pub mod inertia;
pub mod rigid;
pub mod term;
pub mod tree;
pub mod xml;

pub use inertia::{BodyInertia, Inertial, body_inertia};
pub use tree::{Body, JointKind, Tree};
pub mod template;
pub use template::{UrdfDoc, UrdfTemplate};
pub mod export;
