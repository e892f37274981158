//! A caller-owned workspace (`infer::Workspace`): once made for a model and its largest
//! batch, Predict (with and without q̈), Linearize and Rollout into the caller's buffers take
//! nothing from the system allocator, at 1, 8, 32, 81 and 256 states, on the six recorded models
//! (a Lagrangian MVF, white-box models from built-in and formula templates, a URDF robot on
//! the multibody algorithms with a residual network, an older file's MVF and an ensemble of
//! three). This binary installs its own counting allocator (`counting`).

use graybox_core::infer::{Evaluator, Workspace};

mod recorded;
use recorded::load;

mod counting;
use counting::allocations;

const MODELS: [&str; 6] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/formula-dp-wb",
    "inference/ur5-residual",
    "compat/mvf",
    "compat/wb-x3",
];

#[test]
fn calls_allocate_nothing_once_the_workspace_is_made() {
    for name in MODELS {
        let eval = load(name);
        let mut ws = Workspace::for_model(&eval, 256);
        for batch in [1, 8, 32, 81, 256] {
            calls_at(&eval, &mut ws, name, batch);
        }
    }
}

/// A workspace made on one thread and used on another, new one: the multibody algorithms'
/// scratch travels with the workspace (it used to be each thread's own, made at the thread's
/// first call), so the new thread's first calls allocate nothing either.
#[test]
fn a_workspace_brings_its_scratch_to_a_new_thread() {
    for name in MODELS {
        let eval = load(name);
        let mut ws = Workspace::for_model(&eval, 8);
        let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
        let (x, u) = (vec![0.1; 8 * nx], vec![0.2; 8 * m]);
        let (mut next, mut a, mut b) = (
            vec![0.0; 8 * nx],
            vec![0.0; 8 * ndx * ndx],
            vec![0.0; 8 * ndx * m],
        );
        let calls = std::thread::scope(|s| {
            s.spawn(|| {
                allocations(|| {
                    eval.predict_into(&mut ws, &x, &u, eval.config.dt, &mut next, None, &|| false);
                    eval.linearize_into(&mut ws, &x, &u, &mut a, &mut b, &|| false);
                })
            })
            .join()
            .unwrap()
        });
        assert_eq!(
            calls, 0,
            "{name}: a new thread's first calls allocated {calls} times"
        );
    }
}

/// Predict (with and without q̈), Linearize and a rollout from each of `batch` states.
fn calls_at(eval: &Evaluator, ws: &mut Workspace, name: &str, batch: usize) {
    let (n, m) = (eval.config.nv(), eval.config.m);
    let (nx, ndx) = (eval.config.nx(), eval.config.ndx());
    let x: Vec<f64> = (0..batch * nx)
        .map(|i| 0.1 + 0.05 * (i % 7) as f64)
        .collect();
    let u: Vec<f64> = (0..batch * m).map(|i| 0.2 - 0.1 * (i % 3) as f64).collect();
    let steps = 5;
    let us = vec![0.1; steps * m];
    let (mut next, mut acc) = (vec![0.0; batch * nx], vec![0.0; batch * n]);
    let (mut a, mut b) = (vec![0.0; batch * ndx * ndx], vec![0.0; batch * ndx * m]);
    let mut xs = vec![0.0; (steps + 1) * nx];
    let never = &|| false;
    let dt = eval.config.dt;
    let calls = allocations(|| {
        for _ in 0..2 {
            eval.predict_into(ws, &x, &u, dt, &mut next, Some(&mut acc), never);
            eval.predict_into(ws, &x, &u, dt, &mut next, None, never);
            eval.linearize_into(ws, &x, &u, &mut a, &mut b, never);
            eval.rollout_into(ws, &x[..nx], &us, dt, &mut xs, never);
        }
    });
    assert_eq!(calls, 0, "{name}, {batch} states: {calls} allocations");

    // The count sees the evaluator's allocations: the same calls through the Vec entry
    // points allocate their answers (so zero above is the workspace's doing), and give the
    // same numbers bit for bit.
    let mut answers = None;
    let vec_calls =
        allocations(|| answers = Some((eval.predict(&x, &u, true), eval.linearize_batch(&x, &u))));
    assert!(vec_calls > 0, "{name}: the allocator counted nothing");
    let ((want_next, want_acc), (want_a, want_b)) = answers.unwrap();
    assert_eq!(bits(&next), bits(&want_next), "{name}, {batch}: x'");
    assert_eq!(bits(&acc), bits(&want_acc.unwrap()), "{name}, {batch}: q̈");
    assert_eq!(bits(&a), bits(&want_a), "{name}, {batch}: A");
    assert_eq!(bits(&b), bits(&want_b), "{name}, {batch}: B");
    let mut x_t = x[..nx].to_vec();
    for t in 0..steps {
        x_t = eval.predict(&x_t, &us[t * m..(t + 1) * m], false).0;
        assert_eq!(
            bits(&xs[(t + 1) * nx..(t + 2) * nx]),
            bits(&x_t),
            "{name}: x_{t}"
        );
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|v| v.to_bits()).collect()
}
