//! Reverse-mode differentiation over a block of rows, for the fused training step: every
//! value is a column of the block's rows (or one number that every row shares), every
//! [`Scalar`] operation on a [`Var`] is one node, and [`Tape::gradients`] walks the nodes
//! backwards once. The model's equations are written over `Scalar` already, so recording
//! them needs no second copy of the math; the networks, whose layers would be thousands of
//! scalar nodes, are one node each (`mlp.rs`) with their own backward pass, computed in the
//! training's precision ([`Precision`]); the rest (a few hundred values per row) stays f64.
//!
//! A node costs a `Vec` push and an `Rc` clone; its arithmetic is a loop over the block's
//! rows (hundreds), so the bookkeeping is a small share of the work. Values live in arenas
//! that one tape hands to the next ([`Buffers`]), so recording allocates only while they grow.

mod mlp;
mod multibody;
mod ops;
mod seen;

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;

pub use mlp::{Layer, mlp};
pub use multibody::{forward_dynamics, inverse_dynamics};

/// The precision the networks compute in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    F32,
    F64,
}

/// What a tape differentiates with respect to, with the networks' copy in their precision.
#[derive(Debug)]
pub struct Params {
    values: Vec<f64>,
    narrow: Vec<f32>,
    precision: Precision,
}

impl Params {
    pub fn new(values: Vec<f64>, precision: Precision) -> Arc<Self> {
        let narrow = match precision {
            Precision::F32 => values.iter().map(|&v| v as f32).collect(),
            Precision::F64 => vec![],
        };
        Arc::new(Self {
            values,
            narrow,
            precision,
        })
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

/// A tape's storage, passed from a finished tape to the next one.
#[derive(Debug, Default)]
pub struct Buffers {
    nodes: Vec<Node>,
    vals: Vec<f64>,
    net32: Vec<f32>,
    net64: Vec<f64>,
    adj: Vec<f64>,
    seen: seen::Seen,
}

/// Where a node's value lives in the arena: `cols` columns of `len` numbers each (`len` is
/// the block's rows, or 1 for a value every row shares).
#[derive(Debug, Clone, Copy)]
struct Slot {
    start: usize,
    len: usize,
}

#[derive(Debug, Clone)]
enum Op {
    /// A row input; its adjoint is the input's gradient.
    Input,
    /// A constant: no adjoint flows anywhere.
    Const,
    /// Parameter `i`, shared by every row: its adjoint, summed, is ∂/∂θ_i.
    Param(usize),
    Unary(Ref, ops::Unary),
    Binary(Ref, Ref, ops::Binary),
    /// A network's outputs (`mlp.rs`).
    Mlp(Box<mlp::Node>),
    /// A robot's accelerations (`multibody.rs`).
    Multibody(Box<multibody::Node>),
}

#[derive(Debug, Clone)]
struct Node {
    op: Op,
    slot: Slot,
    cols: usize,
    /// The cosine of a sine's input, or the sine of a cosine's, when both are on the tape:
    /// each one's derivative is the other's value, read rather than computed again.
    partner: Option<u32>,
}

/// Column `col` of node `node`: a value on a finished tape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Ref {
    node: u32,
    col: u32,
}

/// The record of one block's computation.
#[derive(Debug)]
pub struct Tape {
    rows: usize,
    params: Arc<Params>,
    nodes: Vec<Node>,
    vals: Vec<f64>,
    /// The networks' layer blocks, in their precision.
    net32: Vec<f32>,
    net64: Vec<f64>,
    /// Storage for the next [`Tape::gradients`].
    spare: Vec<f64>,
    /// Every elementwise node by its operation and inputs: the same operation on the same
    /// values is recorded once (the assembly's dual numbers ask for cos q, products of
    /// the same entries and the like several times), its adjoint gathering every use.
    seen: seen::Seen,
}

/// A value on a tape: a column of the block's rows, or one shared number.
#[derive(Debug, Clone)]
pub struct Var {
    tape: Rc<RefCell<Tape>>,
    r: Ref,
}

/// What [`Tape::gradients`] gives: every node's adjoint (read by [`Tape::adjoint`]) and ∂/∂θ.
#[derive(Debug)]
pub struct Gradients {
    adj: Vec<f64>,
    pub params: Vec<f64>,
}

impl Tape {
    /// An empty tape for a block of `rows` rows, differentiating with respect to `params`,
    /// storing into `buffers` (emptied first).
    pub fn new(rows: usize, params: Arc<Params>, buffers: Buffers) -> Rc<RefCell<Self>> {
        let Buffers {
            mut nodes,
            mut vals,
            mut net32,
            mut net64,
            adj,
            mut seen,
        } = buffers;
        nodes.clear();
        vals.clear();
        net32.clear();
        net64.clear();
        seen.clear();
        Rc::new(RefCell::new(Self {
            rows,
            params,
            nodes,
            vals,
            net32,
            net64,
            spare: adj,
            seen,
        }))
    }

