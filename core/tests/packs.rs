//! A batch's states answer as each does alone, to the bit, whichever way the evaluator runs
//! them: 81 states are a unit of 64 in one wide pack, then a unit of 17 in a narrow pack of 16
//! and one state alone (`infer::pack`), on the recorded models whose structure runs in packs
//! (a Lagrangian MVF, white-box models from built-in and formula templates, an ensemble).
//! Likewise their Jacobians, whose dual numbers run several states' networks in one product
//! (and the UR5's, state by state on the multibody derivatives, in a unit of several).

mod recorded;
use recorded::load;

const MODELS: [&str; 4] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/formula-dp-wb",
    "compat/wb-x3",
];

#[test]
fn a_batch_answers_as_its_states_alone() {
    let batch = 81;
    for name in MODELS {
        let eval = load(name);
        let (nx, n, m) = (eval.config.nx(), eval.config.nv(), eval.config.m);
        let x: Vec<f64> = (0..batch * nx).map(|i| (0.37 * i as f64).sin()).collect();
        let u: Vec<f64> = (0..batch * m).map(|i| (0.91 * i as f64).cos()).collect();
        let (next, acc) = eval.predict(&x, &u, true);
        let acc = acc.unwrap();
        for b in 0..batch {
            let (x1, u1) = (&x[b * nx..(b + 1) * nx], &u[b * m..(b + 1) * m]);
            let (next1, acc1) = eval.predict(x1, u1, true);
            assert_eq!(
                bits(&next[b * nx..(b + 1) * nx]),
                bits(&next1),
                "{name}: x' of {b}"
            );
            assert_eq!(
                bits(&acc[b * n..(b + 1) * n]),
                bits(&acc1.unwrap()),
                "{name}: q̈ of {b}"
            );
        }
    }
}

/// The step's A and B (Linearize) and the continuous dynamics' (collocation) of a batch of
/// 21 states (units of several, on every model and the UR5) as of each state alone.
#[test]
fn a_batch_linearizes_as_its_states_alone() {
    use graybox_core::control::dircol::Continuous;
    let batch = 21;
    for name in MODELS.iter().chain(&["inference/ur5-residual"]) {
        let eval = load(name);
        let (nx, ndx, m) = (eval.config.nx(), eval.config.ndx(), eval.config.m);
        let x: Vec<f64> = (0..batch * nx).map(|i| (0.37 * i as f64).sin()).collect();
        let u: Vec<f64> = (0..batch * m).map(|i| (0.91 * i as f64).cos()).collect();
        let (a, b) = eval.linearize_batch(&x, &u);
        let (fa, fb) = eval.derivative_jacobian(&x, &u);
        for k in 0..batch {
            let (x1, u1) = (&x[k * nx..(k + 1) * nx], &u[k * m..(k + 1) * m]);
            let (a1, b1) = eval.linearize_batch(x1, u1);
            assert_eq!(
                bits(&a[k * ndx * ndx..][..ndx * ndx]),
                bits(&a1),
                "{name}: A of {k}"
            );
            assert_eq!(
                bits(&b[k * ndx * m..][..ndx * m]),
                bits(&b1),
                "{name}: B of {k}"
            );
            let (fa1, fb1) = eval.derivative_jacobian(x1, u1);
            assert_eq!(
                bits(&fa[k].data),
                bits(&fa1[0].data),
                "{name}: ∂f/∂x of {k}"
            );
            assert_eq!(
                bits(&fb[k].data),
                bits(&fb1[0].data),
                "{name}: ∂f/∂u of {k}"
            );
        }
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|v| v.to_bits()).collect()
}
