//! Backend and precision selection, and graybox's own Burn operation (`rows.rs`: a host
//! function of each row with its vector–Jacobian product, the training step's). Burn fixes
//! a device's float type once per process (docs/training.md#precision), so precision is a process-level
//! setting.

mod rows;

pub use rows::{Kept, RowFn, RowFunction, row_map};

use burn::tensor::{Device, FloatDType};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// Burn's pure-Rust CPU backend.
    #[default]
    Flex,
    /// The ndarray CPU backend (deprecated upstream, kept selectable).
    Ndarray,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    #[default]
    F32,
    F64,
}

impl Precision {
    fn dtype(self) -> FloatDType {
        match self {
            Precision::F32 => FloatDType::F32,
            Precision::F64 => FloatDType::F64,
        }
    }
}

/// The plain (non-autodiff) device of `backend` with its float type set to `precision`.
/// Asking for another precision than the one this process already uses is an error.
pub fn device(backend: Backend, precision: Precision) -> Result<Device> {
    let mut device = match backend {
        Backend::Flex => Device::flex(),
        #[allow(deprecated)]
        // selectable on purpose (docs/training.md#why-ndarray-stays-selectable); flex is the default
        Backend::Ndarray => Device::ndarray(),
    };
    if device.configure(precision.dtype()).is_err()
        && device.settings().float_dtype != precision.dtype()
    {
        return Err(Error::invalid(
            "precision",
            format!(
                "this process already computes in {:?} on {backend:?}; precision is fixed per process",
                device.settings().float_dtype
            ),
        ));
    }
    Ok(device)
}
