//! A robot's forward dynamics as one node of the tape (docs/robots.md#training-by-the-adjoint):
//! q̈ = FD(q, q̇, τ; π), forward by the articulated-body algorithm row by row and backward by
//! forward dynamics' adjoint (λ = M⁻¹ḡ; ∂/∂τ = λ, ∂/∂π = −Yᵀλ, ∂/∂(q, q̇) by λ contracted
//! with RNEA's derivatives), O(n) per row each, where the scalar nodes of the same
//! algorithm would be thousands per row. τ and π are the tape's own values (τ from the
//! model's forces, π from its physical values), so the gradients reach them as any node's.

use super::{Op, Ref, Slot, Tape, Var};
use crate::physics::multibody::data::PLACED;
use crate::physics::multibody::regressor::with_parameters;
use crate::physics::multibody::{Model, with_data};

#[derive(Debug, Clone)]
pub(super) struct Node {
    /// The robot with π's inertias.
    model: Model,
    /// q, q̇ and τ (n each), then π (ten per body).
    inputs: Vec<Ref>,
    /// Every row's placements (`Data::save_placements`), which the backward pass restores
    /// instead of computing the trigonometry and the rotations down the tree again.
    placed: Vec<f64>,
}

/// q̈ of every row of the block: `robot`'s tree with the inertias of π (values every row
/// shares: they come from the parameters alone) at (q, q̇) under joint forces τ.
pub fn forward_dynamics(robot: &Model, q: &[Var], qd: &[Var], tau: &[Var], pi: &[Var]) -> Vec<Var> {
    let n = robot.n;
    assert!(
        q.len() == n && qd.len() == n && tau.len() == n,
        "n values each"
    );
    let tape = q[0].tape.clone();
    let r = {
        let mut t = tape.borrow_mut();
        let pi_values: Vec<f64> = (pi.iter())
            .map(|p| match t.col(p.r) {
                [v] => *v,
                _ => panic!("π depends on the parameters alone, not on a row"),
            })
            .collect();
        let model = with_parameters(robot, &pi_values);
        let inputs: Vec<Ref> = (q.iter().chain(qd).chain(tau).chain(pi))
            .map(|v| v.r)
            .collect();
        let rows = t.rows;
        let slots: Vec<Slot> = inputs[..3 * n].iter().map(|&r| t.slot(r)).collect();
        let mut placed = Vec::with_capacity(rows * PLACED * model.bodies.len());
        let start = t.vals.len();
        t.vals.resize(start + n * rows, 0.0);
        let mut row = vec![0.0; 3 * n];
        with_data(|data| {
            for k in 0..rows {
                gather(&t.vals, &slots, k, &mut row);
                data.forward_dynamics(&model, &row[..n], &row[n..2 * n], &row[2 * n..]);
                data.save_placements(&mut placed);
                for (j, a) in data.qdd.iter().enumerate() {
                    t.vals[start + j * rows + k] = *a;
                }
            }
        });
        let node = Node {
            model,
            inputs,
            placed,
        };
        t.node(Op::Multibody(Box::new(node)), start, rows, n)
    };
    (0..n)
        .map(|j| Var {
            tape: tape.clone(),
            r: Ref {
                node: r.node,
                col: j as u32,
            },
        })
        .collect()
}

/// Row `k` of the columns at `slots` (a shared value is every row's).
fn gather(vals: &[f64], slots: &[Slot], k: usize, row: &mut [f64]) {
    for (x, s) in row.iter_mut().zip(slots) {
        *x = vals[s.start + if s.len == 1 { 0 } else { k }];
    }
}

impl Node {
    pub(super) fn inputs(&self) -> impl Iterator<Item = Ref> + '_ {
        self.inputs.iter().copied()
    }

    /// The adjoint row by row: the output's adjoint ḡ carried into q, q̇, τ and π.
    pub(super) fn backward(&self, t: &Tape, adj: &mut [f64], own: &super::Node) {
        let (n, rows) = (self.model.n, t.rows);
        let per_row = PLACED * self.model.bodies.len();
        let slots: Vec<Slot> = self.inputs.iter().map(|&r| t.slot(r)).collect();
        let out = own.slot.start;
        let (lo, hi) = adj.split_at_mut(out);
        let mut pi_sum = vec![0.0; slots.len() - 3 * n];
        let (mut row, mut qdd, mut g, mut d_row) = (
            vec![0.0; 3 * n],
            vec![0.0; n],
            vec![0.0; n],
            vec![0.0; 3 * n],
        );
        with_data(|data| {
            for k in 0..rows {
                for j in 0..n {
                    g[j] = hi[j * rows + k];
                    qdd[j] = t.vals[out + j * rows + k];
                }
                if g.iter().all(|&g| g == 0.0) {
                    continue;
                }
                gather(&t.vals, &slots[..3 * n], k, &mut row);
                let placed = &self.placed[k * per_row..][..per_row];
                data.kinematics_from(&self.model, placed, &row[n..2 * n]);
                data.adjoint(&self.model, &qdd, &g, &mut d_row, &mut pi_sum);
                for (s, d) in slots.iter().zip(&d_row) {
                    lo[s.start + if s.len == 1 { 0 } else { k }] += d;
                }
            }
        });
        // `adjoint` adds +Yᵀλ; ∂/∂π is its negative.
        for (s, d) in slots[3 * n..].iter().zip(&pi_sum) {
            lo[s.start] -= d;
        }
    }
}
