//! The tape's elementwise nodes: [`Scalar`] and the arithmetic operators on [`Var`], each
//! recorded with what its backward pass needs (its inputs' and its own values, in the arena).
//! A value every row shares (length 1) broadcasts against a column, and its adjoint is the
//! column's summed.

use std::ops::{Add, Div, Mul, Neg, Sub};

use super::{Op, Ref, Tape, Var};
use crate::physics::scalar::Scalar;

#[derive(Debug, Clone, Copy)]
pub(super) enum Unary {
    Neg,
    Scale(f64),
    Shift(f64),
    Cos,
    Sin,
    Sqrt,
    Exp,
    Ln,
    Sigmoid,
    Softplus,
    Tanh,
    Square,
}

#[derive(Debug, Clone, Copy)]
pub(super) enum Binary {
    Add,
    Sub,
    Mul,
    Div,
    /// atan2(a, b): the angle of (x, y) = (b, a).
    Atan2,
}

impl Unary {
    fn apply(self, x: f64) -> f64 {
        match self {
            Unary::Neg => -x,
            Unary::Scale(c) => c * x,
            Unary::Shift(c) => x + c,
            Unary::Cos => x.cos(),
            Unary::Sin => x.sin(),
            Unary::Sqrt => x.sqrt(),
            Unary::Exp => x.exp(),
            Unary::Ln => x.ln(),
            Unary::Sigmoid => x.sigmoid(),
            Unary::Softplus => x.softplus(),
            Unary::Tanh => x.tanh(),
            Unary::Square => x * x,
        }
    }

    /// f′ at input `x` with output `y`.
    fn derivative(self, x: f64, y: f64) -> f64 {
        match self {
            Unary::Neg => -1.0,
            Unary::Scale(c) => c,
            Unary::Shift(_) => 1.0,
            Unary::Cos => -x.sin(),
            Unary::Sin => x.cos(),
            Unary::Sqrt => 0.5 / y,
            Unary::Exp => y,
            Unary::Ln => 1.0 / x,
            Unary::Sigmoid => y * (1.0 - y),
            Unary::Softplus => x.sigmoid(),
            Unary::Tanh => 1.0 - y * y,
            Unary::Square => 2.0 * x,
        }
    }
}

impl Binary {
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Binary::Add => a + b,
            Binary::Sub => a - b,
            Binary::Mul => a * b,
            Binary::Div => a / b,
            Binary::Atan2 => a.atan2(b),
        }
    }

    /// (∂f/∂a, ∂f/∂b) at (a, b) with output `y`.
    fn partials(self, a: f64, b: f64, y: f64) -> (f64, f64) {
        match self {
            Binary::Add => (1.0, 1.0),
            Binary::Sub => (1.0, -1.0),
            Binary::Mul => (b, a),
            Binary::Div => (1.0 / b, -y / b),
            Binary::Atan2 => {
                let r2 = a * a + b * b;
                (b / r2, -a / r2)
            }
        }
    }
}

impl Var {
    fn unary(&self, f: Unary) -> Self {
        let r = {
            let mut t = self.tape.borrow_mut();
            let x = t.slot(self.r);
            let out: Vec<f64> = (t.vals[x.start..x.start + x.len].iter())
                .map(|&v| f.apply(v))
                .collect();
            t.push(Op::Unary(self.r, f), x.len, 1, out)
        };
        self.with(r)
    }

    fn binary(&self, o: &Self, f: Binary) -> Self {
        debug_assert!(std::rc::Rc::ptr_eq(&self.tape, &o.tape), "both on one tape");
        let r = {
            let mut t = self.tape.borrow_mut();
            let (a, b) = (t.col(self.r), t.col(o.r));
            let len = a.len().max(b.len());
            let out: Vec<f64> = match (a.len(), b.len()) {
                (x, y) if x == y => a.iter().zip(b).map(|(&a, &b)| f.apply(a, b)).collect(),
                (1, _) => b.iter().map(|&b| f.apply(a[0], b)).collect(),
                _ => a.iter().map(|&a| f.apply(a, b[0])).collect(),
            };
            t.push(Op::Binary(self.r, o.r, f), len, 1, out)
        };
        self.with(r)
    }
}

