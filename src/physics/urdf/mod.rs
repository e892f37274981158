//! Robots from URDF (docs/robots.md#urdf-robots): the rigid-body tree's M(q) and V(q) with trainable,
//! physically consistent inertial parameters.

pub mod frame;
pub mod inertia;
mod mimic;
pub mod parameters;
pub mod read;
pub mod rigid;
mod settings;
pub mod term;
pub mod tree;
pub mod xml;

pub use inertia::{BodyInertia, Inertial, body_inertia};
pub use tree::{Body, JointKind, Tree};
pub mod template;
pub use template::{UrdfDoc, UrdfTemplate};
pub mod export;
pub mod featherstone;
