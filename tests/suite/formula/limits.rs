//! No expression takes the process down: nesting and size are refused past their limits
//! naming them, long sums are legitimate, and what is accepted evaluates exactly as the
//! recursive evaluator graybox had before (`recursive.rs`, run on a 1 GiB stack).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use graybox::infer::Evaluator;
use graybox::model::spec::ModelSpec;
use graybox::physics::formula::{MAX_DEPTH, MAX_NODES, Names, Symbol, parse};
use graybox::physics::formula_template::FormulaTemplate;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{TrainConfig, Trainer};
use serde_json::json;

use super::recursive;

/// Runs `f` on a thread with `stack` bytes of stack: a small one shows that nothing recurses
/// on the input; a huge one lets the recursive reference finish.
fn on_stack<T: Send + 'static>(stack: usize, f: impl FnOnce() -> T + Send + 'static) -> T {
    std::thread::Builder::new()
        .stack_size(stack)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap()
}

const SMALL: usize = 256 << 10;
/// Tokio's and the test harness's threads: what a request or a job runs on.
const THREAD: usize = 2 << 20;

fn names() -> Names {
    Names {
        coordinates: vec!["x".into(), "theta".into()],
        inputs: vec!["f".into()],
        parameters: vec!["mp".into(), "l".into(), "g".into()],
    }
}

fn ref_names() -> recursive::Names {
    recursive::Names {
        coordinates: vec!["x".into(), "theta".into()],
        inputs: vec!["f".into()],
        parameters: vec!["mp".into(), "l".into(), "g".into()],
    }
}

fn value(s: Symbol) -> f64 {
    match s {
        Symbol::Q(i) => [0.3, -1.2][i],
        Symbol::QDot(i) => [0.7, 2.5][i],
        Symbol::U(_) => 4.0,
        Symbol::Param(i) => [0.5, 0.6, 9.81][i],
    }
}

fn ref_value(s: recursive::Symbol) -> f64 {
    use recursive::Symbol as R;
    value(match s {
        R::Q(i) => Symbol::Q(i),
        R::QDot(i) => Symbol::QDot(i),
        R::U(i) => Symbol::U(i),
        R::Param(i) => Symbol::Param(i),
    })
}

/// A random valid expression: leaves, unary minus, parentheses, calls, binary operators and
/// long flat sums, with nesting up to `depth` levels (the generator's own recursion is bounded
/// by `depth`, which the test picks).
fn random_expr(rng: &mut Rng, depth: usize, out: &mut String) {
    let leaf = |rng: &mut Rng, out: &mut String| {
        let pick = [
            "x",
            "theta",
            "x_dot",
            "theta_dot",
            "f",
            "mp",
            "l",
            "g",
            "pi",
        ];
        if rng.uniform() < 0.4 {
            out.push_str(&format!("{:.3}", rng.uniform_in(0.1, 3.0)));
        } else {
            out.push_str(pick[(rng.uniform() * pick.len() as f64) as usize % pick.len()]);
        }
    };
    if depth == 0 {
        return leaf(rng, out);
    }
    let r = rng.uniform();
    if r < 0.15 {
        leaf(rng, out);
    } else if r < 0.25 {
        out.push('-');
        random_expr(rng, depth - 1, out);
    } else if r < 0.4 {
        out.push('(');
        random_expr(rng, depth - 1, out);
        out.push(')');
    } else if r < 0.55 {
        let f = ["sin", "cos", "tanh", "sqrt", "log", "exp", "atan2"];
        let f = f[(rng.uniform() * f.len() as f64) as usize % f.len()];
        out.push_str(f);
        out.push('(');
        random_expr(rng, depth - 1, out);
        if f == "atan2" {
            out.push_str(", ");
            random_expr(rng, depth / 4, out);
        }
        out.push(')');
    } else if r < 0.85 {
        random_expr(rng, depth - 1, out);
        let ops = [" + ", " - ", "*", "/", "^"];
        let op = ops[(rng.uniform() * ops.len() as f64) as usize % ops.len()];
        out.push_str(op);
        if op == "^" && rng.uniform() < 0.6 {
            out.push_str(&format!("{}", (rng.uniform() * 9.0) as i32 - 4));
        } else {
            random_expr(rng, depth / 4, out);
        }
    } else {
        // A long flat sum of small terms: length is not depth.
        let terms = 1 + (rng.uniform() * 4000.0) as usize;
        for k in 0..terms {
            if k > 0 {
                out.push_str(if k % 3 == 0 { " - " } else { " + " });
            }
            random_expr(rng, 0, out);
        }
    }
}

