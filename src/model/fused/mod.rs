//! The fused training step: a model's whole one-step prediction x' = step(x, u; θ) as one
//! Burn op ([`row_map`]), recorded on a host tape per block of rows (`physics::tape`) and
//! differentiated by one backward walk of it, where Burn would record hundreds of small
//! tensor ops per step. Burn keeps the parameters, Adam and checkpoints: the op takes the
//! parameters as one flat row in their visiting order (the model file's order) and hands
//! back its gradient, which Burn's autodiff splits into the parameter tensors.
//!
//! A forward pass that will be differentiated keeps every block's tape for the backward
//! pass (recording again would cost a second forward pass); one that will not recycles
//! each block's storage as soon as its outputs are read.

mod record;

use std::sync::{Arc, Mutex};

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::Tensor;

use super::{Model, ModelConfig, names};
use crate::backend::{Kept, RowFn, RowFunction, row_map};
use crate::error::{Error, Result};
use crate::physics::multibody;
use crate::physics::tape::{Buffers, Gradients, Layer, Params, Precision, Ref, Tape, Var};
use crate::physics::urdf::delay::input_width;

/// Rows per tape: enough that a node's loop dwarfs its bookkeeping, few enough that a
/// block's tape stays in cache-sized pieces.
const BLOCK: usize = 128;

/// Tapes' storage kept for reuse: a batch's blocks (a forward pass keeps them all for its
/// backward pass) up to 64 · 128 rows without allocating.
const POOL: usize = 64;

/// Where each of the model's values sits in the flat parameter row.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    arrays: Vec<(String, usize, usize)>,
    nets: Vec<(String, Vec<Layer>)>,
}