    /// The tape once recording is done and no [`Var`] on it is left.
    pub fn finish(tape: Rc<RefCell<Self>>) -> Self {
        match Rc::try_unwrap(tape) {
            Ok(t) => t.into_inner(),
            Err(_) => panic!("every variable on a tape is dropped before it is finished"),
        }
    }

    /// Its storage, for the next tape.
    pub fn into_buffers(self, grads: Option<Gradients>) -> Buffers {
        Buffers {
            nodes: self.nodes,
            vals: self.vals,
            net32: self.net32,
            net64: self.net64,
            adj: grads.map_or(self.spare, |g| g.adj),
            seen: self.seen,
        }
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    /// A node of `cols` columns of `len` values from `values`.
    fn push(
        &mut self,
        op: Op,
        len: usize,
        cols: usize,
        values: impl IntoIterator<Item = f64>,
    ) -> Ref {
        let start = self.vals.len();
        self.vals.extend(values);
        self.node(op, start, len, cols)
    }

    fn slot(&self, r: Ref) -> Slot {
        let n = &self.nodes[r.node as usize];
        Slot {
            start: n.slot.start + r.col as usize * n.slot.len,
            len: n.slot.len,
        }
    }

    /// The value of a constant node (`Scalar::lift`), which no adjoint reaches.
    fn constant(&self, r: Ref) -> Option<f64> {
        let n = &self.nodes[r.node as usize];
        matches!(n.op, Op::Const).then(|| self.vals[n.slot.start])
    }

    fn col(&self, r: Ref) -> &[f64] {
        let s = self.slot(r);
        &self.vals[s.start..s.start + s.len]
    }

    /// A recorded value: one per row, or one shared.
    pub fn values(&self, r: Ref) -> &[f64] {
        self.col(r)
    }

    /// ∂L/∂`r` from `grads` (of this tape): one number per row, or one for a shared value.
    pub fn adjoint<'g>(&self, grads: &'g Gradients, r: Ref) -> &'g [f64] {
        let s = self.slot(r);
        &grads.adj[s.start..s.start + s.len]
    }

    /// Appends node `op` whose `cols` columns of `len` values the caller has just written
    /// at the end of the arena, from `start`.
    fn node(&mut self, op: Op, start: usize, len: usize, cols: usize) -> Ref {
        debug_assert_eq!(
            self.vals.len() - start,
            len * cols,
            "a node's values fill it"
        );
        self.nodes.push(Node {
            op,
            slot: Slot { start, len },
            cols,
            partner: None,
        });
        Ref {
            node: (self.nodes.len() - 1) as u32,
            col: 0,
        }
    }

