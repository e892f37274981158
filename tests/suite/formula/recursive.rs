//! The formula parser and evaluator graybox had before its programs were flat: a recursive
//! descent parser building a tree of boxes and a recursive evaluator, kept (f64 only) as the
//! reference the property test compares the flat programs with. It recurses once per level
//! of nesting and per term of a sum, so it runs on a thread with a large stack.
#![allow(dead_code)]

use std::fmt;

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

/// A parsed expression. `Sym` keeps the offset of its name, so that checks on which symbols
/// an expression may use can point at the offending one.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    Num(f64),
    Sym(Symbol, usize),
    Neg(Box<Expr>),
    Add(Box<Expr>, Box<Expr>),
    Sub(Box<Expr>, Box<Expr>),
    Mul(Box<Expr>, Box<Expr>),
    Div(Box<Expr>, Box<Expr>),
    /// Base to a constant integer exponent: repeated products, exact for negative bases.
    PowI(Box<Expr>, i32),
    /// Base to any exponent, as exp(b · ln a) (a > 0).
    Pow(Box<Expr>, Box<Expr>),
    Call(Func, Vec<Expr>),
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

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
    End,
}

/// Tokens with their character offsets.
fn lex(text: &str) -> Result<Vec<(Tok, usize)>, ParseError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = vec![];
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let start = i;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit))
        {
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            // An exponent only when digits follow: "2e" is a number and a name.
            if matches!(chars.get(i), Some('e' | 'E')) {
                let sign = usize::from(matches!(chars.get(i + 1), Some('+' | '-')));
                if chars.get(i + 1 + sign).is_some_and(char::is_ascii_digit) {
                    i += 1 + sign;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let s: String = chars[start..i].iter().collect();
            let v: f64 = s.parse().map_err(|_| ParseError {
                offset: start,
                message: format!("'{s}' is not a number"),
            })?;
            out.push((Tok::Num(v), start));
        } else if c.is_ascii_alphabetic() || c == '_' {
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Tok::Name(chars[start..i].iter().collect()), start));
        } else if "+-*/^(),".contains(c) {
            out.push((Tok::Op(c), start));
            i += 1;
        } else {
            return Err(ParseError {
                offset: start,
                message: format!("unexpected character '{c}'"),
            });
        }
    }
    out.push((Tok::End, chars.len()));
    Ok(out)
}

struct Parser<'a> {
    toks: Vec<(Tok, usize)>,
    at: usize,
    names: &'a Names,
}

/// Parses `text` against `names`.
pub fn parse(text: &str, names: &Names) -> Result<Expr, ParseError> {
    let mut p = Parser {
        toks: lex(text)?,
        at: 0,
        names,
    };
    if p.peek() == &Tok::End {
        return Err(p.error("an empty expression"));
    }
    let e = p.expr()?;
    match p.peek() {
        Tok::End => Ok(e),
        Tok::Op(')') => Err(p.error("')' without its '('")),
        t => Err(p.error(format!("expected an operator, found {}", describe(t)))),
    }
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Num(v) => format!("the number {v}"),
        Tok::Name(n) => format!("'{n}'"),
        Tok::Op(c) => format!("'{c}'"),
        Tok::End => "the end".into(),
    }
}

