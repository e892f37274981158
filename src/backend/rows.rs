//! A function of a batch's rows and one row of parameters, computed on the host in f64 and
//! recorded as one Burn op whose backward pass is the function's own vector–Jacobian
//! product: the model's whole training step (`model::fused`), where Burn's ops would
//! allocate a `[batch, 1]` column for each of its hundreds of scalar operations per row and
//! record each on Burn's tape.
//!
//! A backend extension (`#[backend_extension]`): Flex and NdArray read the
//! tensors to the host and back, and Autodiff over either keeps the host rows and outputs for
//! the backward pass.

// NdArray is deprecated upstream and selectable here on purpose (docs/training.md#why-ndarray-stays-selectable).
#![allow(deprecated)]

use std::any::Any;
use std::fmt::Debug;
use std::sync::{Arc, Mutex};

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::tensor::FloatTensor;
use burn::backend::{
    Autodiff, Backend, DType, Dispatch, Flex, NdArray, TensorMetadata, backend_extension,
};
use burn::tensor::{Tensor, TensorData};

/// What a [`RowFunction`]'s forward pass keeps for its backward pass beyond the rows, the
/// parameters and the outputs (a tape, say), taken once by the backward pass.
#[derive(Clone, Default)]
pub struct Kept(Arc<Mutex<Option<Box<dyn Any + Send>>>>);

impl Kept {
    pub fn new(value: impl Any + Send) -> Self {
        Self(Arc::new(Mutex::new(Some(Box::new(value)))))
    }

    /// The kept value, if there is one of type `T` not taken yet.
    pub fn take<T: Any>(&self) -> Option<T> {
        let mut slot = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let value = slot.take()?.downcast::<T>().ok()?;
        Some(*value)
    }
}

impl Debug for Kept {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Kept")
    }
}

/// f(row; params) for every row of a batch, and its vector–Jacobian product.
pub trait RowFunction: Send + Sync + Debug {
    /// Values per input row.
    fn input_width(&self) -> usize;
    /// Values per output row.
    fn output_width(&self) -> usize;
    /// The outputs, batch × `output_width`, of `rows` (batch × `input_width`, row-major).
    fn forward(&self, rows: &[f64], params: &[f64]) -> Vec<f64>;
    /// For `g` = ∂L/∂output (batch × `output_width`) at the outputs `out` that `forward`
    /// gave: ∂L/∂rows (batch × `input_width`) and ∂L/∂params (summed over the batch).
    fn backward(
        &self,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>);
    /// [`forward`](Self::forward) for a pass that will be differentiated: also what the
    /// backward pass may reuse (nothing, unless a function overrides this).
    fn forward_keeping(&self, rows: &[f64], params: &[f64]) -> (Vec<f64>, Kept) {
        (self.forward(rows, params), Kept::default())
    }
    /// [`backward`](Self::backward) with what [`forward_keeping`](Self::forward_keeping) kept.
    fn backward_kept(
        &self,
        _kept: &Kept,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        self.backward(rows, params, out, g)
    }
}

/// A [`RowFunction`] as the op's argument.
#[derive(Clone, Debug)]
pub struct RowFn(pub Arc<dyn RowFunction>);

#[backend_extension(Flex, NdArray, Autodiff)]
pub trait RowOps: Backend {
    /// `f` of `rows` `[batch, input_width]` with `params` `[1, p]`: `[batch, output_width]`.
    fn row_map(f: RowFn, rows: FloatTensor<Self>, params: FloatTensor<Self>) -> FloatTensor<Self>;
}

/// `f` row by row: `rows` `[batch, input_width]`, `params` `[1, p]` → `[batch, output_width]`.
pub fn row_map(f: &RowFn, rows: Tensor<2>, params: Tensor<2>) -> Tensor<2> {
    let [_, k] = rows.dims();
    assert_eq!(k, f.0.input_width(), "row_map: rows of the wrong width");
    assert_eq!(params.dims()[0], 1, "row_map: parameters are one row");
    Tensor::from_dispatch(<Dispatch as RowOps>::row_map(
        f.clone(),
        rows.into_dispatch(),
        params.into_dispatch(),
    ))
}