    /// The adjoints of `seeds` (each a value and ∂L/∂ it, one number per row or one for a
    /// shared value) carried back to every node: ∂L/∂ each input and each parameter.
    pub fn gradients(&mut self, seeds: &[(Ref, &[f64])]) -> Gradients {
        let mut adj = std::mem::take(&mut self.spare);
        adj.clear();
        adj.resize(self.vals.len(), 0.0);
        for (r, g) in seeds {
            let s = self.slot(*r);
            assert_eq!(
                g.len(),
                s.len,
                "a seed has one value per row of its variable"
            );
            (adj[s.start..s.start + s.len].iter_mut().zip(*g)).for_each(|(a, g)| *a += g);
        }
        let t: &Tape = self;
        let mut params = vec![0.0; t.params.len()];
        // A node no seed depends on has no adjoint to carry.
        let live = t.live(seeds.iter().map(|(r, _)| r.node));
        for (i, node) in t.nodes.iter().enumerate().rev() {
            if !live[i] {
                continue;
            }
            match &node.op {
                Op::Input | Op::Const => {}
                Op::Param(p) => params[*p] += adj[node.slot.start],
                Op::Unary(a, f) => ops::unary_back(t, &mut adj, i, *a, *f, node.partner),
                Op::Binary(a, b, f) => ops::binary_back(t, &mut adj, i, *a, *b, *f),
                Op::Mlp(m) => m.backward(t, &mut adj, &mut params, node),
                Op::Multibody(m) => m.backward(t, &mut adj, node),
            }
        }
        Gradients { adj, params }
    }
}

impl Op {
    /// Every value the node reads.
    fn each_input(&self, mut f: impl FnMut(Ref)) {
        match self {
            Op::Input | Op::Const | Op::Param(_) => {}
            Op::Unary(a, _) => f(*a),
            Op::Binary(a, b, _) => {
                f(*a);
                f(*b);
            }
            Op::Mlp(m) => m.inputs().for_each(f),
            Op::Multibody(m) => m.inputs().for_each(f),
        }
    }
}

impl Tape {
    /// Which nodes the `roots` depend on: a node is live when a live node reads it.
    fn live(&self, roots: impl IntoIterator<Item = u32>) -> Vec<bool> {
        let mut live = vec![false; self.nodes.len()];
        roots.into_iter().for_each(|r| live[r as usize] = true);
        for i in (0..self.nodes.len()).rev() {
            if live[i] {
                self.nodes[i]
                    .op
                    .each_input(|r| live[r.node as usize] = true);
            }
        }
        live
    }

    /// Whether each parameter reaches one of `outputs`. One that none does has no gradient
    /// at any rows (a template's parameter that enters V only as a constant term: training
    /// sees ∂V/∂q).
    pub fn reaches(&self, outputs: &[Ref]) -> Vec<bool> {
        let live = self.live(outputs.iter().map(|r| r.node));
        let mut reached = vec![false; self.params.len()];
        for (node, _) in self.nodes.iter().zip(&live).filter(|(_, l)| **l) {
            match &node.op {
                Op::Param(p) => reached[*p] = true,
                Op::Mlp(m) => m.params().for_each(|p| reached[p] = true),
                _ => {}
            }
        }
        reached
    }
}

impl Var {
    /// A row input: one value per row.
    pub fn input(tape: &Rc<RefCell<Tape>>, values: Vec<f64>) -> Self {
        let r = {
            let mut t = tape.borrow_mut();
            assert_eq!(values.len(), t.rows, "an input has one value per row");
            let len = t.rows;
            t.push(Op::Input, len, 1, values)
        };
        Self {
            tape: tape.clone(),
            r,
        }
    }

    /// Parameter `i` of the tape's, shared by every row.
    pub fn param(tape: &Rc<RefCell<Tape>>, i: usize) -> Self {
        let r = {
            let mut t = tape.borrow_mut();
            let v = t.params.values[i];
            t.push(Op::Param(i), 1, 1, [v])
        };
        Self {
            tape: tape.clone(),
            r,
        }
    }

    /// Its values: one per row, or one shared.
    pub fn values(&self) -> Vec<f64> {
        self.tape.borrow().col(self.r).to_vec()
    }

    /// Where it sits on its tape, to read once the tape is finished.
    pub fn id(&self) -> Ref {
        self.r
    }

    fn with(&self, r: Ref) -> Self {
        Self {
            tape: self.tape.clone(),
            r,
        }
    }
}

#[cfg(test)]
mod tests;
