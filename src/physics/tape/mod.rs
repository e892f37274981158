//! Reverse-mode differentiation over a block of rows, for the fused training step: every
//! value is a column of the block's rows (or one number that every row shares), every
//! [`Scalar`] operation on a [`Var`] is one node, and [`Tape::gradients`] walks the nodes
//! backwards once. The model's equations are written over `Scalar` already, so recording
//! them needs no second copy of the math; the networks, whose layers would be thousands of
//! scalar nodes, are one node each (`mlp.rs`) with their own backward pass.
//!
//! A node costs a `Vec` push and an `Rc` clone; its arithmetic is a loop over the block's
//! rows (hundreds), so the bookkeeping is a small share of the work. Values live in one
//! arena, so recording allocates only when the arena grows.

mod mlp;
mod ops;

use std::cell::RefCell;
use std::rc::Rc;

pub use mlp::{Layer, mlp};

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
}

#[derive(Debug, Clone)]
struct Node {
    op: Op,
    slot: Slot,
    cols: usize,
}

/// Column `col` of node `node`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Ref {
    node: u32,
    col: u32,
}

/// The record of one block's computation.
#[derive(Debug)]
pub struct Tape {
    rows: usize,
    params: Rc<[f64]>,
    nodes: Vec<Node>,
    vals: Vec<f64>,
}

/// A value on a tape: a column of the block's rows, or one shared number.
#[derive(Debug, Clone)]
pub struct Var {
    tape: Rc<RefCell<Tape>>,
    r: Ref,
}

/// What [`Tape::gradients`] gives: every node's adjoint, read by variable, and ∂/∂θ.
#[derive(Debug)]
pub struct Gradients {
    adj: Vec<f64>,
    slots: Vec<(Slot, usize)>,
    pub params: Vec<f64>,
}

impl Tape {
    /// An empty tape for a block of `rows` rows, differentiating with respect to `params`.
    pub fn new(rows: usize, params: Rc<[f64]>) -> Rc<RefCell<Self>> {
        Rc::new(RefCell::new(Self {
            rows,
            params,
            nodes: Vec::with_capacity(1024),
            vals: Vec::with_capacity(1 << 16),
        }))
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
        debug_assert_eq!(
            self.vals.len() - start,
            len * cols,
            "a node's values fill it"
        );
        self.nodes.push(Node {
            op,
            slot: Slot { start, len },
            cols,
        });
        Ref {
            node: (self.nodes.len() - 1) as u32,
            col: 0,
        }
    }

    fn slot(&self, r: Ref) -> Slot {
        let n = &self.nodes[r.node as usize];
        Slot {
            start: n.slot.start + r.col as usize * n.slot.len,
            len: n.slot.len,
        }
    }

    fn col(&self, r: Ref) -> &[f64] {
        let s = self.slot(r);
        &self.vals[s.start..s.start + s.len]
    }

    /// The adjoints of `seeds` (each a variable and ∂L/∂ it, one number per row or one for a
    /// shared value) carried back to every node: ∂L/∂ each input and each parameter.
    pub fn gradients(&self, seeds: &[(&Var, &[f64])]) -> Gradients {
        let mut adj = vec![0.0; self.vals.len()];
        for (v, g) in seeds {
            let s = self.slot(v.r);
            assert_eq!(
                g.len(),
                s.len,
                "a seed has one value per row of its variable"
            );
            (adj[s.start..s.start + s.len].iter_mut().zip(*g)).for_each(|(a, g)| *a += g);
        }
        let mut params = vec![0.0; self.params.len()];
        for (i, node) in self.nodes.iter().enumerate().rev() {
            match &node.op {
                Op::Input | Op::Const => {}
                Op::Param(p) => params[*p] += adj[node.slot.start],
                Op::Unary(a, f) => ops::unary_back(self, &mut adj, i, *a, *f),
                Op::Binary(a, b, f) => ops::binary_back(self, &mut adj, i, *a, *b, *f),
                Op::Mlp(m) => m.backward(self, &mut adj, &mut params, node),
            }
        }
        let slots = self.nodes.iter().map(|n| (n.slot, n.cols)).collect();
        Gradients { adj, slots, params }
    }
}

impl Gradients {
    /// ∂L/∂`v`: one number per row (or one for a shared value).
    pub fn of(&self, v: &Var) -> &[f64] {
        let (slot, _) = self.slots[v.r.node as usize];
        let start = slot.start + v.r.col as usize * slot.len;
        &self.adj[start..start + slot.len]
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
            let v = t.params[i];
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

    fn with(&self, r: Ref) -> Self {
        Self {
            tape: self.tape.clone(),
            r,
        }
    }
}

#[cfg(test)]
mod tests;
