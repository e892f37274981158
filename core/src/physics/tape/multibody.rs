//! A robot's forward dynamics as one node of the tape (docs/robots.md#training-by-the-adjoint):
//! q̈ = FD(q, q̇, τ; π), forward by the articulated-body algorithm row by row and backward by
//! forward dynamics' adjoint (λ = M⁻¹ḡ; ∂/∂τ = λ, ∂/∂π = −Yᵀλ, ∂/∂(q, q̇) by λ contracted
//! with RNEA's derivatives), O(n) per row each, where the scalar nodes of the same
//! algorithm would be thousands per row. τ and π are the tape's own values (τ from the
//! model's forces, π from its physical values), so the gradients reach them as any node's.
//!
//! Its inverse, τ = ID(q, q̇, q̈; π) by RNEA, is the same kind of node for the torque loss
//! (docs/training.md#torque-loss): backward ∂/∂q̈ = Mḡ, ∂/∂π = Yᵀḡ and ∂/∂(q, q̇) by ḡ
//! contracted with RNEA's derivatives, without a solve.

use super::{Op, Ref, Slot, Tape, Var};
use crate::physics::multibody::data::PLACED;
use crate::physics::multibody::regressor::with_parameters;
use crate::physics::multibody::{Model, with_data};

#[derive(Debug, Clone)]
pub(super) struct Node {
    /// The robot with π's inertias.
    model: Model,
    /// q, q̇ and τ (q̈ for inverse dynamics; n each), then π (ten per body).
    inputs: Vec<Ref>,
    /// τ = ID(q, q̇, q̈) rather than q̈ = FD(q, q̇, τ).
    inverse: bool,
    /// Every row's placements (`Data::save_placements`), which the backward pass restores
    /// instead of computing the trigonometry and the rotations down the tree again.
    placed: Vec<f64>,
}

/// q̈ of every row of the block: `robot`'s tree with the inertias of π (values every row
/// shares: they come from the parameters alone) at (q, q̇) under joint forces τ.
pub fn forward_dynamics(robot: &Model, q: &[Var], qd: &[Var], tau: &[Var], pi: &[Var]) -> Vec<Var> {
    record(robot, [q, qd, tau], pi, false)
}

/// τ of every row of the block: the joint forces that give `robot`'s tree with the inertias
/// of π the accelerations q̈ at (q, q̇).
pub fn inverse_dynamics(robot: &Model, q: &[Var], qd: &[Var], qdd: &[Var], pi: &[Var]) -> Vec<Var> {
    record(robot, [q, qd, qdd], pi, true)
}

fn record(robot: &Model, [q, qd, third]: [&[Var]; 3], pi: &[Var], inverse: bool) -> Vec<Var> {
    let n = robot.n;
    assert!(
        q.len() == n && qd.len() == n && third.len() == n,
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
        let inputs: Vec<Ref> = (q.iter().chain(qd).chain(third).chain(pi))
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
                let (q, qd, third) = (&row[..n], &row[n..2 * n], &row[2 * n..]);
                let out = if inverse {
                    data.kinematics(&model, q, qd);
                    data.qdd.copy_from_slice(third);
                    data.inverse_torques(&model);
                    &data.bias
                } else {
                    data.forward_dynamics(&model, q, qd, third);
                    &data.qdd
                };
                for (j, a) in out.iter().enumerate() {
                    t.vals[start + j * rows + k] = *a;
                }
                data.save_placements(&mut placed);
            }
        });
        let node = Node {
            model,
            inputs,
            inverse,
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

    /// The adjoint row by row: the output's adjoint ḡ carried into q, q̇, τ (or q̈) and π.
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
                }
                if g.iter().all(|&g| g == 0.0) {
                    continue;
                }
                gather(&t.vals, &slots[..3 * n], k, &mut row);
                let placed = &self.placed[k * per_row..][..per_row];
                data.kinematics_from(&self.model, placed, &row[n..2 * n]);
                if self.inverse {
                    let qdd = &row[2 * n..];
                    data.inverse_adjoint(&self.model, qdd, &g, &mut d_row, &mut pi_sum);
                } else {
                    for (j, a) in qdd.iter_mut().enumerate() {
                        *a = t.vals[out + j * rows + k];
                    }
                    data.adjoint(&self.model, &qdd, &g, &mut d_row, &mut pi_sum);
                }
                for (s, d) in slots.iter().zip(&d_row) {
                    lo[s.start + if s.len == 1 { 0 } else { k }] += d;
                }
            }
        });
        // `adjoint` adds +Yᵀλ, ∂/∂π of forward dynamics is its negative; inverse dynamics'
        // is +Yᵀḡ itself.
        let sign = if self.inverse { 1.0 } else { -1.0 };
        for (s, d) in slots[3 * n..].iter().zip(&pi_sum) {
            lo[s.start] += sign * d;
        }
    }
}
