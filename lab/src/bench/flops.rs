//! The arithmetic a training step of a model's networks needs, and what this machine's matrix
//! kernel does per second: `bench step`'s share of the machine's limit.
//!
//! A network evaluated with `dirs` input tangents (the mass and potential networks carry one
//! per coordinate, for the Coriolis term and ∂V/∂q) multiplies each layer's weights by 1 +
//! dirs columns per row; its backward pass does that twice more (∂W and ∂x). So a sample
//! costs Σ_layers 2 · d_in · d_out · (1 + dirs) · stages · 3 floating-point operations, the
//! elementwise work (tanh, the assembly, the solve) left out.

use std::time::Instant;

use graybox::model::{Model, names};
use graybox::physics::integrator::Integrator;

/// Network FLOPs of one training sample (forward and backward) of `model`.
pub fn per_sample(model: &Model) -> f64 {
    let c = &model.config;
    let stages = match c.integrator {
        Integrator::Rk4 => 4.0,
        Integrator::Midpoint => 2.0,
        Integrator::Euler => 1.0,
    };
    let macs: f64 = (model.params.export().iter())
        .filter(|a| a.name.contains(".layers.") && a.name.ends_with(".weight"))
        .map(|a| {
            let with_tangents =
                a.name.starts_with(names::MASS_NET) || a.name.starts_with(names::POTENTIAL_NET);
            let dirs = if with_tangents { c.nv() } else { 0 };
            (a.values.len() * (1 + dirs)) as f64
        })
        .sum();
    2.0 * macs * stages * 3.0
}

/// One core's f32 matrix-product rate (FLOP/s): matrixmultiply's sgemm, the kernel the fused
/// step's networks run on, on 256 × 256 matrices (in cache, no packing-bound shapes) for
/// half a second.
pub fn sgemm_per_core() -> f64 {
    const N: usize = 256;
    let (a, b) = (vec![0.5f32; N * N], vec![0.25f32; N * N]);
    let mut c = vec![0.0f32; N * N];
    let (start, mut calls) = (Instant::now(), 0u32);
    while start.elapsed().as_secs_f64() < 0.5 {
        // SAFETY: all three are N × N row-major, and c is a unique borrow.
        unsafe {
            matrixmultiply::sgemm(
                N,
                N,
                N,
                1.0,
                a.as_ptr(),
                N as isize,
                1,
                b.as_ptr(),
                N as isize,
                1,
                0.0,
                c.as_mut_ptr(),
                N as isize,
                1,
            );
        }
        calls += 1;
    }
    2.0 * (N * N * N) as f64 * f64::from(calls) / start.elapsed().as_secs_f64()
}
