//! A batch's states answer as each does alone, to the bit, whichever way the evaluator runs
//! them: 81 states are a unit of 64 in one wide pack, then a unit of 17 in a narrow pack of 16
//! and one state alone (`infer::pack`), on the recorded models whose structure runs in packs
//! (a Lagrangian MVF, white-box models from built-in and formula templates, an ensemble).

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
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let x: Vec<f64> = (0..batch * nx).map(|i| (0.37 * i as f64).sin()).collect();
        let u: Vec<f64> = (0..batch * m).map(|i| (0.91 * i as f64).cos()).collect();
        let (next, acc) = eval.predict(&x, &u, true);
        let acc = acc.unwrap();
        let n = nx / 2;
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

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|v| v.to_bits()).collect()
}
