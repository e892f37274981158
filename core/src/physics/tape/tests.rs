//! The tape's gradients against central finite differences of its own forward values: every
//! elementwise node with broadcasting, and a network with input tangents (whose gradient
//! holds the network's second derivatives).

use super::{Layer, Params, Precision, Tape, Var, mlp};
use crate::physics::dual::Dual;
use crate::physics::scalar::Scalar;
use crate::rng::Rng;

const ROWS: usize = 5;

/// Σ_k g_k · f_k over the outputs of `f` on a fresh tape at (`x`, `params`), and the tape's
/// gradient of it with respect to the inputs and the parameters.
fn run(
    x: &[Vec<f64>],
    params: &[f64],
    g: &[Vec<f64>],
    f: &dyn Fn(&[Var]) -> Vec<Var>,
) -> (f64, Vec<Vec<f64>>, Vec<f64>) {
    let tape = Tape::new(
        ROWS,
        Params::new(params.to_vec(), Precision::F64),
        Default::default(),
    );
    let inputs: Vec<Var> = x.iter().map(|c| Var::input(&tape, c.clone())).collect();
    let out = f(&inputs);
    let value: f64 = (out.iter().zip(g))
        .map(|(o, g)| {
            let v = o.values();
            (0..ROWS).map(|k| v[k % v.len()] * g[k]).sum::<f64>()
        })
        .sum();
    // A shared output stands for every row's: its seed is theirs summed.
    let sums: Vec<[f64; 1]> = g.iter().map(|g| [g.iter().sum()]).collect();
    let seeds: Vec<(_, &[f64])> = (out.iter().zip(g).zip(&sums))
        .map(|((o, g), s)| {
            (
                o.id(),
                if o.values().len() == 1 {
                    &s[..]
                } else {
                    &g[..]
                },
            )
        })
        .collect();
    let ids: Vec<_> = inputs.iter().map(Var::id).collect();
    drop((inputs, out));
    let mut t = Tape::finish(tape);
    let grads = t.gradients(&seeds);
    let dx = ids.iter().map(|&r| t.adjoint(&grads, r).to_vec()).collect();
    (value, dx, grads.params.clone())
}