/// Random deep and long expressions either are refused naming a limit or evaluate to the
/// same bits as the recursive evaluator; both outcomes occur.
#[test]
fn random_expressions_refuse_or_match_the_recursive_evaluator() {
    let (mut accepted, mut refused) = (0, 0);
    for case in 0..160 {
        let mut g = Rng::new(case);
        let t = on_stack(1 << 30, move || {
            let mut text = String::new();
            let depth = (g.uniform() * 40.0) as usize;
            random_expr(&mut g, depth, &mut text);
            // A fifth of the cases inside a spine nested past MAX_DEPTH.
            if case % 5 == 0 {
                let levels = MAX_DEPTH + 1 + (g.uniform() * 100.0) as usize;
                let spine: Vec<(&str, &str)> = (0..levels)
                    .map(|_| [("(", ")"), ("sin(", ")"), ("-", ""), ("2^", "")][g.below(4)])
                    .collect();
                let open: String = spine.iter().map(|s| s.0).collect();
                let close: String = spine.iter().rev().map(|s| s.1).collect();
                text = format!("{open}{text}{close}");
            }
            text
        });
        let theirs = {
            let t = t.clone();
            on_stack(1 << 30, move || {
                let e = recursive::parse(&t, &ref_names()).unwrap_or_else(|e| panic!("{e}"));
                e.eval(&ref_value)
            })
        };
        let t2 = t.clone();
        let ours = on_stack(SMALL, move || {
            parse(&t2, &names()).map(|e| e.eval(&value, &0.0))
        });
        match ours {
            Ok(v) => {
                accepted += 1;
                assert!(
                    v.to_bits() == theirs.to_bits() || (v.is_nan() && theirs.is_nan()),
                    "case {case}: {v} vs {theirs} for {}…",
                    &t[..t.len().min(200)]
                );
            }
            Err(e) => {
                refused += 1;
                assert!(e.message.contains("that is the limit"), "case {case}: {e}");
            }
        }
    }
    assert!(
        accepted >= 100 && refused >= 20,
        "{accepted} accepted, {refused} refused"
    );
}

#[test]
fn deep_nesting_is_refused_at_the_limit_without_recursing() {
    let n = 2000;
    let cases = [
        format!("{}x{}", "(".repeat(n), ")".repeat(n)),
        format!("{}x{}", "sin(".repeat(n), ")".repeat(n)),
        format!("{}x", "-".repeat(n)),
        format!("{}2", "x^".repeat(n)),
        format!("{}x", "-(".repeat(n)),
    ];
    for text in cases {
        let head = text[..12].to_string();
        let err = on_stack(SMALL, move || parse(&text, &names()).unwrap_err());
        assert!(
            err.message
                .contains(&format!("more than {MAX_DEPTH} levels")),
            "{head}…: {err}"
        );
        // The error points inside the text, at the level past the limit.
        assert!(err.offset > 0 && err.offset < 4 * n, "{head}…: {err}");
    }
    // Just within the limit: accepted, and the same value as without the parentheses.
    let ok = format!(
        "{}x{}",
        "(".repeat(MAX_DEPTH - 1),
        ")".repeat(MAX_DEPTH - 1)
    );
    let v = on_stack(SMALL, move || {
        parse(&ok, &names()).unwrap().eval(&value, &0.0)
    });
    assert_eq!(v, 0.3);
}

/// The sum Σ_k c_k x in the order the text writes it.
fn flat_sum(terms: usize) -> (String, f64) {
    let mut text = String::new();
    let mut want = 0.0f64;
    for k in 0..terms {
        let c = (k % 7) as f64 + 0.5;
        if k > 0 {
            text.push_str(" + ");
        }
        text.push_str(&format!("{c}*x"));
        want = if k == 0 { c * 0.3 } else { want + c * 0.3 };
    }
    (text, want)
}