/// A tensor's values in f64, row-major.
fn host<B: Backend>(t: FloatTensor<B>) -> Vec<f64> {
    let data =
        burn::tensor::read_sync(B::float_into_data(t)).expect("a CPU tensor's values can be read");
    data.iter::<f64>().collect()
}

/// Host values as a tensor `shape` of `dtype` on `device`.
fn tensor<B: Backend>(
    values: Vec<f64>,
    shape: [usize; 2],
    dtype: DType,
    device: &B::Device,
) -> FloatTensor<B> {
    B::float_from_data(TensorData::new(values, shape).convert_dtype(dtype), device)
}

/// What the forward pass leaves the backward pass: host rows, parameters and outputs (in
/// f64, so that the backward pass linearises at what the forward pass computed).
#[derive(Debug, Clone)]
struct Saved {
    f: RowFn,
    rows: Vec<f64>,
    params: Vec<f64>,
    out: Vec<f64>,
    kept: Kept,
    rows_shape: [usize; 2],
    params_shape: [usize; 2],
}

/// Runs `f` on the host; returns the output tensor and what a backward pass needs (with
/// what `f` keeps for it when `tracked`).
fn run<B: Backend>(
    f: RowFn,
    rows: FloatTensor<B>,
    params: FloatTensor<B>,
    tracked: bool,
) -> (FloatTensor<B>, Saved) {
    let (dtype, device) = (rows.dtype(), rows.device());
    let rows_shape: [usize; 2] = rows.shape().dims();
    let params_shape: [usize; 2] = params.shape().dims();
    let (rows, params) = (host::<B>(rows), host::<B>(params));
    let (out, kept) = if tracked {
        f.0.forward_keeping(&rows, &params)
    } else {
        (f.0.forward(&rows, &params), Kept::default())
    };
    let width = f.0.output_width();
    let t = tensor::<B>(out.clone(), [rows_shape[0], width], dtype, &device);
    let saved = Saved {
        f,
        rows,
        params,
        out,
        kept,
        rows_shape,
        params_shape,
    };
    (t, saved)
}

impl RowOps for Flex {
    fn row_map(f: RowFn, rows: FloatTensor<Self>, params: FloatTensor<Self>) -> FloatTensor<Self> {
        run::<Self>(f, rows, params, false).0
    }
}

impl RowOps for NdArray {
    fn row_map(f: RowFn, rows: FloatTensor<Self>, params: FloatTensor<Self>) -> FloatTensor<Self> {
        run::<Self>(f, rows, params, false).0
    }
}

#[derive(Debug)]
struct RowMapBackward;

impl<B: Backend> Backward<B, 2> for RowMapBackward {
    type State = Saved;

    fn backward(self, ops: Ops<Self::State, 2>, grads: &mut Gradients, _: &mut Checkpointer) {
        let g = grads.consume::<B>(&ops.node);
        let (dtype, device) = (g.dtype(), g.device());
        let s = ops.state;
        let g = host::<B>(g);
        let (d_rows, d_params) = (s.f.0).backward_kept(&s.kept, &s.rows, &s.params, &s.out, &g);
        let [rows, params] = ops.parents;
        if let Some(node) = rows {
            grads.register::<B>(node.id, tensor::<B>(d_rows, s.rows_shape, dtype, &device));
        }
        if let Some(node) = params {
            let d = tensor::<B>(d_params, s.params_shape, dtype, &device);
            grads.register::<B>(node.id, d);
        }
    }
}

impl<B: Backend + RowOps, C: CheckpointStrategy> RowOps for Autodiff<B, C> {
    fn row_map(f: RowFn, rows: FloatTensor<Self>, params: FloatTensor<Self>) -> FloatTensor<Self> {
        match RowMapBackward
            .prepare::<C>([rows.node(), params.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let (out, saved) =
                    run::<B>(f, rows.into_primitive(), params.into_primitive(), true);
                prep.finish(saved, out)
            }
            OpsKind::UnTracked(prep) => prep.finish(B::row_map(
                f,
                rows.into_primitive(),
                params.into_primitive(),
            )),
        }
    }
}
