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
//! rows]` block, so each product with W is one pass over it.

use super::{Op, Ref, Slot, Tape, Var};
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
    /// Where each layer's input block starts in the arena (the last layer's output is the
    /// node's own slot).
    blocks: Vec<usize>,
}

/// The network `layers` (tanh between them) of `x`, whose tangents beyond `dirs` are
/// ignored: its outputs with `dirs` tangents each.
pub fn mlp(layers: &[Layer], x: &[Dual<Var>], dirs: usize) -> Vec<Dual<Var>> {
    let tape = x[0].v.tape.clone();
    let r = {
        let mut t = tape.borrow_mut();
        let rows = t.rows;
        let width = (1 + dirs) * rows;
        let mut inputs = Vec::with_capacity(x.len() * (1 + dirs));
        let mut blocks = vec![t.vals.len()];
        for xi in x {
            for d in 0..=dirs {
                let r = if d == 0 {
                    Some(&xi.v)
                } else {
                    xi.tangent(d - 1)
                }
                .map(|v| v.r);
                inputs.push(r);
                let col: Vec<f64> = match r {
                    Some(r) => {
                        let c = t.col(r);
                        (0..rows).map(|k| c[k % c.len()]).collect()
                    }
                    None => vec![0.0; rows],
                };
                t.vals.extend(col);
            }
        }
        let (last, hidden) = layers.split_last().expect("a network has layers");
        for layer in hidden {
            let at = *blocks.last().expect("an input block");
            let x = &t.vals[at..at + layer.d_in * width];
            let y = forward_layer(x, &t.params, layer, rows, dirs, true);
            blocks.push(t.vals.len());
            t.vals.extend(y);
        }
        let at = *blocks.last().expect("an input block");
        let y = forward_layer(
            &t.vals[at..at + last.d_in * width],
            &t.params,
            last,
            rows,
            dirs,
            false,
        );
        let node = Node {
            layers: layers.to_vec(),
            dirs,
            inputs,
            blocks,
        };
        t.push(Op::Mlp(Box::new(node)), rows, last.d_out * (1 + dirs), y)
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

/// z = Wᵀx (+ b on the values), then tanh on the values and s ⊙ z_d on the tangents when
/// `tanh`: the layer's output block from its input block `x` `[d_in, (1 + dirs) · rows]`.
fn forward_layer(
    x: &[f64],
    params: &[f64],
    l: &Layer,
    rows: usize,
    dirs: usize,
    tanh: bool,
) -> Vec<f64> {
    let mut z = pre_activation(x, params, l, rows, dirs);
    let width = (1 + dirs) * rows;
    if tanh {
        for zo in z.chunks_mut(width) {
            let (v, tangents) = zo.split_at_mut(rows);
            crate::simd::tanh_in_place(v);
            for t in tangents.chunks_mut(rows) {
                t.iter_mut()
                    .zip(v.iter())
                    .for_each(|(t, y)| *t *= 1.0 - y * y);
            }
        }
    }
    z
}

/// Wᵀx with b added to the values (not the tangents): `[d_out, (1 + dirs) · rows]`.
fn pre_activation(x: &[f64], params: &[f64], l: &Layer, rows: usize, dirs: usize) -> Vec<f64> {
    let width = (1 + dirs) * rows;
    let w = &params[l.w..l.w + l.d_in * l.d_out];
    let mut z = vec![0.0; l.d_out * width];
    for (o, zo) in z.chunks_mut(width).enumerate() {
        zo[..rows].fill(params[l.b + o]);
    }
    // Z += Wᵀ X: W is [d_in, d_out] row-major, so Wᵀ's rows step by 1 and its columns by d_out.
    gemm(
        (l.d_out, l.d_in, width),
        (w, 1, l.d_out),
        (x, width, 1),
        (&mut z, width, 1),
    );
    z
}

/// C += A·B for A `m × k`, B `k × n` and C `m × n`, each given with its row and column
/// strides.
fn gemm(
    (m, k, n): (usize, usize, usize),
    (a, rsa, csa): (&[f64], usize, usize),
    (b, rsb, csb): (&[f64], usize, usize),
    (c, rsc, csc): (&mut [f64], usize, usize),
) {
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| {
        if rows == 0 || cols == 0 {
            0
        } else {
            (rows - 1) * rs + (cols - 1) * cs + 1
        }
    };
    assert!(a.len() >= last(m, k, rsa, csa) && b.len() >= last(k, n, rsb, csb));
    assert!(
        c.len() >= last(m, n, rsc, csc),
        "gemm: operands fit their shapes"
    );
    let s = |v: usize| v as isize;
    // SAFETY: the asserts above keep every element the strides reach inside its slice, and C
    // is a unique borrow that A and B cannot alias.
    unsafe {
        matrixmultiply::dgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            s(rsa),
            s(csa),
            b.as_ptr(),
            s(rsb),
            s(csb),
            1.0,
            c.as_mut_ptr(),
            s(rsc),
            s(csc),
        );
    }
}

impl Node {
    /// The node's adjoint carried back through every layer into W, b and the inputs.
    pub(super) fn backward(
        &self,
        t: &Tape,
        adj: &mut [f64],
        d_params: &mut [f64],
        own: &super::Node,
    ) {
        let rows = t.rows;
        let width = (1 + self.dirs) * rows;
        let Slot { start, .. } = own.slot;
        let last = self.layers.len() - 1;
        let mut dy = adj[start..start + own.cols * rows].to_vec();
        for (l, layer) in self.layers.iter().enumerate().rev() {
            let x = &t.vals[self.blocks[l]..self.blocks[l] + layer.d_in * width];
            let dz = if l == last {
                dy
            } else {
                let at = self.blocks[l + 1];
                let y = &t.vals[at..at + layer.d_out * width];
                let z = pre_activation(x, &t.params, layer, rows, self.dirs);
                tanh_back(&dy, y, &z, rows, width)
            };
            dy = layer_back(x, &dz, t, d_params, layer, rows, width);
        }
        for (r, dx) in self.inputs.iter().zip(dy.chunks(rows)) {
            let Some(r) = r else { continue };
            let s = t.slot(*r);
            if s.len == rows {
                (adj[s.start..s.start + rows].iter_mut().zip(dx)).for_each(|(a, g)| *a += g);
            } else {
                adj[s.start] += dx.iter().sum::<f64>();
            }
        }
    }
}

/// ∂z from ∂y through y = tanh z and y_d = (1 − y²) z_d.
fn tanh_back(dy: &[f64], y: &[f64], z: &[f64], rows: usize, width: usize) -> Vec<f64> {
    let mut dz = vec![0.0; dy.len()];
    for ((dzo, dyo), (yo, zo)) in dz
        .chunks_mut(width)
        .zip(dy.chunks(width))
        .zip(y.chunks(width).zip(z.chunks(width)))
    {
        let (v, s) = (&yo[..rows], |k: usize| 1.0 - yo[k] * yo[k]);
        let mut ds = vec![0.0; rows];
        for d in 1..width / rows {
            for k in 0..rows {
                let (g, zk) = (dyo[d * rows + k], zo[d * rows + k]);
                dzo[d * rows + k] = s(k) * g;
                ds[k] += g * zk;
            }
        }
        for k in 0..rows {
            dzo[k] = s(k) * (dyo[k] - 2.0 * v[k] * ds[k]);
        }
    }
    dz
}

/// ∂W and ∂b accumulated from the layer's input block `x` and ∂z; returns ∂x.
fn layer_back(
    x: &[f64],
    dz: &[f64],
    t: &Tape,
    d_params: &mut [f64],
    l: &Layer,
    rows: usize,
    width: usize,
) -> Vec<f64> {
    let w = &t.params[l.w..l.w + l.d_in * l.d_out];
    for (o, dzo) in dz.chunks(width).enumerate() {
        d_params[l.b + o] += dzo[..rows].iter().sum::<f64>();
    }
    // ∂W += X ∂Zᵀ ([d_in, d_out]), ∂X = W ∂Z ([d_in, width]).
    let dw = &mut d_params[l.w..l.w + l.d_in * l.d_out];
    gemm(
        (l.d_in, width, l.d_out),
        (x, width, 1),
        (dz, 1, width),
        (dw, l.d_out, 1),
    );
    let mut dx = vec![0.0; l.d_in * width];
    gemm(
        (l.d_in, l.d_out, width),
        (w, l.d_out, 1),
        (dz, width, 1),
        (&mut dx, width, 1),
    );
    dx
}
