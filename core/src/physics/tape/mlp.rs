//! A network as one node of the tape: tanh layers and a linear last one, carrying `dirs`
//! tangent directions through (the model's ∂/∂q for L and V), with the backward pass of the
//! whole thing written out. Per layer, with s = 1 − y² and tangents t_d:
//!
//! ```text
//! forward:  z = Wᵀx + b,  z_d = Wᵀt_d,  y = tanh z,  y_d = s ⊙ z_d     (last layer: y = z)
//! backward: ∂z_d = s ⊙ ∂y_d,  ∂s = Σ_d ∂y_d ⊙ z_d,  ∂z = s ⊙ (∂y − 2y ⊙ ∂s)
//!           ∂W += x ∂zᵀ + Σ_d t_d ∂z_dᵀ,  ∂b += Σ_rows ∂z,  ∂x = W ∂z,  ∂t_d = W ∂z_d
//! ```
//!
//! The ∂s term is the second derivative of the network: the gradient of its input
//! derivatives. A layer's value and tangents sit side by side as one `[width, (1 + dirs) ·
//! rows]` block, so each product with W is one pass over it. The blocks live in the tape's
//! arena of the networks' precision ([`Net`]); only the last layer's outputs join the f64
//! values.

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Mul, Sub};

use super::{Op, Params, Precision, Ref, Tape, Var};
use crate::physics::dual::Dual;

/// One layer's place in the parameters: W `[d_in, d_out]` row-major from `w`, b from `b`.
#[derive(Debug, Clone, Copy)]
pub struct Layer {
    pub d_in: usize,
    pub d_out: usize,
    pub w: usize,
    pub b: usize,
}

#[derive(Debug, Clone)]
pub(super) struct Node {
    layers: Vec<Layer>,
    dirs: usize,
    /// Input i's value (d = 0) and tangents at `i · (1 + dirs) + d`; `None`: zero.
    inputs: Vec<Option<Ref>>,
    /// Where each layer's input block starts in the networks' arena, and last, where the
    /// outputs' block does.
    blocks: Vec<usize>,
}

/// A float the networks compute in: its arena on the tape, its copy of the parameters and
/// its matrix product.
pub(super) trait Net:
    Copy + Debug + Default + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + AddAssign
{
    const ONE: Self;
    const TWO: Self;
    fn of(x: f64) -> Self;
    fn wide(self) -> f64;
    fn tanh_in_place(z: &mut [Self]);
    /// The f64 values, this precision's arena and parameters.
    fn parts(t: &mut Tape) -> (&[f64], &mut Vec<Self>, &[Self]);
    fn arena(t: &Tape) -> &[Self];
    fn params(p: &Params) -> &[Self];
    /// C += A·B by matrixmultiply's kernel for this float.
    ///
    /// # Safety
    /// Every element the shapes and strides reach lies inside its operand, and C aliases
    /// neither A nor B ([`gemm`] checks this).
    unsafe fn mm(
        mkn: (usize, usize, usize),
        a: (*const Self, isize, isize),
        b: (*const Self, isize, isize),
        c: (*mut Self, isize, isize),
    );
}

macro_rules! net_float {
    ($t:ty, $arena:ident, $params:ident, $mm:path, $tanh:path) => {
        impl Net for $t {
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            fn of(x: f64) -> Self {
                x as $t
            }
            fn wide(self) -> f64 {
                self as f64
            }
            fn tanh_in_place(z: &mut [Self]) {
                $tanh(z)
            }
            fn parts(t: &mut Tape) -> (&[f64], &mut Vec<Self>, &[Self]) {
                (&t.vals, &mut t.$arena, &t.params.$params)
            }
            fn arena(t: &Tape) -> &[Self] {
                &t.$arena
            }
            fn params(p: &Params) -> &[Self] {
                &p.$params
            }
            unsafe fn mm(
                (m, k, n): (usize, usize, usize),
                (a, rsa, csa): (*const Self, isize, isize),
                (b, rsb, csb): (*const Self, isize, isize),
                (c, rsc, csc): (*mut Self, isize, isize),
            ) {
                // SAFETY: the caller's contract.
                unsafe { $mm(m, k, n, 1.0, a, rsa, csa, b, rsb, csb, 1.0, c, rsc, csc) }
            }
        }
    };
}

net_float!(
    f32,
    net32,
    narrow,
    matrixmultiply::sgemm,
    crate::simd::tanh_in_place_f32
);
net_float!(
    f64,
    net64,
    values,
    matrixmultiply::dgemm,
    crate::simd::tanh_in_place
);

