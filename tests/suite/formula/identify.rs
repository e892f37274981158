//! Formula templates' identifiable combinations and fixed parameters (issue 35): a damped
//! pendulum written as a formula reports the products its dynamics determine (each unchanged
//! along the scaling the dynamics cannot see), and a fixed g keeps its value through training
//! while the rest become identifiable on their own.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use graybox::model::report::identifiable;
use graybox::model::spec::ModelSpec;
use graybox::physics::formula_template::FormulaTemplate;
use graybox::physics::params::Part;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, TemplateSystem, simulate};
use graybox::train::{TrainConfig, Trainer};
use serde_json::json;

/// θ̈ m l² = τ − b θ̇ − m g l sin θ, every parameter trained unless `g_fixed`.
fn damped_pendulum(g_fixed: bool) -> Template {
    let doc = json!({
        "kind": "formula", "name": "damped", "coordinates": ["theta"], "periodic": [true],
        "inputs": ["tau"],
        "parameters": {
            "b": {"value": 0.5, "positive": true}, "g": {"value": 9.81, "positive": true, "fixed": g_fixed},
            "l": {"value": 1.0, "positive": true}, "m": {"value": 1.0, "positive": true}
        },
        "mass": [["m*l^2"]], "potential": "-m*g*l*cos(theta)", "forces": ["tau - b*theta_dot"]
    });
    Template::Formula(Arc::new(FormulaTemplate::parse(&doc.to_string()).unwrap()))
}

const ALL: [Part; 3] = [Part::Mass, Part::Potential, Part::Forces];

fn named(values: [f64; 4]) -> Vec<(String, f64)> {
    ["b", "g", "l", "m"]
        .iter()
        .map(|n| n.to_string())
        .zip(values)
        .collect()
}

#[test]
fn a_formula_pendulum_reports_the_products_its_dynamics_determine() {
    let t = damped_pendulum(false);
    let (b, g, l, m) = (0.4, 9.0, 0.7, 1.3);
    let found = identifiable(&t, &ALL, &named([b, g, l, m]));
    // Four parameters, one direction unseen: three independent combinations, the simplest
    // first (b alone; g/l, the pendulum's ω²).
    let names: Vec<&str> = found.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names.len(), 3, "{names:?}");
    assert_eq!(&names[..2], ["b", "g/l"], "{names:?}");
    assert!((found[1].value - g / l).abs() < 1e-12);
    // (g, l, m) → (c g, c l, m / c²) leaves q̈ unchanged: every reported product too, and
    // m, l or g alone, which that scaling moves, is not among them.
    for c in [0.5, 3.0] {
        let scaled = [b, c * g, c * l, m / (c * c)];
        let (a, z) = (
            TemplateSystem::new(t.clone(), vec![b, g, l, m]),
            TemplateSystem::new(t.clone(), scaled.to_vec()),
        );
        let (q, qd, u) = ([0.7], [-1.2], [0.3]);
        assert!((a.acceleration(&q, &qd, &u)[0] - z.acceleration(&q, &qd, &u)[0]).abs() < 1e-12);
        let again = identifiable(&t, &ALL, &named(scaled));
        for (x, y) in found.iter().zip(&again) {
            assert_eq!(x.name, y.name);
            assert!(
                (x.value - y.value).abs() <= 1e-9 * x.value.abs(),
                "{x:?} vs {y:?}"
            );
        }
    }
    assert!(
        names.iter().all(|n| !["g", "l", "m"].contains(n)),
        "{names:?}"
    );
    // With a network part the template's products are not the model's: none reported.
    assert!(identifiable(&t, &[Part::Mass, Part::Forces], &named([b, g, l, m])).is_empty());
}

#[test]
fn a_fixed_parameter_keeps_its_value_and_the_rest_become_identifiable() {
    let t = damped_pendulum(true);
    let truth = vec![0.3, 9.81, 0.8, 1.5]; // b, g, l, m: the document starts at b 0.5, l 1, m 1
    let sim = |seed| {
        let cfg = SimConfig {
            count: 256,
            seed,
            ..SimConfig::default()
        };
        simulate(&t, truth.clone(), &cfg).unwrap()
    };
    let (data, val) = (sim(1), sim(2));
    let cfg = TrainConfig {
        epochs: 40,
        batch_size: 64,
        lr: 3e-2,
        ..TrainConfig::default()
    };
    let device = graybox::backend::device(
        graybox::backend::Backend::Flex,
        graybox::backend::Precision::F32,
    )
    .unwrap()
    .autodiff();
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let mut tr = Trainer::new("W-B", spec, &[], &data, Some(&val), cfg, &device).unwrap();
    tr.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let r = tr.report();
    // Exactly: projected onto itself after every step (f32 training; 9.81 as an f32 logarithm).
    let g = r.physical_parameters["g"];
    assert!((g - 9.81).abs() < 1e-5, "g moved to {g}");
    for (name, start) in [("b", 0.5), ("l", 1.0), ("m", 1.0)] {
        assert!(
            (r.physical_parameters[name] - start).abs() > 1e-3,
            "{name} did not train: {r:?}"
        );
    }
    // g known, the scaling is gone: each trained parameter is identifiable alone.
    let names: Vec<&str> = r.identifiable.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["b", "l", "m"], "{:?}", r.identifiable);
    // Not warned about for staying put: it is fixed.
    assert!(
        r.warnings.iter().all(|w| !w.message.contains(" g")),
        "{:?}",
        r.warnings
    );
}

/// The paper's double pendulum as a formula (README "What the data determines"): nine
/// parameters, the mass and the length scale free, seven products, each unchanged under
/// (m, l, g, b, η) → (c_m m, c_l l, c_l g, c_m c_l² b, c_m c_l² η).
#[test]
fn the_formula_double_pendulum_reports_seven_products_invariant_under_both_scalings() {
    let t = Template::Formula(Arc::new(super::template(&super::double_pendulum())));
    let names: Vec<String> = t.params().iter().map(|p| p.name.to_string()).collect();
    let at = |c_m: f64, c_l: f64| -> Vec<(String, f64)> {
        let scale = |name: &str| match name {
            "m1" | "m2" => c_m,
            "l1" | "l2" | "g" => c_l,
            _ => c_m * c_l * c_l, // b1, b2, eta1, eta2
        };
        (names.iter().zip(t.defaults()))
            .map(|(n, v)| (n.clone(), v * scale(n)))
            .collect()
    };
    let found = identifiable(&t, &ALL, &at(1.0, 1.0));
    let got: Vec<&str> = found.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        got,
        [
            "b1/b2",
            "b1/eta1",
            "b1/eta2",
            "g/l1",
            "g/l2",
            "m1/m2",
            "b1/(g^2*m1)"
        ]
    );
    for (c_m, c_l) in [(2.0, 1.0), (1.0, 0.5), (3.0, 1.7)] {
        for (x, y) in found.iter().zip(identifiable(&t, &ALL, &at(c_m, c_l))) {
            assert_eq!(x.name, y.name);
            assert!(
                (x.value - y.value).abs() <= 1e-9 * x.value.abs(),
                "{x:?} vs {y:?}"
            );
        }
    }
}
