//! Robots from URDF (docs/robots.md#urdf-robots): the rigid-body tree's M(q) and V(q) with trainable,
//! physically consistent inertial parameters.

mod base;
pub mod delay;
pub mod export;
mod forces;
pub mod frame;
mod groups;
pub mod least_squares;
mod mimic;
mod multibody;
pub mod parameters;
pub mod read;
mod settings;
pub mod template;
pub mod tree;
pub mod xml;

pub use template::{UrdfDoc, UrdfTemplate};
pub use tree::{Body, JointKind, Tree};