/// Adds `g · d(k)` into the adjoint at `at` for every output row k; a shared input (length
/// 1) takes the sum.
fn accumulate(
    adj: &mut [f64],
    at: usize,
    len: usize,
    out: usize,
    rows: usize,
    d: impl Fn(usize) -> f64,
) {
    if len == rows {
        for k in 0..rows {
            adj[at + k] += adj[out + k] * d(k);
        }
    } else {
        let s: f64 = (0..rows).map(|k| adj[out + k] * d(k)).sum();
        adj[at] += s;
    }
}

pub(super) fn unary_back(t: &Tape, adj: &mut [f64], node: usize, a: Ref, f: Unary) {
    let out = t.nodes[node].slot;
    let x = t.slot(a);
    let (xs, ys) = (&t.vals[x.start..], &t.vals[out.start..]);
    accumulate(adj, x.start, x.len, out.start, out.len, |k| {
        f.derivative(xs[k % x.len], ys[k])
    });
}

pub(super) fn binary_back(t: &Tape, adj: &mut [f64], node: usize, a: Ref, b: Ref, f: Binary) {
    let out = t.nodes[node].slot;
    let (sa, sb) = (t.slot(a), t.slot(b));
    let (va, vb, y) = (
        &t.vals[sa.start..],
        &t.vals[sb.start..],
        &t.vals[out.start..],
    );
    let at = |k: usize| f.partials(va[k % sa.len], vb[k % sb.len], y[k]);
    accumulate(adj, sa.start, sa.len, out.start, out.len, |k| at(k).0);
    accumulate(adj, sb.start, sb.len, out.start, out.len, |k| at(k).1);
}

macro_rules! operator {
    ($trait:ident, $method:ident, $op:expr) => {
        impl $trait for Var {
            type Output = Var;
            fn $method(self, o: Var) -> Var {
                self.binary(&o, $op)
            }
        }
    };
}

operator!(Add, add, Binary::Add);
operator!(Sub, sub, Binary::Sub);
operator!(Mul, mul, Binary::Mul);
operator!(Div, div, Binary::Div);

impl Neg for Var {
    type Output = Var;
    fn neg(self) -> Var {
        self.unary(Unary::Neg)
    }
}

impl Scalar for Var {
    fn cos(&self) -> Self {
        self.unary(Unary::Cos)
    }
    fn sin(&self) -> Self {
        self.unary(Unary::Sin)
    }
    fn sqrt(&self) -> Self {
        self.unary(Unary::Sqrt)
    }
    fn exp(&self) -> Self {
        self.unary(Unary::Exp)
    }
    fn ln(&self) -> Self {
        self.unary(Unary::Ln)
    }
    fn atan2(&self, x: &Self) -> Self {
        self.binary(x, Binary::Atan2)
    }
    fn sigmoid(&self) -> Self {
        self.unary(Unary::Sigmoid)
    }
    fn softplus(&self) -> Self {
        self.unary(Unary::Softplus)
    }
    fn scale(&self, c: f64) -> Self {
        self.unary(Unary::Scale(c))
    }
    fn shift(&self, c: f64) -> Self {
        self.unary(Unary::Shift(c))
    }
    fn square(&self) -> Self {
        self.unary(Unary::Square)
    }
    fn tanh(&self) -> Self {
        self.unary(Unary::Tanh)
    }
    fn lift(&self, c: f64) -> Self {
        let r = self.tape.borrow_mut().push(Op::Const, 1, 1, [c]);
        self.with(r)
    }
}

/// A trainable value on the tape (a parameter node, or one computed from parameters).
impl crate::physics::assembly::Coef<Var> for Var {
    fn times(&self, x: &Var) -> Var {
        self.clone() * x.clone()
    }
    fn value(&self, _like: &Var) -> Var {
        self.clone()
    }
    fn mul_div(&self, mul: f64, div: f64) -> Self {
        self.scale(mul / div)
    }
}