/// The network `layers` (tanh between them) of `x`, whose tangents beyond `dirs` are
/// ignored: its outputs with `dirs` tangents each.
pub fn mlp(layers: &[Layer], x: &[Dual<Var>], dirs: usize) -> Vec<Dual<Var>> {
    let tape = x[0].v.tape.clone();
    let r = {
        let mut t = tape.borrow_mut();
        let inputs: Vec<Option<Ref>> = (x.iter())
            .flat_map(|xi| {
                (0..=dirs).map(move |d| {
                    if d == 0 {
                        Some(&xi.v)
                    } else {
                        xi.tangent(d - 1)
                    }
                    .map(|v| v.r)
                })
            })
            .collect();
        let node = match t.params.precision {
            Precision::F32 => record::<f32>(&mut t, layers, inputs, dirs),
            Precision::F64 => record::<f64>(&mut t, layers, inputs, dirs),
        };
        let rows = t.rows;
        let cols = layers[layers.len() - 1].d_out * (1 + dirs);
        let start = t.vals.len();
        let out = node.blocks[layers.len()];
        match t.params.precision {
            Precision::F32 => widen::<f32>(&mut t, out, cols * rows),
            Precision::F64 => widen::<f64>(&mut t, out, cols * rows),
        }
        t.node(Op::Mlp(Box::new(node)), start, rows, cols)
    };
    (0..layers[layers.len() - 1].d_out)
        .map(|o| {
            let col = |d: usize| Var {
                tape: tape.clone(),
                r: Ref {
                    node: r.node,
                    col: (o * (1 + dirs) + d) as u32,
                },
            };
            Dual::new(col(0), (1..=dirs).map(|d| Some(col(d))))
        })
        .collect()
}

/// Appends `len` values of the networks' arena from `at` to the f64 values.
fn widen<T: Net>(t: &mut Tape, at: usize, len: usize) {
    let start = t.vals.len();
    t.vals.resize(start + len, 0.0);
    let (src, out) = (T::arena(t)[at..at + len].to_vec(), &mut t.vals[start..]);
    (out.iter_mut().zip(src)).for_each(|(o, v)| *o = v.wide());
}

/// The network's forward pass into the arena of `T`: the input block, then every layer's.
fn record<T: Net>(t: &mut Tape, layers: &[Layer], inputs: Vec<Option<Ref>>, dirs: usize) -> Node {
    let rows = t.rows;
    let slots: Vec<_> = inputs.iter().map(|r| r.map(|r| t.slot(r))).collect();
    let (vals, arena, params) = T::parts(t);
    let mut blocks = vec![arena.len()];
    for s in slots {
        match s {
            Some(s) if s.len == rows => {
                arena.extend(vals[s.start..s.start + rows].iter().map(|&v| T::of(v)))
            }
            Some(s) => arena.extend(std::iter::repeat_n(T::of(vals[s.start]), rows)),
            None => arena.resize(arena.len() + rows, T::default()),
        }
    }
    let width = (1 + dirs) * rows;
    for (l, layer) in layers.iter().enumerate() {
        let at = arena.len();
        arena.resize(at + layer.d_out * width, T::default());
        let (head, z) = arena.split_at_mut(at);
        let x = &head[blocks[l]..blocks[l] + layer.d_in * width];
        forward_layer(x, z, params, layer, rows, width, l + 1 < layers.len());
        blocks.push(at);
    }
    Node {
        layers: layers.to_vec(),
        dirs,
        inputs,
        blocks,
    }
}

/// z = Wᵀx (+ b on the values), then tanh on the values and s ⊙ z_d on the tangents when
/// `tanh`: the layer's output block `z` (zeroed) from its input block `x`, both
/// `[·, (1 + dirs) · rows]`.
fn forward_layer<T: Net>(
    x: &[T],
    z: &mut [T],
    params: &[T],
    l: &Layer,
    rows: usize,
    width: usize,
    tanh: bool,
) {
    for (o, zo) in z.chunks_mut(width).enumerate() {
        zo[..rows].fill(params[l.b + o]);
    }
    // Z += Wᵀ X: W is [d_in, d_out] row-major, so Wᵀ's rows step by 1 and its columns by d_out.
    let w = &params[l.w..l.w + l.d_in * l.d_out];
    gemm(
        (l.d_out, l.d_in, width),
        (w, 1, l.d_out),
        (x, width, 1),
        (z, width, 1),
    );
    if tanh {
        for zo in z.chunks_mut(width) {
            let (v, tangents) = zo.split_at_mut(rows);
            T::tanh_in_place(v);
            for t in tangents.chunks_mut(rows) {
                (t.iter_mut().zip(v.iter())).for_each(|(t, &y)| *t = *t * (T::ONE - y * y));
            }
        }
    }
}

/// C += A·B for A `m × k`, B `k × n` and C `m × n`, each given with its row and column
/// strides.
fn gemm<T: Net>(
    (m, k, n): (usize, usize, usize),
    (a, rsa, csa): (&[T], usize, usize),
    (b, rsb, csb): (&[T], usize, usize),
    (c, rsc, csc): (&mut [T], usize, usize),
) {
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| {
        if rows == 0 || cols == 0 {
            0
        } else {
            (rows - 1) * rs + (cols - 1) * cs + 1
        }
    };
    assert!(
        a.len() >= last(m, k, rsa, csa)
            && b.len() >= last(k, n, rsb, csb)
            && c.len() >= last(m, n, rsc, csc),
        "gemm: operands fit their shapes"
    );
    let s = |v: usize| v as isize;
    // SAFETY: the assert keeps every element the strides reach inside its slice, and C is a
    // unique borrow that A and B cannot alias.
    unsafe {
        T::mm(
            (m, k, n),
            (a.as_ptr(), s(rsa), s(csa)),
            (b.as_ptr(), s(rsb), s(csb)),
            (c.as_mut_ptr(), s(rsc), s(csc)),
        )
    }
}