/// Checks the tape's gradient of `f` at a random point against central differences (step
/// 1e-6: truncation ~1e-12 · f‴, round-off ~1e-16 · |L| / 1e-6 ≈ 1e-10 · |L|; 1e-6 relative
/// to the gradient's size catches any wrong rule, whose error is of the gradient's order).
fn check(inputs: usize, params: usize, outputs: usize, f: &dyn Fn(&[Var]) -> Vec<Var>) {
    let mut rng = Rng::new(7);
    let x: Vec<Vec<f64>> = (0..inputs)
        .map(|_| (0..ROWS).map(|_| rng.uniform_in(0.3, 1.5)).collect())
        .collect();
    let p: Vec<f64> = (0..params).map(|_| rng.uniform_in(-0.8, 0.8)).collect();
    let g: Vec<Vec<f64>> = (0..outputs)
        .map(|_| (0..ROWS).map(|_| rng.normal()).collect())
        .collect();
    let (_, dx, dp) = run(&x, &p, &g, f);
    let h = 1e-6;
    let scale = dx
        .iter()
        .flatten()
        .chain(&dp)
        .fold(1e-3f64, |m, v| m.max(v.abs()));
    for i in 0..inputs {
        for k in 0..ROWS {
            let at = |d: f64| {
                let mut x = x.clone();
                x[i][k] += d;
                run(&x, &p, &g, f).0
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!(
                (dx[i][k] - fd).abs() <= 1e-6 * scale,
                "∂/∂x{i}[{k}]: {} vs {fd}",
                dx[i][k]
            );
        }
    }
    for j in 0..params {
        let at = |d: f64| {
            let mut p = p.clone();
            p[j] += d;
            run(&x, &p, &g, f).0
        };
        let fd = (at(h) - at(-h)) / (2.0 * h);
        assert!(
            (dp[j] - fd).abs() <= 1e-6 * scale,
            "∂/∂θ{j}: {} vs {fd}",
            dp[j]
        );
    }
}

#[test]
fn every_elementwise_node_against_finite_differences() {
    check(2, 2, 3, &|v| {
        let (x, y) = (&v[0], &v[1]);
        let tape = x.tape.clone();
        let (a, b) = (Var::param(&tape, 0), Var::param(&tape, 1));
        let u = x.sin() * y.cos() + (x.clone() / y.clone()).exp().scale(0.3);
        let w = y.ln() * a.clone() - x.sqrt().shift(2.0) * b.sigmoid();
        let z = u.atan2(&w).tanh() + b.softplus().square() - (-x.clone()) * a.lift(0.7);
        // A value every row shares, by itself: its adjoint is every row's summed.
        vec![u * w.clone(), z, a * b]
    });
}

#[test]
fn a_network_with_input_tangents_against_finite_differences() {
    // 2 → 4 → 3 → 2, tanh between: 8 + 4 + 12 + 3 + 6 + 2 parameters.
    let layers = [(2, 4), (4, 3), (3, 2)];
    let mut at = 0;
    let layers: Vec<Layer> = (layers.iter())
        .map(|&(d_in, d_out)| {
            let l = Layer {
                d_in,
                d_out,
                w: at,
                b: at + d_in * d_out,
            };
            at += d_in * d_out + d_out;
            l
        })
        .collect();
    let count = at;
    check(2, count, 6, &move |v| {
        // Input 0 carries a per-row tangent (a row value) and a shared one (a constant);
        // input 1 only the second direction.
        let one = v[0].lift(1.5);
        let x = [
            Dual::new(v[0].clone(), [Some(v[1].square()), Some(one)]),
            Dual::new(v[1].clone(), [None, Some(v[0].clone() * v[1].clone())]),
        ];
        let out = mlp(&layers, &x, 2);
        out.into_iter()
            .flat_map(|o| {
                [
                    o.v.clone(),
                    o.tangent(0).cloned().unwrap(),
                    o.tangent(1).cloned().unwrap(),
                ]
            })
            .collect()
    });
}

/// Repeated operations are one node whose adjoint gathers every use, x · 1, x + 0 and x − 0
/// are x, and a sine and cosine of one value read each other's values in the backward pass:
/// gradients still equal central differences, with the sine's and the cosine's nodes used
/// several times and in either order.
#[test]
fn nodes_recorded_once_against_finite_differences() {
    check(2, 1, 2, &|v| {
        let (x, y) = (&v[0], &v[1]);
        let a = Var::param(&x.tape, 0);
        let (one, zero) = (x.lift(1.0), x.lift(0.0));
        let s = x.sin() * x.cos() + x.cos().square() * (x.clone() * y.clone());
        let t = (y.clone() * x.clone()) * one.clone() + zero.clone() - x.sin() * a.clone();
        vec![
            s * y.cos() + y.sin(),
            (t - zero) * one + (a.clone() * a).scale(1.0),
        ]
    });
}

#[test]
fn a_repeated_operation_is_one_node() {
    let tape = Tape::new(3, Params::new(vec![], Precision::F64), Default::default());
    let x = Var::input(&tape, vec![0.1, 0.2, 0.3]);
    let y = Var::input(&tape, vec![1.0, 2.0, 3.0]);
    let before = tape.borrow().nodes.len();
    let (a, b) = (x.clone() * y.clone(), y.clone() * x.clone());
    let (c, d) = (x.cos(), x.cos());
    assert_eq!((a.id(), c.id()), (b.id(), d.id()));
    assert_eq!((x.clone() * x.lift(1.0)).id(), x.id());
    assert_eq!(
        tape.borrow().nodes.len(),
        before + 3,
        "x·y, cos x and the constant 1"
    );
    // The same operation on other values is a node of its own.
    assert_ne!((x.clone() - y.clone()).id(), (y - x).id());
}

/// A parameter that no output reads is unreached, whatever else depends on it; a network's
/// weights are reached through its output.
#[test]
fn reaches_names_the_parameters_the_outputs_depend_on() {
    let tape = Tape::new(
        2,
        Params::new(vec![0.5; 5], Precision::F64),
        Default::default(),
    );
    let x = Var::input(&tape, vec![0.1, 0.2]);
    let (p0, p1, p2) = (
        Var::param(&tape, 0),
        Var::param(&tape, 1),
        Var::param(&tape, 2),
    );
    let used = x.clone() * p0;
    let dead = (x.clone() * p1).sin();
    let layer = Layer {
        d_in: 1,
        d_out: 1,
        w: 3,
        b: 4,
    };
    let net = mlp(&[layer], &[Dual::constant(x.clone())], 0);
    let out = [used.id(), net[0].v.id()];
    drop((x, dead, p2, used, net));
    let t = Tape::finish(tape);
    assert_eq!(t.reaches(&out), [true, false, false, true, true]);
}
