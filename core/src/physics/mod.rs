//! The mechanics, written once over [`scalar::Scalar`] and free of Burn: the manipulator
//! equation (`dynamics`), the assembly of L, ∇V and F from a model's parts (`assembly`,
//! `parts`, `mass_matrix`, `scaling`), integrators, dual numbers for ∂/∂q, and the white-box
//! systems with their physical parameters: built-in templates, formula templates and URDF
//! robots. Training records it on the tape (`tape`), inference, simulation and
//! control on f64 and dual numbers. It imports only `error`, `rng`, `simd`'s elementwise kernels and the name rule of
//! `records`; the math behind it is in docs/dynamics.md and docs/robots.md.

pub mod assembly;
pub mod documents;
pub mod dual;
pub mod dynamics;
pub mod eigen;
pub mod energy;
pub mod formula;
pub mod formula_template;
pub mod identify;
pub mod integrator;
pub mod mass_matrix;
pub mod multibody;
pub mod params;
pub mod parts;
pub mod scalar;
pub mod scaling;
pub mod space;
pub mod stiffness;
pub mod tangents;
pub mod tape;
pub mod templates;
pub mod urdf;

/// The most coordinates a template document may have, whatever the service's `--max-dof`
/// (which may only be lower): documents are read inside model files and job specs too, and
/// their checks grow as n³.
pub const MAX_DOF: usize = 256;