impl Node {
    /// The values it reads: its inputs and their tangents.
    pub(super) fn inputs(&self) -> impl Iterator<Item = Ref> + '_ {
        self.inputs.iter().flatten().copied()
    }

    /// Its layers' weights and biases, by their place in the parameters.
    pub(super) fn params(&self) -> impl Iterator<Item = usize> + '_ {
        (self.layers.iter()).flat_map(|l| (l.w..l.w + l.d_in * l.d_out).chain(l.b..l.b + l.d_out))
    }

    /// The node's adjoint carried back through every layer into W, b and the inputs.
    pub(super) fn backward(
        &self,
        t: &Tape,
        adj: &mut [f64],
        d_params: &mut [f64],
        own: &super::Node,
    ) {
        match t.params.precision {
            Precision::F32 => self.backward_in::<f32>(t, adj, d_params, own),
            Precision::F64 => self.backward_in::<f64>(t, adj, d_params, own),
        }
    }

    fn backward_in<T: Net>(
        &self,
        t: &Tape,
        adj: &mut [f64],
        d_params: &mut [f64],
        own: &super::Node,
    ) {
        let (rows, arena, w) = (t.rows, T::arena(t), T::params(&t.params));
        let width = (1 + self.dirs) * rows;
        let start = own.slot.start;
        let mut dy: Vec<T> = (adj[start..start + own.cols * rows].iter())
            .map(|&g| T::of(g))
            .collect();
        let (mut dx, mut dw) = (Vec::new(), Vec::new());
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate().rev() {
            let at = self.blocks[l];
            let x = &arena[at..at + layer.d_in * width];
            if l != last {
                let at = self.blocks[l + 1];
                tanh_back(&mut dy, &arena[at..at + layer.d_out * width], rows, width);
            }
            for (o, dzo) in dy.chunks(width).enumerate() {
                d_params[layer.b + o] += dzo[..rows].iter().map(|v| v.wide()).sum::<f64>();
            }
            // ∂W = X ∂Zᵀ ([d_in, d_out]), ∂X = W ∂Z ([d_in, width]).
            let (d_in, d_out) = (layer.d_in, layer.d_out);
            dw.clear();
            dw.resize(d_in * d_out, T::default());
            gemm(
                (d_in, width, d_out),
                (x, width, 1),
                (&dy, 1, width),
                (&mut dw, d_out, 1),
            );
            (d_params[layer.w..layer.w + dw.len()].iter_mut().zip(&dw))
                .for_each(|(p, g)| *p += g.wide());
            dx.clear();
            dx.resize(d_in * width, T::default());
            let wl = &w[layer.w..layer.w + d_in * d_out];
            gemm(
                (d_in, d_out, width),
                (wl, d_out, 1),
                (&dy, width, 1),
                (&mut dx, width, 1),
            );
            std::mem::swap(&mut dy, &mut dx);
        }
        for (r, dx) in self.inputs.iter().zip(dy.chunks(rows)) {
            let Some(r) = r else { continue };
            let s = t.slot(*r);
            if s.len == rows {
                (adj[s.start..s.start + rows].iter_mut().zip(dx)).for_each(|(a, g)| *a += g.wide());
            } else {
                adj[s.start] += dx.iter().map(|v| v.wide()).sum::<f64>();
            }
        }
    }
}

/// ∂y → ∂z in place, through y = tanh z and y_d = s ⊙ z_d (s = 1 − y²). The second-derivative
/// term s ⊙ ∂s = Σ_d ∂y_d ⊙ z_d ⊙ s = Σ_d ∂y_d ⊙ y_d needs only the layer's outputs, so the
/// backward pass never recomputes the pre-activations.
fn tanh_back<T: Net>(dy: &mut [T], y: &[T], rows: usize, width: usize) {
    let mut sds = vec![T::default(); rows];
    for (g, yo) in dy.chunks_mut(width).zip(y.chunks(width)) {
        let (gv, gt) = g.split_at_mut(rows);
        let (v, yt) = yo.split_at(rows);
        sds.fill(T::default());
        for (gd, yd) in gt.chunks_mut(rows).zip(yt.chunks(rows)) {
            for k in 0..rows {
                sds[k] += gd[k] * yd[k];
                gd[k] = (T::ONE - v[k] * v[k]) * gd[k];
            }
        }
        for k in 0..rows {
            gv[k] = (T::ONE - v[k] * v[k]) * gv[k] - T::TWO * v[k] * sds[k];
        }
    }
}
