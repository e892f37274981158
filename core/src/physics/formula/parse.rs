//! Text to program by operator precedence: operands go straight to the program, operators
//! wait on a stack of their own until an operator that binds less tightly (or the end of
//! their parentheses) comes, so every loop here is flat whatever the nesting.

use super::{Expr, FUNCTIONS, Func, MAX_DEPTH, MAX_NODES, Names, Op, ParseError};

/// The nodes a whole template document may still spend: every expression of a document
/// parses against one budget.
#[derive(Debug)]
pub struct Budget {
    used: usize,
}

impl Budget {
    /// A fresh document's budget of [`MAX_NODES`].
    pub fn document() -> Self {
        Self { used: 0 }
    }
}

/// Parses `text` against `names` as an expression of a document of its own.
pub fn parse(text: &str, names: &Names) -> Result<Expr, ParseError> {
    parse_within(text, names, &mut Budget::document())
}

/// Parses `text` against `names`, spending its nodes from `budget`.
pub fn parse_within(text: &str, names: &Names, budget: &mut Budget) -> Result<Expr, ParseError> {
    let mut p = Parser {
        lex: Lexer::new(text),
        names,
        ops: vec![],
        pending: vec![],
        height: 0,
        max_height: 0,
        spent: budget.used,
    };
    if p.lex.peek()?.0 == Tok::End {
        return Err(error(p.lex.peek()?.1, "an empty expression"));
    }
    let mut operand = true;
    loop {
        let (tok, at) = p.lex.next()?;
        if operand {
            match tok {
                Tok::Num(v) => p.emit(Op::Num(v), at)?,
                Tok::Name(name) if p.lex.peek()?.0 == Tok::Op('(') => {
                    p.lex.next()?;
                    p.push(Pending::Open(at, Some(function(&name, at)?), 0), at)?;
                    continue;
                }
                Tok::Name(name) => p.emit(p.name(&name, at)?, at)?,
                Tok::Op('(') => {
                    p.push(Pending::Open(at, None, 0), at)?;
                    continue;
                }
                Tok::Op('-') => {
                    p.push(Pending::Neg, at)?;
                    continue;
                }
                t => {
                    let found = describe(&t);
                    return Err(error(
                        at,
                        format!("expected a number, a name or '(', found {found}"),
                    ));
                }
            }
            operand = false;
            continue;
        }
        match tok {
            Tok::Op(c @ ('+' | '-' | '*' | '/' | '^')) => p.binary(c, at)?,
            Tok::Op(',') => p.comma(&tok, at)?,
            Tok::Op(')') => {
                p.close(at)?;
                continue;
            }
            Tok::End => {
                p.unwind(&tok, at)?;
                budget.used = p.spent + p.ops.len();
                return Ok(Expr {
                    ops: p.ops,
                    stack: p.max_height,
                });
            }
            t => return Err(p.unexpected(&t, at)),
        }
        operand = true;
    }
}

/// A called function: its name, its kind, how many arguments it takes.
type Callee = (&'static str, Func, usize);

/// An operator waiting for its right operand or for its closing parenthesis.
#[derive(Debug, Clone, Copy)]
enum Pending {
    /// '(' at an offset, the function it calls (None: grouping) and its arguments so far.
    Open(usize, Option<Callee>, usize),
    Neg,
    /// A binary operator with its precedence.
    Bin(Op, u8),
}

/// Unary minus binds less tightly than `^` and more than `*` and `/`.
const NEG: u8 = 3;

struct Parser<'a> {
    lex: Lexer<'a>,
    names: &'a Names,
    ops: Vec<Op>,
    pending: Vec<Pending>,
    /// The program's value stack after `ops`, and its deepest so far.
    height: usize,
    max_height: usize,
    /// Nodes the document's earlier expressions took.
    spent: usize,
}

fn error(offset: usize, message: impl Into<String>) -> ParseError {
    ParseError {
        offset,
        message: message.into(),
    }
}

fn function(name: &str, at: usize) -> Result<Callee, ParseError> {
    FUNCTIONS
        .iter()
        .find(|(n, _, _)| *n == name)
        .copied()
        .ok_or_else(|| {
            let known: Vec<&str> = FUNCTIONS.iter().map(|(n, _, _)| *n).collect();
            error(
                at,
                format!("unknown function '{name}'; known: {}", known.join(", ")),
            )
        })
}

