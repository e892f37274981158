//! The tape's elementwise nodes: [`Scalar`] and the arithmetic operators on [`Var`], each
//! recorded with what its backward pass needs (its inputs' and its own values, in the arena).
//! A value every row shares (length 1) broadcasts against a column, and its adjoint is the
//! column's summed.

use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use super::{Op, Ref, Slot, Tape, Var};
use crate::physics::scalar::Scalar;
use crate::physics::tangents::{Sparse, WIDTH};

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

impl Var {
    fn unary(&self, f: Unary) -> Self {
        if matches!(f, Unary::Scale(c) if c == 1.0) || matches!(f, Unary::Shift(c) if c == 0.0) {
            return self.clone();
        }
        let key = f.key(self.r);
        if let Some(&r) = self.tape.borrow().seen.get(&key) {
            return self.with(r);
        }
        let r = {
            let mut t = self.tape.borrow_mut();
            let x = t.slot(self.r);
            let start = t.vals.len();
            t.vals.resize(start + x.len, 0.0);
            let (src, out) = t.vals.split_at_mut(start);
            let src = &src[x.start..x.start + x.len];
            fill_unary(out, src, f);
            let r = t.node(Op::Unary(self.r, f), start, x.len, 1);
            t.seen.insert(key, r);
            let other = match f {
                Unary::Sin => Some(Unary::Cos),
                Unary::Cos => Some(Unary::Sin),
                _ => None,
            };
            if let Some(&p) = other.and_then(|o| t.seen.get(&o.key(self.r))) {
                t.nodes[p.node as usize].partner = Some(r.node);
                t.nodes[r.node as usize].partner = Some(p.node);
            }
            r
        };
        self.with(r)
    }

    fn binary(&self, o: &Self, f: Binary) -> Self {
        debug_assert!(std::rc::Rc::ptr_eq(&self.tape, &o.tape), "both on one tape");
        let key = f.key(self.r, o.r);
        {
            let t = self.tape.borrow();
            // x · 1, x + 0 and x − 0 are x, to the bit (a NaN included).
            let (ca, cb) = (t.constant(self.r), t.constant(o.r));
            match (f, ca, cb) {
                (Binary::Mul, _, Some(1.0)) | (Binary::Add | Binary::Sub, _, Some(0.0)) => {
                    return self.clone();
                }
                (Binary::Mul, Some(1.0), _) | (Binary::Add, Some(0.0), _) => return o.clone(),
                _ => {}
            }
            if let Some(&r) = t.seen.get(&key) {
                return self.with(r);
            }
        }
        let r = {
            let mut t = self.tape.borrow_mut();
            let (sa, sb) = (t.slot(self.r), t.slot(o.r));
            let len = sa.len.max(sb.len);
            let start = t.vals.len();
            t.vals.resize(start + len, 0.0);
            let (src, out) = t.vals.split_at_mut(start);
            let (a, b) = (
                &src[sa.start..sa.start + sa.len],
                &src[sb.start..sb.start + sb.len],
            );
            fill_binary(out, a, b, f);
            let r = t.node(Op::Binary(self.r, o.r, f), start, len, 1);
            t.seen.insert(key, r);
            r
        };
        self.with(r)
    }
}

/// `out` = f(`x`) elementwise, one loop per rule so that the simple ones vectorise (a
/// `match` inside the loop would not).
fn fill_unary(out: &mut [f64], x: &[f64], f: Unary) {
    macro_rules! each {
        ($op:expr) => {{
            let op = $op;
            (out.iter_mut().zip(x)).for_each(|(o, &x)| *o = op(x))
        }};
    }
    match f {
        Unary::Neg => each!(|x: f64| -x),
        Unary::Scale(c) => each!(|x: f64| c * x),
        Unary::Shift(c) => each!(|x: f64| x + c),
        Unary::Square => each!(|x: f64| x * x),
        Unary::Sqrt => each!(|x: f64| x.sqrt()),
        _ => each!(|x: f64| f.apply(x)),
    }
}

/// `out` = f(`a`, `b`) elementwise, a shared value broadcast; one loop per rule and shape.
fn fill_binary(out: &mut [f64], a: &[f64], b: &[f64], f: Binary) {
    macro_rules! each {
        ($op:expr) => {{
            let op = $op;
            match (a.len(), b.len()) {
                (x, y) if x == y => {
                    (out.iter_mut().zip(a.iter().zip(b))).for_each(|(o, (&a, &b))| *o = op(a, b))
                }
                (1, _) => (out.iter_mut().zip(b)).for_each(|(o, &b)| *o = op(a[0], b)),
                _ => (out.iter_mut().zip(a)).for_each(|(o, &a)| *o = op(a, b[0])),
            }
        }};
    }
    match f {
        Binary::Add => each!(|a: f64, b: f64| a + b),
        Binary::Sub => each!(|a: f64, b: f64| a - b),
        Binary::Mul => each!(|a: f64, b: f64| a * b),
        Binary::Div => each!(|a: f64, b: f64| a / b),
        Binary::Atan2 => each!(|a: f64, b: f64| a.atan2(b)),
    }
}

/// A value read by row: a column, or one number every row shares.
trait Col: Copy {
    fn at(self, k: usize) -> f64;
}

#[derive(Clone, Copy)]
struct Full<'a>(&'a [f64]);

#[derive(Clone, Copy)]
struct Shared(f64);

impl Col for Full<'_> {
    #[inline(always)]
    fn at(self, k: usize) -> f64 {
        self.0[k]
    }
}

impl Col for Shared {
    #[inline(always)]
    fn at(self, _: usize) -> f64 {
        self.0
    }
}

