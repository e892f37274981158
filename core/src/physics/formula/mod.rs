//! Expressions of formula templates (docs/robots.md#formula-templates): parsed once into a flat postfix program,
//! evaluated over [`Scalar`], so that training (the tape's columns), the f64 evaluator and dual
//! numbers (∂/∂q, linearization) all run the same formula and no symbolic differentiation is
//! needed.
//!
//! Grammar (usual precedence; `^` binds tighter than unary minus and is right-associative,
//! so `-x^2` is −(x²) and `2^3^2` is 2⁹):
//!
//! ```text
//! expr  = term  { ("+" | "-") term }
//! term  = unary { ("*" | "/") unary }
//! unary = "-" unary | power
//! power = atom [ "^" unary ]
//! atom  = number | name | name "(" expr { "," expr } ")" | "(" expr ")"
//! ```
//!
//! Names: the coordinates, `<coordinate>_dot`, the inputs, the parameters and `pi`;
//! functions `sin cos tan exp log sqrt tanh sinh cosh atan2`. Errors carry the character
//! offset (0-based) where they were found.
//!
//! Nothing here recurses on the input: the parser keeps its pending operators on a stack of
//! its own (operator precedence), and a program is a `Vec` run by a value stack. Input decides
//! only how long those stacks grow, and [`MAX_DEPTH`] and [`MAX_NODES`] bound that.

mod parse;
#[cfg(test)]
mod tests;

use std::fmt;

pub use parse::{Budget, parse, parse_within};

use super::scalar::Scalar;
use crate::arena::{AVec, Arena};

/// Nesting an expression may have: parentheses, calls, unary minus and `^` chains each add a
/// level (a sum or product of any length adds one). Generated mass-matrix entries nest a few
/// dozen levels; thousands is an attack on the parser's stacks, not a mechanism.
pub const MAX_DEPTH: usize = 256;

/// Numbers, names, operators and calls of one template document, all expressions together:
/// bounds its parse, its programs and the work of every evaluation.
pub const MAX_NODES: usize = 100_000;

/// What a name in an expression stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Symbol {
    /// Coordinate q_i.
    Q(usize),
    /// Velocity q̇_i.
    QDot(usize),
    /// Input u_i.
    U(usize),
    /// Template parameter i.
    Param(usize),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    Sin,
    Cos,
    Tan,
    Exp,
    Log,
    Sqrt,
    Tanh,
    Sinh,
    Cosh,
    Atan2,
}

pub const FUNCTIONS: [(&str, Func, usize); 10] = [
    ("sin", Func::Sin, 1),
    ("cos", Func::Cos, 1),
    ("tan", Func::Tan, 1),
    ("exp", Func::Exp, 1),
    ("log", Func::Log, 1),
    ("sqrt", Func::Sqrt, 1),
    ("tanh", Func::Tanh, 1),
    ("sinh", Func::Sinh, 1),
    ("cosh", Func::Cosh, 1),
    ("atan2", Func::Atan2, 2),
];

/// Names that are not free for coordinates, inputs or parameters.
pub fn reserved(name: &str) -> bool {
    name == "pi" || FUNCTIONS.iter().any(|(f, _, _)| *f == name)
}

/// One instruction of a program: operands come from the value stack, the result goes back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Op {
    Num(f64),
    /// A symbol with the offset of its name, so that checks on which symbols an expression
    /// may use can point at the offending one.
    Sym(Symbol, usize),
    Neg,
    Add,
    Sub,
    Mul,
    Div,
    /// Base to a constant integer exponent: repeated products, exact for negative bases.
    PowI(i32),
    /// Base to any exponent, as exp(b · ln a) (a > 0).
    Pow,
    /// A function of its arity's operands, the first pushed first.
    Call(Func),
}

/// A parsed expression: its instructions in postfix order (operands before their operator,
/// in reading order) and the deepest its value stack gets.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    ops: Vec<Op>,
    stack: usize,
}

/// A parse error at a character offset.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseError {
    pub offset: usize,
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (at offset {})", self.message, self.offset)
    }
}

/// The names an expression may use, by kind, in order (index = position).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Names {
    pub coordinates: Vec<String>,
    pub inputs: Vec<String>,
    pub parameters: Vec<String>,
}

