//! Expressions of formula templates (design.md §9): parsed once, evaluated over [`Scalar`],
//! so that training (Burn columns), the f64 evaluator and dual numbers (∂/∂q, linearization)
//! all run the same formula and no symbolic differentiation is needed.
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

use std::fmt;

use super::scalar::Scalar;

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
    pub fn eval<S: Scalar>(&self, sym: &dyn Fn(Symbol) -> S, like: &S) -> S {
        let ev = |e: &Expr| e.eval(sym, like);
        match self {
            Expr::Num(v) => like.lift(*v),
            Expr::Sym(s, _) => sym(*s),
            Expr::Neg(a) => -ev(a),
            Expr::Add(a, b) => ev(a) + ev(b),
            Expr::Sub(a, b) => ev(a) - ev(b),
            Expr::Mul(a, b) => ev(a) * ev(b),
            Expr::Div(a, b) => ev(a) / ev(b),
            Expr::PowI(a, k) => powi(ev(a), *k, like),
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
                    Func::Sinh => (x.exp() - (-x).exp()).scale(0.5),
                    Func::Cosh => (x.exp() + (-x).exp()).scale(0.5),
                    Func::Atan2 => x.atan2(&ev(&args[1])),
                }
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::dual::Dual;

    fn names() -> Names {
        Names {
            coordinates: vec!["x".into(), "theta".into()],
            inputs: vec!["f".into()],
            parameters: vec!["mp".into(), "l".into(), "g".into()],
        }
    }

    fn value(text: &str) -> f64 {
        let e = parse(text, &names()).unwrap_or_else(|e| panic!("{text}: {e}"));
        // x = 0.3, θ = −1.2, ẋ = 0.7, θ̇ = 2.5, f = 4, mp = 0.5, l = 0.6, g = 9.81
        let sym = |s: Symbol| match s {
            Symbol::Q(i) => [0.3, -1.2][i],
            Symbol::QDot(i) => [0.7, 2.5][i],
            Symbol::U(_) => 4.0,
            Symbol::Param(i) => [0.5, 0.6, 9.81][i],
        };
        e.eval(&sym, &0.0)
    }

    #[test]
    fn precedence_and_associativity_follow_the_grammar() {
        // Each against the same formula written in Rust.
        assert_eq!(value("1 + 2 * 3"), 7.0);
        assert_eq!(value("2 ^ 3 ^ 2"), 512.0);
        assert_eq!(value("-x^2"), -(0.3f64 * 0.3));
        assert_eq!(value("(-x)^2"), 0.3f64 * 0.3);
        assert_eq!(value("8 / 4 / 2"), 1.0);
        assert_eq!(value("10 - 4 - 3"), 3.0);
        assert_eq!(value("2 * -3"), -6.0);
        assert_eq!(value("x^-2"), 1.0 / (0.3f64 * 0.3));
        assert_eq!(value("1.5e2 + .5 + 2E-1"), 150.7);
    }

    #[test]
    fn names_functions_and_constants_evaluate_like_rust() {
        let (x, th, xd, thd, f, mp, l, g) = (0.3f64, -1.2f64, 0.7, 2.5, 4.0, 0.5, 0.6, 9.81);
        let close =
            |a: f64, b: f64| assert!((a - b).abs() <= 1e-15 * b.abs().max(1.0), "{a} vs {b}");
        close(value("mp*l*cos(theta)"), mp * l * th.cos());
        close(value("-mp*g*l*cos(theta)"), -mp * g * l * th.cos());
        close(value("f + -0.1*x_dot + theta_dot"), f - 0.1 * xd + thd);
        close(
            value("tan(x) + exp(x) + log(l) + sqrt(g)"),
            x.tan() + x.exp() + l.ln() + g.sqrt(),
        );
        close(
            value("tanh(x) + sinh(x) + cosh(x)"),
            x.tanh() + x.sinh() + x.cosh(),
        );
        close(value("atan2(theta, x)"), th.atan2(x));
        close(value("l ^ 1.5"), l.powf(1.5));
        close(value("pi"), std::f64::consts::PI);
    }

    #[test]
    fn errors_name_what_and_where() {
        let err = |t: &str| parse(t, &names()).unwrap_err();
        let e = err("mp * foo");
        assert_eq!(e.offset, 5);
        assert!(
            e.message.contains("unknown name 'foo'") && e.message.contains("theta_dot"),
            "{e}"
        );
        let e = err("sin(x) + cosine(x)");
        assert_eq!(
            (e.offset, e.message.contains("unknown function 'cosine'")),
            (9, true),
            "{e}"
        );
        let e = err("mp * (l + 1");
        assert_eq!(e.offset, 11);
        assert!(e.message.contains("offset 5"), "{e}");
        assert_eq!(err("mp +* l").offset, 4);
        assert_eq!(err("mp l").offset, 3);
        assert_eq!(err("x)").offset, 1);
        assert_eq!(err("x # 2").offset, 2);
        assert_eq!(err("").offset, 0);
        assert_eq!(err("   ").offset, 3);
        let e = err("atan2(x)");
        assert!(e.message.contains("takes 2"), "{e}");
        let e = err("sin + 1");
        assert!(e.message.contains("is a function"), "{e}");
        // Offsets count characters, not bytes.
        assert_eq!(err("θ + 1").offset, 0);
        assert_eq!(err("x + θ").offset, 4);
    }

    #[test]
    fn symbols_are_reported_with_their_offsets() {
        let e = parse("mp*l*cos(theta) + theta_dot*f", &names()).unwrap();
        assert_eq!(
            e.symbols(),
            vec![
                (Symbol::Param(0), 0),
                (Symbol::Param(1), 3),
                (Symbol::Q(1), 9),
                (Symbol::QDot(1), 18),
                (Symbol::U(0), 28)
            ]
        );
    }

    /// Dual numbers differentiate every operator and function: against central differences.
    #[test]
    fn dual_derivatives_match_finite_differences() {
        let names = Names {
            coordinates: vec!["a".into(), "b".into()],
            ..Names::default()
        };
        let texts = [
            "a^3 - 2*a*b + b^-2",
            "sin(a)*cos(b) + tan(a/3)",
            "exp(a - b) + log(b) + sqrt(b)",
            "tanh(a) + sinh(b) + cosh(a*b)",
            "atan2(a, b) + b^1.5 + 1/(a + 2)",
        ];
        let at = [0.7, 1.3];
        for t in texts {
            let e = parse(t, &names).unwrap();
            let f = |a: f64, b: f64| {
                e.eval(
                    &|s| match s {
                        Symbol::Q(0) => a,
                        _ => b,
                    },
                    &0.0,
                )
            };
            let d = e.eval(
                &|s| match s {
                    Symbol::Q(i) => Dual::variable(at[i], i, 2, 1.0),
                    _ => unreachable!(),
                },
                &Dual::constant(0.0),
            );
            assert!((d.v - f(at[0], at[1])).abs() < 1e-14, "{t}");
            // Central differences: error ~ h² f''' ≈ 1e-10 at h = 1e-5; rounding ~ 1e-16/h.
            let h = 1e-5;
            let fd = [
                (f(at[0] + h, at[1]) - f(at[0] - h, at[1])) / (2.0 * h),
                (f(at[0], at[1] + h) - f(at[0], at[1] - h)) / (2.0 * h),
            ];
            for (k, fd) in fd.iter().enumerate() {
                let ad = d.tangent(k).copied().unwrap_or(0.0);
                assert!(
                    (ad - fd).abs() < 1e-8 * fd.abs().max(1.0),
                    "{t} ∂{k}: {ad} vs {fd}"
                );
            }
        }
    }
}
