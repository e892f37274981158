//! tanh as one Burn operation whose backward pass reads its output: a network's hidden layers
//! were ~35% (MVF) to 55% (naive) of a training step as Burn's ops (tanh through libm, or
//! 2σ(2z) − 1 as three passes forward and a recomputed σ backward). Here the forward is one
//! vectorised pass (`simd.rs`) and the backward one pass of g(1 − y²) from the saved output.
//!
//! Burn's backend extension (`#[backend_extension]`) routes the op to the backend a tensor
//! lives on; every backend graybox selects implements it (an unlisted one would panic): Flex
//! with the vectorised kernels, NdArray with Burn's own ops, and Autodiff over either with the
//! backward pass written out.

// NdArray is deprecated upstream and selectable here on purpose (docs/training.md#why-ndarray-stays-selectable).
#![allow(deprecated)]

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind, unary};
use burn::backend::flex::FlexTensor;
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::{Autodiff, Backend, DType, Dispatch, Flex, NdArray, backend_extension};
use burn::tensor::Tensor;

use crate::simd;

#[backend_extension(Flex, NdArray, Autodiff)]
pub trait TanhOps: Backend {
    /// tanh, elementwise.
    fn tanh_fused(x: FloatTensor<Self>) -> FloatTensor<Self>;
    /// g ⊙ (1 − y²), tanh's backward from its output y.
    fn tanh_backward(y: FloatTensor<Self>, g: FloatTensor<Self>) -> FloatTensor<Self>;
}

/// tanh of every element.
pub fn tanh<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    Tensor::from_dispatch(<Dispatch as TanhOps>::tanh_fused(x.into_dispatch()))
}

/// `t` as a contiguous tensor from offset 0, so that its first elements are its values in
/// order (writing through `storage_mut` copies a buffer another tensor shares).
fn contiguous(t: FlexTensor) -> FlexTensor {
    if t.layout().is_contiguous() && t.layout().start_offset() == 0 {
        t
    } else {
        t.to_contiguous()
    }
}

impl TanhOps for Flex {
    fn tanh_fused(x: FlexTensor) -> FlexTensor {
        let mut x = contiguous(x);
        let n = x.layout().num_elements();
        match x.dtype() {
            DType::F32 => simd::tanh_in_place_f32(&mut x.storage_mut::<f32>()[..n]),
            DType::F64 => simd::tanh_in_place(&mut x.storage_mut::<f64>()[..n]),
            _ => return Flex::float_tanh(x),
        }
        x
    }

    fn tanh_backward(y: FlexTensor, g: FlexTensor) -> FlexTensor {
        let (y, mut g) = (contiguous(y), contiguous(g));
        let n = g.layout().num_elements();
        assert_eq!(n, y.layout().num_elements(), "tanh_backward: shapes differ");
        match g.dtype() {
            DType::F32 => simd::tanh_grad_in_place_f32(
                &mut g.storage_mut::<f32>()[..n],
                &y.storage::<f32>()[..n],
            ),
            DType::F64 => {
                simd::tanh_grad_in_place(&mut g.storage_mut::<f64>()[..n], &y.storage::<f64>()[..n])
            }
            _ => return generic_backward::<Flex>(y, g),
        }
        g
    }
}

/// g ⊙ (1 − y²) from Burn's own ops.
fn generic_backward<B: Backend>(y: FloatTensor<B>, g: FloatTensor<B>) -> FloatTensor<B> {
    let y2 = B::float_mul(y.clone(), y);
    B::float_mul(g, B::float_add_scalar(B::float_neg(y2), 1f32.into()))
}

impl TanhOps for NdArray {
    fn tanh_fused(x: FloatTensor<Self>) -> FloatTensor<Self> {
        NdArray::float_tanh(x)
    }

    fn tanh_backward(y: FloatTensor<Self>, g: FloatTensor<Self>) -> FloatTensor<Self> {
        generic_backward::<NdArray>(y, g)
    }
}

#[derive(Debug)]
struct TanhBackward;

impl<B: Backend + TanhOps> Backward<B, 1> for TanhBackward {
    /// The output, which the derivative 1 − y² needs (kept, not recomputed).
    type State = FloatTensor<B>;

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let y = ops.state;
        unary::<B, _>(ops.parents, ops.node, grads, |g| B::tanh_backward(y, g));
    }
}

impl<B: Backend + TanhOps, C: CheckpointStrategy> TanhOps for Autodiff<B, C> {
    fn tanh_fused(x: FloatTensor<Self>) -> FloatTensor<Self> {
        match TanhBackward
            .prepare::<C>([x.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let y = B::tanh_fused(x.into_primitive());
                prep.finish(y.clone(), y)
            }
            OpsKind::UnTracked(prep) => prep.finish(B::tanh_fused(x.into_primitive())),
        }
    }

    fn tanh_backward(y: FloatTensor<Self>, g: FloatTensor<Self>) -> FloatTensor<Self> {
        // Only ever called on the inner backend's tensors (from `TanhBackward`); a
        // differentiable version would be the composition of Burn's ops.
        let y2 = Self::float_mul(y.clone(), y);
        Self::float_mul(g, Self::float_add_scalar(Self::float_neg(y2), 1f32.into()))
    }
}
