//! The fused step (`Model::fused`) against Burn's op-by-op path on the same parameters: the
//! one-step loss and every parameter tensor's gradient, for structured models of every
//! component kind, residual networks on a template's V and F, a periodic model, the naive network, n = 2, 3 and 6, and each integrator.

use burn::module::Module;
use burn::tensor::{Device, Tensor};

use super::{GradCollector, f64_device};
use crate::common::{config, perturb, tensor};
use graybox::model::Model;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;

/// The one-step loss on 17 random rows (more than one tape block would hold is not needed:
/// blocks are independent) and each parameter tensor's gradient.
fn loss_and_gradients(model: &Model, dev: &Device) -> (f64, Vec<Vec<f64>>) {
    let (n, m) = (model.config.n, model.config.m);
    let mut r = Rng::new(8);
    let mut draw = |w: usize, s: f64| -> Vec<Vec<f64>> {
        (0..17)
            .map(|_| (0..w).map(|_| r.uniform_in(-s, s)).collect())
            .collect()
    };
    let (x, u, y) = (draw(2 * n, 2.0), draw(m, 5.0), draw(2 * n, 2.0));
    let loss: Tensor<1> = model.loss_sum(tensor(&x, dev), tensor(&u, dev), tensor(&y, dev));
    let value = loss.clone().into_data().iter::<f64>().next().unwrap();
    let grads = loss.backward();
    let mut gc = GradCollector {
        grads: &grads,
        out: vec![],
    };
    model.params.visit(&mut gc);
    (value, gc.out)
}

/// ‖a − b‖ / ‖b‖ (0 when both are zero).
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    let d = norm(&mut a.iter().zip(b).map(|(x, y)| x - y));
    let s = norm(&mut b.iter().copied());
    if s == 0.0 { d } else { d / s }
}

/// Both paths compute the same f64 mechanics in other orders (the tape sums a layer's
/// products row by row, Burn by matrix products): rounding separates them by ~1e-15
/// relative; a wrong rule anywhere moves a gradient by its own size.
#[test]
fn the_fused_step_has_burns_loss_and_gradients() {
    let dev = f64_device().autodiff();
    let dp = Some(Template::DoublePendulum);
    let custom = r#"{"kind":"structured","mass":{"type":"constant"},"potential":{"type":"quadratic"},"forces":{"type":"constant_affine"}}"#;
    let residual = r#"{"mass": "template",
        "potential": {"type": "template", "residual": {"type": "mlp", "hidden": [16, 16]}},
        "forces": {"type": "template", "residual": "mlp"}}"#;
    let cases: Vec<(&str, ModelSpec, usize, usize, Integrator, bool)> = vec![
        (
            "MVF",
            ModelSpec::named("MVF", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MVF n=3",
            ModelSpec::named("MVF", None).unwrap(),
            3,
            1,
            Integrator::Midpoint,
            false,
        ),
        (
            "MVF n=6",
            ModelSpec::named("MVF", None).unwrap(),
            6,
            2,
            Integrator::Euler,
            false,
        ),
        (
            "MVB",
            ModelSpec::named("MVB", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MV",
            ModelSpec::named("MV", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "W-B",
            ModelSpec::named("W-B", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "constant",
            serde_json::from_str(custom).unwrap(),
            3,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "residuals",
            ModelSpec::parse(residual, dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MVF periodic",
            ModelSpec::named("MVF", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            true,
        ),
        (
            "naive",
            ModelSpec::named("naive", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
    ];
    for (what, spec, n, m, integrator, periodic) in cases {
        let mut c = config(spec, n, m);
        c.integrator = integrator;
        if periodic {
            c.periodic = (0..n).map(|k| k == 0).collect();
        }
        let burn = perturb(&Model::init(c, None, 5, &dev).unwrap(), &dev);
        let fused = burn.clone().fused();
        let (v_ref, g_ref) = loss_and_gradients(&burn, &dev);
        let (v, g) = loss_and_gradients(&fused, &dev);
        assert!(
            (v - v_ref).abs() <= 1e-12 * v_ref.abs(),
            "{what}: loss {v} vs {v_ref}"
        );
        for (i, (a, b)) in g.iter().zip(&g_ref).enumerate() {
            let e = relative(a, b);
            assert!(e <= 1e-12, "{what}: tensor {i}: gradient error {e:e}");
        }
        eprintln!("{what}: loss {v:e} matches");
    }
}
