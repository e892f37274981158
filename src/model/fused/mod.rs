//! The fused training step: a model's whole one-step prediction x' = step(x, u; θ) as one
//! Burn op ([`row_map`]), recorded on a host tape per block of rows (`physics::tape`) and
//! differentiated by one backward walk of it, where Burn would record hundreds of small
//! tensor ops per step. Burn keeps the parameters, Adam and checkpoints: the op takes the
//! parameters as one flat row in their visiting order (the model file's order) and hands
//! back its gradient, which Burn's autodiff splits into the parameter tensors.
//!
//! The backward pass records the block again rather than keeping every block's tape from
//! the forward pass: a tape is megabytes, a batch has many blocks, and recording costs one
//! forward pass.

mod record;

use std::rc::Rc;
use std::sync::Arc;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::Tensor;

use super::{Model, ModelConfig};
use crate::backend::{RowFn, RowFunction, row_map};
use crate::physics::tape::{Layer, Tape, Var};

/// Rows per tape: enough that a node's loop dwarfs its bookkeeping, few enough that a
/// block's tape stays in cache-sized pieces.
const BLOCK: usize = 128;

/// Where each of the model's values sits in the flat parameter row.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    arrays: Vec<(String, usize, usize)>,
    nets: Vec<(String, Vec<Layer>)>,
}

impl Layout {
    fn of(model: &Model) -> Self {
        let (mut arrays, mut at) = (vec![], 0);
        for a in model.params.export() {
            arrays.push((a.name, at, a.values.len()));
            at += a.values.len();
        }
        let mut nets = vec![];
        for prefix in ["naive", "mass_net", "potential_net", "force_net", "b_net"] {
            let layer = |i: usize| -> Option<Layer> {
                let find = |what: &str| {
                    let name = format!("{prefix}.layers.{i}.{what}");
                    arrays.iter().find(|a| a.0 == name).map(|a| (a.1, a.2))
                };
                let ((w, w_len), (b, d_out)) = (find("weight")?, find("bias")?);
                Some(Layer {
                    d_in: w_len / d_out,
                    d_out,
                    w,
                    b,
                })
            };
            let layers: Vec<Layer> = (0..).map_while(layer).collect();
            if !layers.is_empty() {
                nets.push((prefix.to_string(), layers));
            }
        }
        Self { arrays, nets }
    }

    /// The offset and length of a value that is not a network's.
    fn array(&self, name: &str) -> Option<(usize, usize)> {
        self.arrays.iter().find(|a| a.0 == name).map(|a| (a.1, a.2))
    }

    fn net(&self, name: &str) -> Option<&[Layer]> {
        self.nets
            .iter()
            .find(|n| n.0 == name)
            .map(|n| n.1.as_slice())
    }
}

/// The step as a row function: a row is [x, u], the output x'.
#[derive(Debug)]
pub(super) struct FusedStep {
    config: ModelConfig,
    layout: Layout,
}

impl FusedStep {
    /// Records `rows` on a fresh tape: the tape, the input variables and x'.
    fn record(
        &self,
        rows: &[f64],
        params: &Rc<[f64]>,
    ) -> (Rc<std::cell::RefCell<Tape>>, Vec<Var>, Vec<Var>) {
        let width = self.input_width();
        let count = rows.len() / width;
        let tape = Tape::new(count, params.clone());
        let inputs: Vec<Var> = (0..width)
            .map(|j| Var::input(&tape, rows.iter().skip(j).step_by(width).copied().collect()))
            .collect();
        let nx = 2 * self.config.n;
        let out = record::step(
            &self.config,
            &self.layout,
            &tape,
            &inputs[..nx],
            &inputs[nx..],
        );
        (tape, inputs, out)
    }
}

impl RowFunction for FusedStep {
    fn input_width(&self) -> usize {
        2 * self.config.n + self.config.m
    }

    fn output_width(&self) -> usize {
        2 * self.config.n
    }

    fn forward(&self, rows: &[f64], params: &[f64]) -> Vec<f64> {
        let params: Rc<[f64]> = Rc::from(params);
        let (w, nx) = (self.input_width(), self.output_width());
        let mut out = Vec::with_capacity(rows.len() / w * nx);
        for block in rows.chunks(BLOCK * w) {
            let (_, _, x) = self.record(block, &params);
            let cols: Vec<Vec<f64>> = x.iter().map(Var::values).collect();
            let count = block.len() / w;
            for k in 0..count {
                out.extend(cols.iter().map(|c| c[k % c.len()]));
            }
        }
        out
    }

    fn backward(
        &self,
        rows: &[f64],
        params: &[f64],
        _out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let params: Rc<[f64]> = Rc::from(params);
        let (w, nx) = (self.input_width(), self.output_width());
        let mut d_rows = vec![0.0; rows.len()];
        let mut d_params = vec![0.0; params.len()];
        for (b, (block, gb)) in rows.chunks(BLOCK * w).zip(g.chunks(BLOCK * nx)).enumerate() {
            let (tape, inputs, x) = self.record(block, &params);
            let count = block.len() / w;
            let seeds: Vec<Vec<f64>> = (0..nx)
                .map(|j| {
                    let col: Vec<f64> = gb.iter().skip(j).step_by(nx).copied().collect();
                    // An output every row shares takes the rows' seeds summed.
                    if x[j].values().len() == 1 {
                        vec![col.iter().sum()]
                    } else {
                        col
                    }
                })
                .collect();
            let t = tape.borrow();
            let pairs: Vec<(&Var, &[f64])> =
                x.iter().zip(&seeds).map(|(v, s)| (v, &s[..])).collect();
            let grads = t.gradients(&pairs);
            for (j, v) in inputs.iter().enumerate() {
                let d = grads.of(v);
                for k in 0..count {
                    d_rows[(b * BLOCK + k) * w + j] = d[k % d.len()];
                }
            }
            d_params
                .iter_mut()
                .zip(&grads.params)
                .for_each(|(a, g)| *a += g);
        }
        (d_rows, d_params)
    }
}

/// Every parameter tensor of a module in visiting order, flattened into one row.
struct Flatten(Vec<Tensor<2>>);

impl ModuleVisitor for Flatten {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let t = param.val();
        let count = t.dims().iter().product::<usize>();
        self.0.push(t.reshape([1, count]));
    }
}

impl Model {
    /// The same model training through the fused step (its forward and backward passes on
    /// the host tape) instead of Burn's op-by-op graph. URDF models on the recursive
    /// algorithms keep their own op.
    pub fn fused(mut self) -> Self {
        if self.consts.rigid.is_none() {
            let layout = Layout::of(&self);
            let step = FusedStep {
                config: self.config.clone(),
                layout,
            };
            self.consts.fused = Some(RowFn(Arc::new(step)));
        }
        self
    }

    /// x' by the fused op.
    pub(super) fn fused_step(&self, f: &RowFn, x: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
        let mut flat = Flatten(vec![]);
        self.params.visit(&mut flat);
        row_map(f, Tensor::cat(vec![x, u], 1), Tensor::cat(flat.0, 1))
    }
}