#[test]
fn long_sums_are_legitimate_and_the_node_budget_bounds_them() {
    let (text, want) = flat_sum(10_000);
    let got = on_stack(SMALL, move || {
        parse(&text, &names()).unwrap().eval(&value, &0.0)
    });
    assert_eq!(got, want);
    // 3 nodes a term (c, x, ·) and one + between terms: past MAX_NODES.
    let (text, _) = flat_sum(MAX_NODES / 4 + 10);
    let err = on_stack(SMALL, move || parse(&text, &names()).unwrap_err());
    assert!(
        err.message.contains(&format!("more than {MAX_NODES}")),
        "{err}"
    );

    // The budget is the document's: two expressions (4 nodes a term) under it alone, over it
    // together.
    let (half, _) = flat_sum(MAX_NODES / 8 + 100);
    let doc = json!({
        "kind": "formula", "name": "long", "coordinates": ["x"], "inputs": ["u"],
        "mass": [["1"]], "potential": half, "forces": [format!("u + {half}")],
    });
    let Err(err) = FormulaTemplate::parse(&doc.to_string()) else {
        panic!("a document over the node budget was accepted");
    };
    let err = err.to_string();
    assert!(
        err.contains("forces[0]") && err.contains("more than"),
        "{err}"
    );
    // The error quotes a window of the expression, not all of it.
    assert!(err.len() < 1000, "{} bytes", err.len());
}

/// A pendulum whose potential is a flat sum of `terms` equal parts of −m g l cos θ.
fn long_pendulum(terms: usize) -> Template {
    let part = format!("{}*m*g*l*cos(theta)", 1.0 / terms as f64);
    let potential = vec![format!("-{part}"); terms].join(" ");
    let doc = json!({
        "kind": "formula", "name": "long", "coordinates": ["theta"], "periodic": [true],
        "inputs": ["u"],
        "parameters": {"m": {"value": 1.0, "positive": true}, "l": {"value": 1.0, "positive": true},
                       "g": {"value": 9.81, "positive": true}, "b": {"value": 0.1}},
        "mass": [["m*l^2"]], "potential": potential, "forces": ["u - b*theta_dot"],
    });
    Template::Formula(Arc::new(FormulaTemplate::parse(&doc.to_string()).unwrap()))
}

/// A 3000-term potential trains (W-B, Burn's autodiff over every term), and its model
/// predicts and linearizes, on a thread with the stack a request or a job gets. Slow (tens of
/// seconds): the autodiff records an op per term at every step, and a shorter
/// formula would not show that nothing recurses per term.
#[test]
fn a_long_potential_trains_predicts_and_linearizes_on_a_normal_stack() {
    on_stack(THREAD, || {
        let t = long_pendulum(3000);
        let data = simulate(
            &t,
            t.defaults(),
            &SimConfig {
                count: 32,
                seed: 3,
                ..SimConfig::default()
            },
        )
        .unwrap();
        let cfg = TrainConfig {
            epochs: 2,
            batch_size: 16,
            val_fraction: 0.25,
            ..TrainConfig::default()
        };
        let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
        let device = super::flex();
        let mut tr = Trainer::new("W-B", spec, &[], &data, None, cfg, &device).unwrap();
        tr.run(&AtomicBool::new(false), |_, _| {}).unwrap();
        let file = tr.model_file();
        let e = Evaluator::from_file(&file).unwrap();
        let (x, u) = ([0.4, -0.3], [0.5]);
        let (next, _) = e.predict(&x, &u, false);
        assert!(next.iter().all(|v| v.is_finite()), "{next:?}");
        let (a, b) = e.linearize_batch(&x, &u);
        // ∂/∂u of the next state against a central difference (h = 1e-5; the one-step map
        // is smooth, so the error is ~h² ≈ 1e-10 plus rounding ~1e-16/h).
        let h = 1e-5;
        let (p, _) = e.predict(&x, &[u[0] + h], false);
        let (m, _) = e.predict(&x, &[u[0] - h], false);
        for i in 0..2 {
            let fd = (p[i] - m[i]) / (2.0 * h);
            assert!(
                (b[i] - fd).abs() < 1e-6 * fd.abs().max(1.0),
                "B[{i}]: {} vs {fd}",
                b[i]
            );
        }
        assert!(a.iter().all(|v| v.is_finite()), "{a:?}");
    });
}