impl Parser<'_> {
    fn name(&self, name: &str, at: usize) -> Result<Op, ParseError> {
        if name == "pi" {
            return Ok(Op::Num(std::f64::consts::PI));
        }
        if let Some(s) = self.names.resolve(name) {
            return Ok(Op::Sym(s, at));
        }
        Err(error(
            at,
            if FUNCTIONS.iter().any(|(f, _, _)| *f == name) {
                format!("'{name}' is a function: write {name}(…)")
            } else {
                format!("unknown name '{name}'; known: {}", self.names.known())
            },
        ))
    }

    fn push(&mut self, p: Pending, at: usize) -> Result<(), ParseError> {
        if self.pending.len() >= MAX_DEPTH {
            return Err(error(
                at,
                format!(
                    "nested more than {MAX_DEPTH} levels deep (parentheses, calls, unary minus \
                     and ^ chains each add one); that is the limit"
                ),
            ));
        }
        self.pending.push(p);
        Ok(())
    }

    /// Appends `op` to the program, folding constants as the old tree parser did: −c, c^k,
    /// and x^k for a whole k with |k| ≤ 64 as repeated products.
    fn emit(&mut self, op: Op, at: usize) -> Result<(), ParseError> {
        let last = self.ops.last().copied();
        let before = self.ops.len().checked_sub(2).map(|i| self.ops[i]);
        match (op, last, before) {
            (Op::Neg, Some(Op::Num(v)), _) => {
                self.ops.pop();
                return self.emit(Op::Num(-v), at);
            }
            (Op::Pow, Some(Op::Num(k)), Some(Op::Num(b))) => {
                self.ops.truncate(self.ops.len() - 2);
                self.height -= 2;
                return self.emit(Op::Num(b.powf(k)), at);
            }
            (Op::Pow, Some(Op::Num(k)), _) if k.fract() == 0.0 && k.abs() <= 64.0 => {
                self.ops.pop();
                self.height -= 1;
                return self.emit(Op::PowI(k as i32), at);
            }
            _ => {}
        }
        if self.spent + self.ops.len() >= MAX_NODES {
            return Err(error(
                at,
                format!(
                    "the document has more than {MAX_NODES} numbers, names, operators and \
                     calls in its expressions; that is the limit"
                ),
            ));
        }
        match op {
            Op::Num(_) | Op::Sym(..) => self.height += 1,
            Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow | Op::Call(Func::Atan2) => {
                self.height -= 1
            }
            Op::Neg | Op::PowI(_) | Op::Call(_) => {}
        }
        self.max_height = self.max_height.max(self.height);
        self.ops.push(op);
        Ok(())
    }

    /// Moves waiting operators that bind at least as tightly as `c` to the program, then
    /// makes `c` wait.
    fn binary(&mut self, c: char, at: usize) -> Result<(), ParseError> {
        let (op, prec) = match c {
            '+' => (Op::Add, 1),
            '-' => (Op::Sub, 1),
            '*' => (Op::Mul, 2),
            '/' => (Op::Div, 2),
            _ => (Op::Pow, 4),
        };
        let right = op == Op::Pow;
        while let Some(&top) = self.pending.last() {
            let top_prec = match top {
                Pending::Neg => NEG,
                Pending::Bin(_, p) => p,
                Pending::Open(..) => break,
            };
            if top_prec < prec || (top_prec == prec && right) {
                break;
            }
            self.pending.pop();
            self.emit_pending(top, at)?;
        }
        self.push(Pending::Bin(op, prec), at)
    }

    fn emit_pending(&mut self, p: Pending, at: usize) -> Result<(), ParseError> {
        match p {
            Pending::Neg => self.emit(Op::Neg, at),
            Pending::Bin(op, _) => self.emit(op, at),
            Pending::Open(..) => unreachable!("parentheses close in close() and comma()"),
        }
    }

    /// Moves every operator above the innermost '(' to the program; that '(' (None: there is
    /// none).
    fn pop_to_open(&mut self, at: usize) -> Result<Option<Pending>, ParseError> {
        while let Some(top) = self.pending.pop() {
            if let Pending::Open(..) = top {
                return Ok(Some(top));
            }
            self.emit_pending(top, at)?;
        }
        Ok(None)
    }

    fn comma(&mut self, tok: &Tok, at: usize) -> Result<(), ParseError> {
        match self.pop_to_open(at)? {
            Some(Pending::Open(open, Some(f), args)) => {
                self.pending.push(Pending::Open(open, Some(f), args + 1));
                Ok(())
            }
            Some(open) => {
                self.pending.push(open);
                Err(self.unexpected(tok, at))
            }
            None => Err(self.unexpected(tok, at)),
        }
    }

    fn close(&mut self, at: usize) -> Result<(), ParseError> {
        match self.pop_to_open(at)? {
            None => Err(error(at, "')' without its '('")),
            Some(Pending::Open(open, Some((name, f, arity)), args)) => {
                if args + 1 != arity {
                    return Err(error(
                        open,
                        format!("{name} takes {arity} argument(s), got {}", args + 1),
                    ));
                }
                self.emit(Op::Call(f), at)
            }
            Some(_) => Ok(()),
        }
    }

    /// At the end: every waiting operator to the program; an open '(' is an error.
    fn unwind(&mut self, end: &Tok, at: usize) -> Result<(), ParseError> {
        if self.pending.iter().any(|p| matches!(p, Pending::Open(..))) {
            return Err(self.unexpected(end, at));
        }
        while let Some(top) = self.pending.pop() {
            self.emit_pending(top, at)?;
        }
        Ok(())
    }

    /// The error for `t` where an operator belongs, said for the innermost open '('.
    fn unexpected(&self, t: &Tok, at: usize) -> ParseError {
        let open = self.pending.iter().rev().find_map(|p| match p {
            Pending::Open(open, f, _) => Some((*open, f.map(|(name, _, _)| name))),
            _ => None,
        });
        error(
            at,
            match open {
                Some((_, Some(name))) => format!("expected ',' or ')' in {name}(…)"),
                Some((open, None)) => format!("expected ')' to close the '(' at offset {open}"),
                None => format!("expected an operator, found {}", describe(t)),
            },
        )
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
    End,
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Num(v) => format!("the number {v}"),
        Tok::Name(n) => format!("'{n}'"),
        Tok::Op(c) => format!("'{c}'"),
        Tok::End => "the end".into(),
    }
}

