//! Nodes by what they compute: the same operation on the same values is recorded once
//! (`Tape::seen`).

use super::Ref;
use super::ops::{Binary, Unary};

/// What identifies an elementwise node: its operation (a constant's bits included) and its
/// inputs, commutative ones in one order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct Key {
    op: u8,
    constant: u64,
    a: Ref,
    b: Option<Ref>,
}

/// A multiply-rotate hash of a [`Key`]'s few words (the FxHash of rustc): SipHash's
/// defence against chosen keys costs more than the node it would find, and a tape's keys
/// are its own node numbers.
#[derive(Default, Clone, Copy)]
pub(super) struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        bytes.iter().for_each(|&b| self.write_u64(u64::from(b)));
    }
    fn write_u8(&mut self, i: u8) {
        self.write_u64(u64::from(i));
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
}

/// The tape's map of recorded nodes by [`Key`].
pub(super) type Seen =
    std::collections::HashMap<Key, Ref, std::hash::BuildHasherDefault<KeyHasher>>;

impl Unary {
    pub(super) fn key(self, a: Ref) -> Key {
        let (op, constant) = match self {
            Unary::Neg => (0, 0),
            Unary::Scale(c) => (1, c.to_bits()),
            Unary::Shift(c) => (2, c.to_bits()),
            Unary::Cos => (3, 0),
            Unary::Sin => (4, 0),
            Unary::Sqrt => (5, 0),
            Unary::Exp => (6, 0),
            Unary::Ln => (7, 0),
            Unary::Sigmoid => (8, 0),
            Unary::Softplus => (9, 0),
            Unary::Tanh => (10, 0),
            Unary::Square => (11, 0),
        };
        Key {
            op,
            constant,
            a,
            b: None,
        }
    }
}

impl Binary {
    pub(super) fn key(self, a: Ref, b: Ref) -> Key {
        let (op, (a, b)) = match self {
            // a + b and a · b are b + a and b · a to the bit.
            Binary::Add => (20, (a.min_by_node(b), a.max_by_node(b))),
            Binary::Mul => (21, (a.min_by_node(b), a.max_by_node(b))),
            Binary::Sub => (22, (a, b)),
            Binary::Div => (23, (a, b)),
            Binary::Atan2 => (24, (a, b)),
        };
        Key {
            op,
            constant: 0,
            a,
            b: Some(b),
        }
    }
}

impl Ref {
    fn order(self) -> (u32, u32) {
        (self.node, self.col)
    }
    fn min_by_node(self, o: Ref) -> Ref {
        if self.order() <= o.order() { self } else { o }
    }
    fn max_by_node(self, o: Ref) -> Ref {
        if self.order() <= o.order() { o } else { self }
    }
}
