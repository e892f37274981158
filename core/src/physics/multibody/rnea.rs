//! Inverse dynamics by the recursive Newton–Euler algorithm (Featherstone 2008, Table 5.1)
//! and M(q) by the composite rigid-body algorithm (Table 6.2), over the coordinates (mimic
//! joints contracted with G), as entry points for one call (`thread_data::with_workspace`): the
//! algorithms themselves are `Data`'s (`Data::accelerations` and `Data::torques` are RNEA's
//! two passes, `Data::mass` is CRBA), written once for every scalar.

use super::Model;
use super::data::Data;
use super::spatial::Inertial;
use super::thread_data::with_workspace;
use crate::physics::scalar::Scalar;

fn at_rest<S: Scalar>(q: &[S]) -> Vec<S> {
    vec![q[0].lift(0.0); q.len()]
}

/// τ = ID(q, q̇, q̈) = M(q) q̈ + C(q, q̇) q̇ + g(q).
pub fn inverse_dynamics<S: Scalar>(model: &Model, q: &[S], qd: &[S], qdd: &[S]) -> Vec<S> {
    with_workspace(model, q, |data| {
        data.kinematics(model, q, qd);
        data.qdd.clone_from_slice(qdd);
        data.inverse_torques(model);
        data.bias.clone()
    })
}

/// g(q) = ID(q, 0, 0) = ∂V/∂q.
pub fn gravity_torques<S: Scalar>(model: &Model, q: &[S]) -> Vec<S> {
    bias(model, q, &at_rest(q))
}

/// C(q, q̇) q̇ = ID(q, q̇, 0) without gravity.
pub fn coriolis<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> Vec<S> {
    with_workspace(model, q, |data| {
        data.kinematics_without_gravity(model, q, qd);
        data.torques(model);
        data.bias.clone()
    })
}

/// C(q, q̇) q̇ + g(q) = ID(q, q̇, 0).
pub fn bias<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> Vec<S> {
    with_workspace(model, q, |data| {
        data.kinematics(model, q, qd);
        data.torques(model);
        data.bias.clone()
    })
}

/// M(q) over the coordinates (rows), by CRBA.
pub fn crba<S: Scalar>(model: &Model, q: &[S]) -> Vec<Vec<S>> {
    with_workspace(model, q, |data| {
        data.kinematics(model, q, &at_rest(q));
        rows_of_mass(model, data)
    })
}

/// M(q) by CRBA with the bodies' inertias given over the scalar in place of the model's (a
/// URDF template's trainable values, which training differentiates M with respect to).
pub fn crba_with<S: Scalar>(model: &Model, q: &[S], inertias: &[Inertial<S>]) -> Vec<Vec<S>> {
    with_workspace(model, q, |data| {
        data.kinematics_with(model, q, &at_rest(q), inertias);
        rows_of_mass(model, data)
    })
}

fn rows_of_mass<S: Scalar>(model: &Model, data: &mut Data<S>) -> Vec<Vec<S>> {
    data.mass(model);
    data.mass.chunks_exact(model.n).map(<[S]>::to_vec).collect()
}