/// Adds `g_k · d(k)` into the adjoint of the input at `s` for every output row k (`lo` is
/// the adjoint below the output's); a shared input takes the sum.
#[inline(always)]
fn accumulate(lo: &mut [f64], s: Slot, g: &[f64], d: impl Fn(usize) -> f64) {
    if s.len == g.len() {
        let dst = &mut lo[s.start..s.start + g.len()];
        for k in 0..g.len() {
            dst[k] += g[k] * d(k);
        }
    } else {
        lo[s.start] += (0..g.len()).map(|k| g[k] * d(k)).sum::<f64>();
    }
}

/// The output's adjoint and everything below it (every input's sits lower in the arena).
fn split(adj: &mut [f64], out: Slot) -> (&mut [f64], &[f64]) {
    let (lo, hi) = adj.split_at_mut(out.start);
    (lo, &hi[..out.len])
}

pub(super) fn unary_back(
    t: &Tape,
    adj: &mut [f64],
    node: usize,
    a: Ref,
    f: Unary,
    partner: Option<u32>,
) {
    let out = t.nodes[node].slot;
    let x = t.slot(a);
    let other = partner.map(|p| {
        let s = t.nodes[p as usize].slot;
        &t.vals[s.start..s.start + s.len]
    });
    let (xs, ys) = (
        &t.vals[x.start..x.start + x.len],
        &t.vals[out.start..out.start + out.len],
    );
    let (lo, g) = split(adj, out);
    // One loop per rule, so that each vectorises.
    macro_rules! rule {
        (|$x:ident, $y:ident| $d:expr) => {
            accumulate(lo, x, g, |k| {
                let ($x, $y) = (xs[k], ys[k]);
                let _ = ($x, $y);
                $d
            })
        };
    }
    match f {
        Unary::Neg => rule!(|x, y| -1.0),
        Unary::Scale(c) => rule!(|x, y| c),
        Unary::Shift(_) => rule!(|x, y| 1.0),
        Unary::Exp => rule!(|x, y| y),
        Unary::Tanh => rule!(|x, y| 1.0 - y * y),
        Unary::Square => rule!(|x, y| 2.0 * x),
        Unary::Sigmoid => rule!(|x, y| y * (1.0 - y)),
        Unary::Sin if let Some(cos) = other => accumulate(lo, x, g, |k| cos[k]),
        Unary::Cos if let Some(sin) = other => accumulate(lo, x, g, |k| -sin[k]),
        _ => rule!(|x, y| f.derivative(x, y)),
    }
}

pub(super) fn binary_back(t: &Tape, adj: &mut [f64], node: usize, a: Ref, b: Ref, f: Binary) {
    let out = t.nodes[node].slot;
    let (sa, sb) = (t.slot(a), t.slot(b));
    let col = |s: Slot| &t.vals[s.start..s.start + s.len];
    let (va, vb, y) = (col(sa), col(sb), col(out));
    let (lo, g) = split(adj, out);
    match (sa.len == out.len, sb.len == out.len) {
        (true, true) => binary_rule(f, lo, g, y, (sa, Full(va)), (sb, Full(vb))),
        (true, false) => binary_rule(f, lo, g, y, (sa, Full(va)), (sb, Shared(vb[0]))),
        (false, true) => binary_rule(f, lo, g, y, (sa, Shared(va[0])), (sb, Full(vb))),
        (false, false) => binary_rule(f, lo, g, y, (sa, Shared(va[0])), (sb, Shared(vb[0]))),
    }
}

/// Both inputs' adjoints under rule `f`, one loop per input and rule.
fn binary_rule<A: Col, B: Col>(
    f: Binary,
    lo: &mut [f64],
    g: &[f64],
    y: &[f64],
    (sa, a): (Slot, A),
    (sb, b): (Slot, B),
) {
    macro_rules! rule {
        (|$a:ident, $b:ident, $y:ident| $da:expr, $db:expr) => {{
            accumulate(lo, sa, g, |k| {
                let ($a, $b, $y) = (a.at(k), b.at(k), y[k]);
                let _ = ($a, $b, $y);
                $da
            });
            accumulate(lo, sb, g, |k| {
                let ($a, $b, $y) = (a.at(k), b.at(k), y[k]);
                let _ = ($a, $b, $y);
                $db
            });
        }};
    }
    match f {
        Binary::Add => rule!(|a, b, y| 1.0, 1.0),
        Binary::Sub => rule!(|a, b, y| 1.0, -1.0),
        Binary::Mul => rule!(|a, b, y| b, a),
        Binary::Div => rule!(|a, b, y| 1.0 / b, -y / b),
        Binary::Atan2 => rule!(|a, b, y| b / (a * a + b * b), -a / (a * a + b * b)),
    }
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
    ($trait:ident, $method:ident, $assign:ident, $assign_method:ident, $op:expr) => {
        operator!($trait, $method, $op);
        /// The same node: a `Var` is a handle, so in place saves nothing here.
        impl $assign<&Var> for Var {
            fn $assign_method(&mut self, o: &Var) {
                *self = self.binary(o, $op);
            }
        }
    };
}

operator!(Add, add, AddAssign, add_assign, Binary::Add);
operator!(Sub, sub, SubAssign, sub_assign, Binary::Sub);
operator!(Mul, mul, MulAssign, mul_assign, Binary::Mul);
operator!(Div, div, DivAssign, div_assign, Binary::Div);

impl Neg for Var {
    type Output = Var;
    fn neg(self) -> Var {
        self.unary(Unary::Neg)
    }
}

impl Scalar for Var {
    type Tangents = Sparse<Var, WIDTH>;
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
