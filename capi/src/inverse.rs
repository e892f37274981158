//! Inverse dynamics in a controller's process: the generalized force that produces given
//! accelerations (a robot's feed-forward torque), as the service's InverseDynamics answers.

use graybox_core::error::Error;
use graybox_core::infer::finite_rows;

use crate::boundary::{batch_of, guard, input, output, values};
use crate::{GbxModel, GbxStatus, model_ref};

/// τ = M(q) q̈ + c(q, q̇) + ∇V(q) − F(q, q̇, 0) for `batch` states: `x` [batch, nq + nv] and
/// `qdd` [batch, nv] row-major give `tau` [batch, nv], the generalized force the inputs must
/// add (a URDF robot's joint torques). An ensemble answers with its members' mean. A naive
/// model has none: `GBX_STATUS_INVALID_ARGUMENT`, naming the model. The call allocates its
/// scratch (it is not one of the workspace's allocation-free calls).
///
/// # Safety
/// `model` is a loaded model; the arrays hold the sizes above.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_inverse_dynamics(
    model: *const GbxModel,
    x: *const f64,
    qdd: *const f64,
    batch: usize,
    tau: *mut f64,
) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        // A naive model's refusal is the caller's to mend, not the library's fault.
        (m.eval.check_energy()).map_err(|e| Error::invalid("model", e.to_string()))?;
        let (nx, b) = (m.nq + m.nv, batch_of(batch)?);
        values("x", b, nx)?;
        let lt = values("qdd", b, m.nv)?;
        // SAFETY (all three): the caller promises these sizes.
        let (x, qdd) = unsafe { (input(x, b, nx, "x")?, input(qdd, b, m.nv, "qdd")?) };
        let out = unsafe { output(tau, lt, "tau")? };
        let inv = m.eval.inverse_dynamics_until(x, qdd, &|| false)?;
        let inv = inv.ok_or(Error::Cancelled)?;
        finite_rows("x", "generalized force", &inv.tau, m.nv)?;
        out.copy_from_slice(&inv.tau);
        Ok(())
    })
}