impl Names {
    fn resolve(&self, name: &str) -> Option<Symbol> {
        let pos = |v: &[String], n: &str| v.iter().position(|c| c == n);
        if let Some(i) = pos(&self.coordinates, name) {
            return Some(Symbol::Q(i));
        }
        if let Some(i) = name
            .strip_suffix("_dot")
            .and_then(|c| pos(&self.coordinates, c))
        {
            return Some(Symbol::QDot(i));
        }
        if let Some(i) = pos(&self.inputs, name) {
            return Some(Symbol::U(i));
        }
        pos(&self.parameters, name).map(Symbol::Param)
    }

    fn known(&self) -> String {
        let dots = self.coordinates.iter().map(|c| format!("{c}_dot"));
        let all: Vec<String> = self
            .coordinates
            .iter()
            .cloned()
            .chain(dots)
            .chain(self.inputs.iter().cloned())
            .chain(self.parameters.iter().cloned())
            .chain(["pi".to_string()])
            .collect();
        all.join(", ")
    }
}

impl Expr {
    /// The instructions, in the order they run.
    pub fn ops(&self) -> &[Op] {
        &self.ops
    }

    /// Every symbol the expression uses, with its offset, in reading order.
    pub fn symbols(&self) -> Vec<(Symbol, usize)> {
        self.ops
            .iter()
            .filter_map(|op| match op {
                Op::Sym(s, at) => Some((*s, *at)),
                _ => None,
            })
            .collect()
    }

    /// The value with each symbol's value from `sym`; `like` gives constants their kind and
    /// shape (a batch column, a dual number without tangents).
    pub fn eval<S: Scalar>(&self, sym: &dyn Fn(Symbol) -> S, like: &S) -> S {
        self.eval_in(&Arena::new(), sym, like)
    }

    /// [`Expr::eval`] with its operand stack in `a`. Each operation updates the stack's top
    /// in place: a wide value (a dual number over a `Pack`) is not copied in and out.
    pub fn eval_in<S: Scalar>(&self, a: &Arena, sym: &dyn Fn(Symbol) -> S, like: &S) -> S {
        const OPERANDS: &str = "a parsed program has its operands";
        let mut stack: AVec<S> = AVec::with_capacity_in(self.stack, a);
        for op in &self.ops {
            match *op {
                Op::Num(v) => stack.push(like.lift(v)),
                Op::Sym(s, _) => stack.push(sym(s)),
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow | Op::Call(Func::Atan2) => {
                    let [.., a, b] = &mut stack[..] else {
                        unreachable!("{OPERANDS}")
                    };
                    match op {
                        Op::Add => *a += b,
                        Op::Sub => *a -= b,
                        Op::Mul => *a *= b,
                        Op::Div => *a /= b,
                        Op::Call(_) => *a = a.atan2(b),
                        _ => *a = (b.clone() * a.ln()).exp(),
                    }
                    stack.truncate(stack.len() - 1);
                }
                Op::Neg | Op::PowI(_) | Op::Call(_) => {
                    let x = stack.last_mut().expect(OPERANDS);
                    *x = match *op {
                        Op::Neg => -x.clone(),
                        Op::PowI(k) => powi(x.clone(), k, like),
                        Op::Call(f) => call(f, x),
                        _ => unreachable!("a unary operation"),
                    };
                }
            }
        }
        stack.pop().expect(OPERANDS)
    }
}

/// A function of one argument.
fn call<S: Scalar>(f: Func, x: &S) -> S {
    match f {
        Func::Sin => x.sin(),
        Func::Cos => x.cos(),
        Func::Tan => x.sin() / x.cos(),
        Func::Exp => x.exp(),
        Func::Log => x.ln(),
        Func::Sqrt => x.sqrt(),
        Func::Tanh => x.tanh(),
        Func::Sinh => (x.exp() - (-x.clone()).exp()).scale(0.5),
        Func::Cosh => (x.exp() + (-x.clone()).exp()).scale(0.5),
        Func::Atan2 => unreachable!("atan2 takes two operands"),
    }
}

/// xᵏ by squaring; a negative k is 1/x^|k|.
fn powi<S: Scalar>(x: S, k: i32, like: &S) -> S {
    if k == 0 {
        return like.lift(1.0);
    }
    let mut n = k.unsigned_abs();
    let mut base = x;
    let mut acc: Option<S> = None;
    while n > 0 {
        if n & 1 == 1 {
            acc = Some(match acc {
                Some(a) => a * base.clone(),
                None => base.clone(),
            });
        }
        n >>= 1;
        if n > 0 {
            base = base.square();
        }
    }
    let p = acc.expect("k ≠ 0");
    if k < 0 { like.lift(1.0) / p } else { p }
}
