//! Dense linear algebra written once over the mechanics' [`Scalar`](crate::physics::scalar::Scalar),
//! so the f64 algorithms, the forward-mode types and training's scalars share one
//! implementation. It uses nothing of `physics` but that trait; `physics` and `control` use it.

pub mod cholesky;