impl Layout {
    fn of(params: &super::Params) -> Self {
        let (mut arrays, mut at) = (vec![], 0);
        for a in params.export() {
            arrays.push((a.name, at, a.values.len()));
            at += a.values.len();
        }
        let mut nets = vec![];
        for prefix in [
            names::NAIVE,
            names::MASS_NET,
            names::POTENTIAL_NET,
            names::FORCE_NET,
            names::B_NET,
            names::DAMPING_NET,
        ] {
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
pub(crate) struct FusedStep {
    config: ModelConfig,
    layout: Layout,
    precision: Precision,
    /// The robot whose algorithms give q̈, when they do (see `Model::assembled`).
    robot: Option<multibody::Model>,
    /// Finished tapes' storage, for the next ones.
    pool: Mutex<Vec<Buffers>>,
    kind: Kind,
}

/// What the op computes of a row.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Kind {
    /// x' of [x, u].
    Step,
    /// x' of [x, u, Δt_i / Δt] (transitions of their own steps: `record::step`).
    Timed,
    /// The torque loss's errors of [q, q̇, q̈, inputs] (the inputs' block `urdf::delay`'s
    /// when the robot has an effort delay), joint j's divided by the scale's j-th value
    /// (`record::torque`).
    Torque(Vec<f64>),
}

/// One block's finished tape: where its inputs and outputs are on it.
struct Block {
    tape: Tape,
    inputs: Vec<Ref>,
    outputs: Vec<Ref>,
}

impl FusedStep {
    /// Records `rows` on a fresh tape.
    fn record(&self, rows: &[f64], params: &Arc<Params>) -> Block {
        let width = self.input_width();
        let count = rows.len() / width;
        let buffers = self.pool.lock().ok().and_then(|mut p| p.pop());
        let tape = Tape::new(count, params.clone(), buffers.unwrap_or_default());
        let inputs: Vec<Var> = (0..width)
            .map(|j| Var::input(&tape, rows.iter().skip(j).step_by(width).copied().collect()))
            .collect();
        let (nq, nv, m) = (self.config.nq(), self.config.nv(), self.config.m);
        let recipe = record::Recipe {
            config: &self.config,
            layout: &self.layout,
            robot: self.robot.as_ref(),
        };
        let (nx, at) = (nq + nv, |r: std::ops::Range<usize>| &inputs[r]);
        let out = match &self.kind {
            Kind::Step => record::step(&recipe, &tape, at(0..nx), at(nx..nx + m), None),
            Kind::Timed => {
                let scale = Some(&inputs[nx + m]);
                record::step(&recipe, &tape, at(0..nx), at(nx..nx + m), scale)
            }
            Kind::Torque(scale) => {
                let measured = (at(0..nq), at(nq..nx), at(nx..nx + nv));
                let efforts = at(nx + nv..width);
                record::torque(&recipe, &tape, measured, efforts, scale)
            }
        };
        let block_inputs = inputs.iter().map(Var::id).collect();
        let outputs = out.iter().map(Var::id).collect();
        drop((inputs, out));
        Block {
            tape: Tape::finish(tape),
            inputs: block_inputs,
            outputs,
        }
    }

    fn recycle(&self, tape: Tape, grads: Option<Gradients>) {
        if let Ok(mut pool) = self.pool.lock()
            && pool.len() < POOL
        {
            pool.push(tape.into_buffers(grads));
        }
    }

    /// The block's outputs, row-major, appended to `out`.
    fn outputs(block: &Block, out: &mut Vec<f64>) {
        let cols: Vec<&[f64]> = block
            .outputs
            .iter()
            .map(|&r| block.tape.values(r))
            .collect();
        for k in 0..block.tape.rows() {
            out.extend(cols.iter().map(|c| c[k % c.len()]));
        }
    }

    fn params(&self, params: &[f64]) -> Arc<Params> {
        Params::new(params.to_vec(), self.precision)
    }

    /// Every block of `rows`, recorded.
    fn blocks(&self, rows: &[f64], params: &Arc<Params>) -> Vec<Block> {
        let w = self.input_width();
        rows.chunks(BLOCK * w)
            .map(|b| self.record(b, params))
            .collect()
    }

    /// ∂L/∂rows and ∂L/∂θ from the recorded `blocks` and ∂L/∂x' `g`; the blocks' storage
    /// goes back to the pool.
    fn gradients(&self, blocks: Vec<Block>, g: &[f64], params: usize) -> (Vec<f64>, Vec<f64>) {
        let (w, nx) = (self.input_width(), self.output_width());
        let mut d_rows = Vec::with_capacity(g.len() / nx * w);
        let mut d_params = vec![0.0; params];
        for (mut block, gb) in blocks.into_iter().zip(g.chunks(BLOCK * nx)) {
            let count = block.tape.rows();
            let seeds: Vec<Vec<f64>> = (0..nx)
                .map(|j| {
                    let col = gb.iter().skip(j).step_by(nx).copied();
                    // An output every row shares takes the rows' seeds summed.
                    match block.tape.values(block.outputs[j]).len() {
                        1 => vec![col.sum()],
                        _ => col.collect(),
                    }
                })
                .collect();
            let pairs: Vec<(Ref, &[f64])> = block
                .outputs
                .iter()
                .zip(&seeds)
                .map(|(&r, s)| (r, &s[..]))
                .collect();
            let grads = block.tape.gradients(&pairs);
            let d: Vec<&[f64]> = (block.inputs.iter())
                .map(|&r| block.tape.adjoint(&grads, r))
                .collect();
            for k in 0..count {
                d_rows.extend(d.iter().map(|d| d[k % d.len()]));
            }
            (d_params.iter_mut().zip(&grads.params)).for_each(|(a, g)| *a += g);
            self.recycle(block.tape, Some(grads));
        }
        (d_rows, d_params)
    }
}

impl RowFunction for FusedStep {
    fn input_width(&self) -> usize {
        let (nx, m) = (self.config.nx(), self.config.m);
        match self.kind {
            Kind::Step => nx + m,
            Kind::Timed => nx + m + 1,
            Kind::Torque(_) => nx + self.config.nv() + input_width(m, self.config.effort_lags()),
        }
    }

    fn output_width(&self) -> usize {
        match self.kind {
            Kind::Step | Kind::Timed => self.config.nx(),
            Kind::Torque(_) => self.config.nv(),
        }
    }

    fn forward(&self, rows: &[f64], params: &[f64]) -> Vec<f64> {
        let params = self.params(params);
        let w = self.input_width();
        let mut out = Vec::with_capacity(rows.len() / w * self.output_width());
        for block in rows.chunks(BLOCK * w) {
            let block = self.record(block, &params);
            Self::outputs(&block, &mut out);
            self.recycle(block.tape, None);
        }
        out
    }

    fn forward_keeping(&self, rows: &[f64], params: &[f64]) -> (Vec<f64>, Kept) {
        let params = self.params(params);
        let blocks = self.blocks(rows, &params);
        let mut out = Vec::with_capacity(rows.len() / self.input_width() * self.output_width());
        blocks.iter().for_each(|b| Self::outputs(b, &mut out));
        (out, Kept::new(blocks))
    }

    fn backward(
        &self,
        rows: &[f64],
        params: &[f64],
        _out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let p = self.params(params);
        self.gradients(self.blocks(rows, &p), g, params.len())
    }

    fn backward_kept(
        &self,
        kept: &Kept,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        match kept.take::<Vec<Block>>() {
            Some(blocks) => self.gradients(blocks, g, params.len()),
            None => self.backward(rows, params, out, g),
        }
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

/// The model's ops: its step, its step on rows of their own Δt and its torque errors; a
/// robot's by its multibody algorithms when `multibody`.
pub(super) fn ops(
    config: &ModelConfig,
    params: &super::Params,
    multibody: bool,
) -> [Arc<FusedStep>; 3] {
    let torque = Kind::Torque(torque_scale(config));
    [Kind::Step, Kind::Timed, torque]
        .map(|k| Arc::new(FusedStep::new(config, params, (multibody, k))))
}

impl FusedStep {
    /// The op of `kind` for `config`'s model with parameters like `params`; a robot's q̈
    /// (or τ) by its multibody algorithms when `multibody` (else by its template's assembly).
    pub(super) fn new(
        config: &ModelConfig,
        params: &super::Params,
        (multibody, kind): (bool, Kind),
    ) -> Self {
        let mut flat = Flatten(vec![]);
        params.visit(&mut flat);
        // The networks compute in the process's precision; the rest of the step in f64.
        let precision = match flat.0.first().map(|t| t.dtype()) {
            Some(burn::tensor::DType::F64) => Precision::F64,
            _ => Precision::F32,
        };
        Self {
            config: config.clone(),
            layout: Layout::of(params),
            precision,
            robot: if multibody { robot(config) } else { None },
            pool: Mutex::new(vec![]),
            kind,
        }
    }

    pub(super) fn is_multibody(&self) -> bool {
        self.robot.is_some()
    }
}

/// Each joint's unit of the torque loss's error: the spread of its measured effort where
/// every joint has an input of its own (m = nv, the efforts of a robot's log), else the
/// model's typical force on it (`Scaling::force_scale`); a joint whose spread is zero takes
/// the largest one's, so no error is divided by zero.
pub(super) fn torque_scale(config: &ModelConfig) -> Vec<f64> {
    let s = &config.scaling;
    let own = match config.m == config.nv() {
        true => &s.u_std,
        false => &s.force_scale,
    };
    let largest = own
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let floor = if largest > 0.0 { largest } else { 1.0 };
    (own.iter())
        .map(|&v| if v.is_finite() && v > 0.0 { v } else { floor })
        .collect()
}

/// The tree of `config`'s robot, when its q̈ comes from the multibody algorithms (its
/// inertias are the template's defaults: training replaces them by π's).
fn robot(config: &ModelConfig) -> Option<multibody::Model> {
    let (t, gravity) = config.spec.multibody()?;
    let defaults = config.template()?.defaults();
    Some(t.multibody_model(&defaults, gravity))
}

impl Model {
    /// x' by the fused op; each row `scale[i]` times Δt long when given (`[B, 1]`).
    pub(super) fn fused_step(
        &self,
        x: Tensor<2>,
        u: Tensor<2>,
        scale: Option<Tensor<2>>,
    ) -> Tensor<2> {
        let (f, rows) = match scale {
            None => (RowFn(self.step.clone()), vec![x, u]),
            Some(s) => (RowFn(self.timed_step()), vec![x, u, s]),
        };
        row_map(&f, Tensor::cat(rows, 1), self.flat_params())
    }

    fn timed_step(&self) -> Arc<FusedStep> {
        self.timed.clone()
    }

    /// The torque loss's errors of rows [q, q̇, q̈, u] `[B, nq + 2nv + m]`: the manipulator
    /// equation's residual, each joint's in units of its scale (docs/training.md#torque-loss).
    pub fn torque_errors(&self, rows: Tensor<2>) -> Tensor<2> {
        row_map(&RowFn(self.torque.clone()), rows, self.flat_params())
    }

    /// Σ over the rows of their squared torque errors.
    pub fn torque_sum(&self, rows: Tensor<2>) -> Tensor<1> {
        self.torque_errors(rows).square().sum()
    }

    /// Every parameter in one row, in the order the fused step reads them.
    fn flat_params(&self) -> Tensor<2> {
        let mut flat = Flatten(vec![]);
        self.params.visit(&mut flat);
        Tensor::cat(flat.0, 1)
    }

    /// A step's gradient must reach some parameter, else training would "succeed" having
    /// learned nothing: checked on the recorded step's structure, which is the same for any
    /// rows.
    pub fn check_learns(&self) -> Result<()> {
        let f = &self.step;
        let params: Vec<f64> = self.flat_params().into_data().iter::<f64>().collect();
        let block = f.record(&vec![0.0; f.input_width()], &f.params(&params));
        let reached = block.tape.reaches(&block.outputs);
        f.recycle(block.tape, None);
        if reached.contains(&true) {
            return Ok(());
        }
        Err(Error::invalid(
            "template",
            "no trainable parameter: the loss depends on none of the model's values (a template \
             parameter that enters V only as a constant term has no gradient); give the template a \
             parameter that M, ∂V/∂q or F depends on, or choose a model with a network",
        ))
    }
}