impl Parser<'_> {
    fn peek(&self) -> &Tok {
        &self.toks[self.at].0
    }

    fn offset(&self) -> usize {
        self.toks[self.at].1
    }

    fn next(&mut self) -> (Tok, usize) {
        let t = self.toks[self.at].clone();
        if t.0 != Tok::End {
            self.at += 1;
        }
        t
    }

    fn error(&self, message: impl Into<String>) -> ParseError {
        ParseError {
            offset: self.offset(),
            message: message.into(),
        }
    }

    fn eat(&mut self, c: char) -> bool {
        if self.peek() == &Tok::Op(c) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn expr(&mut self) -> Result<Expr, ParseError> {
        let mut e = self.term()?;
        loop {
            if self.eat('+') {
                e = Expr::Add(Box::new(e), Box::new(self.term()?));
            } else if self.eat('-') {
                e = Expr::Sub(Box::new(e), Box::new(self.term()?));
            } else {
                return Ok(e);
            }
        }
    }

    fn term(&mut self) -> Result<Expr, ParseError> {
        let mut e = self.unary()?;
        loop {
            if self.eat('*') {
                e = Expr::Mul(Box::new(e), Box::new(self.unary()?));
            } else if self.eat('/') {
                e = Expr::Div(Box::new(e), Box::new(self.unary()?));
            } else {
                return Ok(e);
            }
        }
    }

    fn unary(&mut self) -> Result<Expr, ParseError> {
        if self.eat('-') {
            return Ok(match self.unary()? {
                Expr::Num(v) => Expr::Num(-v),
                e => Expr::Neg(Box::new(e)),
            });
        }
        self.power()
    }

    fn power(&mut self) -> Result<Expr, ParseError> {
        let base = self.atom()?;
        if !self.eat('^') {
            return Ok(base);
        }
        Ok(match (base, self.unary()?) {
            // Constant powers fold: 3^2 is then an integer exponent in 2^3^2.
            (Expr::Num(b), Expr::Num(k)) => Expr::Num(b.powf(k)),
            (base, Expr::Num(k)) if k.fract() == 0.0 && k.abs() <= 64.0 => {
                Expr::PowI(Box::new(base), k as i32)
            }
            (base, exponent) => Expr::Pow(Box::new(base), Box::new(exponent)),
        })
    }

    fn atom(&mut self) -> Result<Expr, ParseError> {
        let (tok, at) = self.next();
        match tok {
            Tok::Num(v) => Ok(Expr::Num(v)),
            Tok::Op('(') => {
                let e = self.expr()?;
                if !self.eat(')') {
                    return Err(self.error(format!("expected ')' to close the '(' at offset {at}")));
                }
                Ok(e)
            }
            Tok::Name(name) if self.peek() == &Tok::Op('(') => self.call(&name, at),
            Tok::Name(name) => {
                if name == "pi" {
                    return Ok(Expr::Num(std::f64::consts::PI));
                }
                if let Some(s) = self.names.resolve(&name) {
                    return Ok(Expr::Sym(s, at));
                }
                let hint = if FUNCTIONS.iter().any(|(f, _, _)| *f == name) {
                    format!("'{name}' is a function: write {name}(…)")
                } else {
                    format!("unknown name '{name}'; known: {}", self.names.known())
                };
                Err(ParseError {
                    offset: at,
                    message: hint,
                })
            }
            t => Err(ParseError {
                offset: at,
                message: format!("expected a number, a name or '(', found {}", describe(&t)),
            }),
        }
    }

    fn call(&mut self, name: &str, at: usize) -> Result<Expr, ParseError> {
        let Some(&(_, f, arity)) = FUNCTIONS.iter().find(|(n, _, _)| *n == name) else {
            let known: Vec<&str> = FUNCTIONS.iter().map(|(n, _, _)| *n).collect();
            return Err(ParseError {
                offset: at,
                message: format!("unknown function '{name}'; known: {}", known.join(", ")),
            });
        };
        self.eat('(');
        let mut args = vec![self.expr()?];
        while self.eat(',') {
            args.push(self.expr()?);
        }
        if !self.eat(')') {
            return Err(self.error(format!("expected ',' or ')' in {name}(…)")));
        }
        if args.len() != arity {
            return Err(ParseError {
                offset: at,
                message: format!("{name} takes {arity} argument(s), got {}", args.len()),
            });
        }
        Ok(Expr::Call(f, args))
    }
}

impl Expr {
    /// Every symbol the expression uses, with its offset, in reading order.
    pub fn symbols(&self) -> Vec<(Symbol, usize)> {
        let mut out = vec![];
        self.visit(&mut |e| {
            if let Expr::Sym(s, at) = e {
                out.push((*s, *at));
            }
        });
        out
    }

    fn visit(&self, f: &mut impl FnMut(&Expr)) {
        f(self);
        match self {
            Expr::Num(_) | Expr::Sym(..) => {}
            Expr::Neg(a) | Expr::PowI(a, _) => a.visit(f),
            Expr::Add(a, b)
            | Expr::Sub(a, b)
            | Expr::Mul(a, b)
            | Expr::Div(a, b)
            | Expr::Pow(a, b) => {
                a.visit(f);
                b.visit(f);
            }
            Expr::Call(_, args) => args.iter().for_each(|a| a.visit(f)),
        }
    }

    /// The value with each symbol's value from `sym`; `like` gives constants their kind and
    /// shape (a batch column, a dual number without tangents).
    pub fn eval(&self, sym: &dyn Fn(Symbol) -> f64) -> f64 {
        let ev = |e: &Expr| e.eval(sym);
        match self {
            Expr::Num(v) => *v,
            Expr::Sym(s, _) => sym(*s),
            Expr::Neg(a) => -ev(a),
            Expr::Add(a, b) => ev(a) + ev(b),
            Expr::Sub(a, b) => ev(a) - ev(b),
            Expr::Mul(a, b) => ev(a) * ev(b),
            Expr::Div(a, b) => ev(a) / ev(b),
            Expr::PowI(a, k) => powi(ev(a), *k),
            Expr::Pow(a, b) => (ev(b) * ev(a).ln()).exp(),
            Expr::Call(f, args) => {
                let x = ev(&args[0]);
                match f {
                    Func::Sin => x.sin(),
                    Func::Cos => x.cos(),
                    Func::Tan => x.sin() / x.cos(),
                    Func::Exp => x.exp(),
                    Func::Log => x.ln(),
                    Func::Sqrt => x.sqrt(),
                    Func::Tanh => x.tanh(),
                    Func::Sinh => (x.exp() - (-x).exp()) * 0.5,
                    Func::Cosh => (x.exp() + (-x).exp()) * 0.5,
                    Func::Atan2 => x.atan2(ev(&args[1])),
                }
            }
        }
    }
}

/// xᵏ by squaring; a negative k is 1/x^|k|.
fn powi(x: f64, k: i32) -> f64 {
    if k == 0 {
        return 1.0;
    }
    let mut n = k.unsigned_abs();
    let mut base = x;
    let mut acc: Option<f64> = None;
    while n > 0 {
        if n & 1 == 1 {
            acc = Some(match acc {
                Some(a) => a * base,
                None => base,
            });
        }
        n >>= 1;
        if n > 0 {
            base = base * base;
        }
    }
    let p = acc.expect("k ≠ 0");
    if k < 0 { 1.0 / p } else { p }
}