/// Tokens with their character offsets, read one at a time (one of look-ahead) straight from
/// the text: no copy of it, whatever its size.
struct Lexer<'t> {
    text: &'t str,
    /// Where the next token starts: in bytes, and in characters (what errors report).
    pos: usize,
    at: usize,
    peeked: Option<(Tok, usize)>,
}

impl<'t> Lexer<'t> {
    fn new(text: &'t str) -> Self {
        Self {
            text,
            pos: 0,
            at: 0,
            peeked: None,
        }
    }

    fn peek(&mut self) -> Result<&(Tok, usize), ParseError> {
        if self.peeked.is_none() {
            self.peeked = Some(self.read()?);
        }
        Ok(self.peeked.as_ref().expect("just read"))
    }

    fn next(&mut self) -> Result<(Tok, usize), ParseError> {
        match self.peeked.take() {
            Some(t) => Ok(t),
            None => self.read(),
        }
    }

    fn read(&mut self) -> Result<(Tok, usize), ParseError> {
        for c in self.text[self.pos..].chars() {
            if !c.is_whitespace() {
                break;
            }
            self.pos += c.len_utf8();
            self.at += 1;
        }
        let rest = &self.text[self.pos..];
        let bytes = rest.as_bytes();
        let start = self.at;
        let Some(&b) = bytes.first() else {
            return Ok((Tok::End, start));
        };
        let digit = |i: usize| bytes.get(i).is_some_and(u8::is_ascii_digit);
        // Every token is ASCII, so its length in bytes is its length in characters.
        let (tok, len) = if b.is_ascii_digit() || (b == b'.' && digit(1)) {
            let mut i = 0;
            while digit(i) || bytes.get(i) == Some(&b'.') {
                i += 1;
            }
            // An exponent only when digits follow: "2e" is a number and a name.
            if matches!(bytes.get(i), Some(b'e' | b'E')) {
                let sign = usize::from(matches!(bytes.get(i + 1), Some(b'+' | b'-')));
                if digit(i + 1 + sign) {
                    i += 1 + sign;
                    while digit(i) {
                        i += 1;
                    }
                }
            }
            let s = &rest[..i];
            let v: f64 = s
                .parse()
                .map_err(|_| error(start, format!("'{s}' is not a number")))?;
            (Tok::Num(v), i)
        } else if b.is_ascii_alphabetic() || b == b'_' {
            let i = bytes
                .iter()
                .position(|c| !(c.is_ascii_alphanumeric() || *c == b'_'))
                .unwrap_or(bytes.len());
            (Tok::Name(rest[..i].to_string()), i)
        } else if b"+-*/^(),".contains(&b) {
            (Tok::Op(b as char), 1)
        } else {
            let c = rest.chars().next().expect("not at the end");
            return Err(error(start, format!("unexpected character '{c}'")));
        };
        self.pos += len;
        self.at += len;
        Ok((tok, start))
    }
}
