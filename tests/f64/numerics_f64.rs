//! Numerical checks in f64 against independent references (docs/dynamics.md#forward-mode-input-derivatives). Burn fixes the float
//! type per process, so every test in this binary runs in f64.

use crate::common;
#[path = "numerics_f64/fused.rs"]
mod fused;
#[path = "numerics_f64/multibody.rs"]
mod multibody;

use burn::module::Module;
use burn::tensor::{Device, Tensor};
use common::*;
use graybox::arena::Arena;
use graybox::backend::{Backend, Precision, device};
use graybox::infer::Evaluator;
use graybox::model::Model;
use graybox::model::file::ModelFile;
use graybox::model::params_io::import;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::TemplateSystem;
use graybox::sim::{SimConfig, simulate, true_step};
use graybox::train::{TrainConfig, Trainer};

fn f64_device() -> Device {
    device(Backend::Flex, Precision::F64).expect("f64 device")
}

/// Central difference step for O(1)–O(100) smooth functions in f64: truncation ~h²·f‴ ≈ 1e-10,
/// rounding ~ε·|f|/h ≈ 1e-9 at |f| = 100; both far below the 1e-7 bound.
const H: f64 = 1e-5;

/// The inference core's f64 evaluator of `model`: the assembly training records on its tape,
/// on f64 with L's q-derivatives in forward mode.
fn evaluator(model: &Model) -> Evaluator {
    let file = ModelFile::new(model.config.clone(), model.params.export(), None);
    Evaluator::from_file(&file).unwrap()
}

/// ∂V/∂q of every potential form, and ∂L/∂q of every mass form (the networks' input
/// derivatives through the standardization and the softplus diagonal among them), vs
/// central differences of V and L.
#[test]
fn model_input_jacobians_match_finite_differences() {
    let dev = f64_device();
    let cases: Vec<(ModelSpec, usize, usize)> = vec![
        (ModelSpec::named("MVF", None).unwrap(), 2, 2),
        (ModelSpec::named("MVF", None).unwrap(), 3, 1),
        (ModelSpec::named("W-B", Some(Template::DoublePendulum)).unwrap(), 2, 2),
        (ModelSpec::named("W-B", Some(Template::Cartpole)).unwrap(), 2, 1),
        (
            serde_json::from_str(r#"{"kind":"structured","mass":{"type":"constant"},"potential":{"type":"quadratic"},"forces":{"type":"constant_affine"}}"#).unwrap(),
            3,
            2,
        ),
    ];
    for (spec, n, m) in cases {
        let model = Model::init(config(spec.clone(), n, m), None, 5, &dev).unwrap();
        let eval = evaluator(&perturb(&model, &dev));
        let (q, qd, u) = paper_samples(n, m, 5, 3);
        let arena = Arena::new();
        for b in 0..q.len() {
            let terms =
                |q: &[f64]| (eval.terms(&arena, q, &qd[b], &u[b])).expect("a structured model");
            let v = |q: &[f64]| {
                let x = [q, &qd[b]].concat();
                let e = eval.energy_until(&x, &u[b], &|| false).unwrap();
                e.expect("never stopped").potential[0]
            };
            let t = terms(&q[b]);
            for k in 0..n {
                let at = |h: f64| {
                    let mut q = q[b].clone();
                    q[k] += h;
                    q
                };
                let fd = (v(&at(H)) - v(&at(-H))) / (2.0 * H);
                let ad = t.grad_v.as_ref().map_or(0.0, |g| g[k]);
                assert!(
                    rel_err(&[ad], &[fd]) < 1e-7,
                    "{spec:?} ∂V/∂q{k}: {ad} vs {fd}"
                );
                let (lp, lm) = (terms(&at(H)), terms(&at(-H)));
                let (l, dl) = (&t.factor.l, &t.factor.dl[k]);
                for e in 0..l.entries.len() {
                    let fd = (lp.factor.l.entries[e] - lm.factor.l.entries[e]) / (2.0 * H);
                    let ad = dl.entries[e].unwrap_or(0.0);
                    assert!(
                        rel_err(&[ad], &[fd]) < 1e-7,
                        "{spec:?} ∂L{e}/∂q{k}: {ad} vs {fd}"
                    );
                }
            }
        }
    }
}

/// The W-B double pendulum's q̈ (the inference core's and the true system's) equals the
/// paper's equations written out independently, and its training step's x′ (the tape's)
/// equals RK4 on them. 1e-9: a handful of f64 operations on O(100) quantities.
#[test]
fn double_pendulum_matches_closed_form() {
    let dev = f64_device();
    let spec = ModelSpec::named("W-B", Some(Template::DoublePendulum)).unwrap();
    let model = Model::init(config(spec, 2, 2), Some(PAPER.to_vec()), 0, &dev).unwrap();
    assert_eq!(model.config.integrator, Integrator::Rk4);
    let (q, qd, u) = paper_samples(2, 2, 64, 42);
    let eval = evaluator(&model);
    let sys = TemplateSystem::new(Template::DoublePendulum, PAPER.to_vec());
    let x: Vec<Vec<f64>> = (0..q.len()).map(|i| [&q[i][..], &qd[i]].concat()).collect();
    let stepped = host(model.step(tensor(&x, &dev), tensor(&u, &dev)));
    for i in 0..q.len() {
        let want = double_pendulum_accel(&PAPER, &q[i], &qd[i], &u[i]);
        for (path, got) in [
            ("inference", eval.accel(&q[i], &qd[i], &u[i])),
            ("true system", sys.acceleration(&q[i], &qd[i], &u[i])),
        ] {
            assert!(rel_err(&got, &want) < 1e-9, "{path} {got:?} vs {want:?}");
        }
        let f = |x: &[f64]| {
            let a = double_pendulum_accel(&PAPER, &x[..2], &x[2..], &u[i]);
            vec![x[2], x[3], a[0], a[1]]
        };
        let dt = model.config.dt;
        let along = |k: &[f64], h: f64| -> Vec<f64> {
            x[i].iter().zip(k).map(|(x, k)| x + h * k).collect()
        };
        let k1 = f(&x[i]);
        let k2 = f(&along(&k1, dt / 2.0));
        let k3 = f(&along(&k2, dt / 2.0));
        let k4 = f(&along(&k3, dt));
        let want: Vec<f64> = (0..4)
            .map(|j| x[i][j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]))
            .collect();
        assert!(
            rel_err(&stepped[i], &want) < 1e-9,
            "step {:?} vs {want:?}",
            stepped[i]
        );
    }
}

/// The Coriolis term assembled from L and ∂L/∂q (learned M) equals the Christoffel-symbol
/// definition with ∂M/∂q from central differences of M = LLᵀ; the whole q̈ is checked.
/// FD error ~1e-9 on O(100) terms, so 1e-6.
#[test]
fn learned_mass_coriolis_matches_christoffel_definition() {
    let dev = f64_device();
    // n = 10: L's q-derivatives come in two groups of directions (`dual::groups`).
    for n in [2, 3, 10] {
        let eval = evaluator(&perturb(&model("MVF", None, n, 2, 4, &dev), &dev));
        let (q, qd, u) = paper_samples(n, 2, 4, 8);
        let arena = Arena::new();
        for b in 0..q.len() {
            let terms =
                |q: &[f64]| (eval.terms(&arena, q, &qd[b], &u[b])).expect("a structured model");
            let mass_at = |q: &[f64]| -> Vec<Vec<f64>> {
                let l = terms(q).factor.l;
                let lij = |i: usize, j: usize| {
                    if j <= i {
                        l.entries[i * (i + 1) / 2 + j]
                    } else {
                        0.0
                    }
                };
                (0..n)
                    .map(|i| {
                        (0..n)
                            .map(|j| (0..n).map(|k| lij(i, k) * lij(j, k)).sum())
                            .collect()
                    })
                    .collect()
            };
            let dm: Vec<Vec<Vec<f64>>> = (0..n)
                .map(|k| {
                    let at = |h: f64| {
                        let mut q = q[b].clone();
                        q[k] += h;
                        mass_at(&q)
                    };
                    let (p, m) = (at(H), at(-H));
                    (0..n)
                        .map(|i| (0..n).map(|j| (p[i][j] - m[i][j]) / (2.0 * H)).collect())
                        .collect()
                })
                .collect();
            let t = terms(&q[b]);
            let w = &qd[b];
            let c: Vec<f64> = (0..n)
                .map(|i| {
                    let mut s = 0.0;
                    for j in 0..n {
                        for k in 0..n {
                            s += dm[k][i][j] * w[j] * w[k] - 0.5 * dm[i][j][k] * w[j] * w[k];
                        }
                    }
                    s
                })
                .collect();
            let gv = t.grad_v.expect("MVF has a potential");
            let rhs: Vec<f64> = (0..n).map(|i| t.forces[i] - c[i] - gv[i]).collect();
            let want = gauss_solve(mass_at(&q[b]), rhs);
            let got = eval.accel(&q[b], &qd[b], &u[b]);
            assert!(rel_err(&got, &want) < 1e-6, "n={n}: {got:?} vs {want:?}");
        }
    }
}

/// Unforced, undamped systems conserve T + V; RK4's error at Δt = 1e-3 over 1 s is far below
/// the 1e-6 relative bound.
#[test]
fn energy_is_conserved_without_forces() {
    for t in [Template::DoublePendulum, Template::Cartpole] {
        let mut p = t.defaults();
        for (i, info) in t.params().iter().enumerate() {
            if info.name.starts_with('b') || info.name.starts_with("eta") {
                p[i] = 0.0;
            }
        }
        let sys = TemplateSystem::new(t.clone(), p);
        let (q, qd, _) = paper_samples(2, 1, 5, 21);
        for (q0, qd0) in q.iter().zip(&qd) {
            let (t0, v0) = sys.energy(q0, qd0);
            let scale = t0.abs() + v0.abs();
            let mut x: Vec<f64> = q0.iter().chain(qd0).copied().collect();
            let mut drift: f64 = 0.0;
            for _ in 0..1000 {
                x = true_step(&sys, &x, &vec![0.0; t.m()], 1e-3, Integrator::Rk4);
                let (tk, vk) = sys.energy(&x[..2], &x[2..]);
                drift = drift.max((tk + vk - t0 - v0).abs());
            }
            assert!(
                drift < 1e-6 * scale,
                "{}: drift {drift} vs scale {scale}",
                t.name()
            );
        }
    }
}

/// Global error at a fixed horizon shrinks by 2^p when Δt halves: ~16 (RK4), ~4 (midpoint),
/// ~2 (Euler). (One step's local error shrinks by 2^(p+1).)
#[test]
fn integrators_have_their_order() {
    let sys = TemplateSystem::new(Template::DoublePendulum, PAPER.to_vec());
    let x0 = vec![0.5, -0.3, 1.0, -2.0];
    let u = vec![5.0, -3.0];
    let horizon = 0.2;
    let run = |integ: Integrator, dt: f64| {
        let steps = (horizon / dt).round() as usize;
        (0..steps).fold(x0.clone(), |x, _| true_step(&sys, &x, &u, dt, integ))
    };
    let reference = run(Integrator::Rk4, 1e-4);
    for (integ, want, lo, hi) in [
        (Integrator::Rk4, 16.0, 13.0, 19.0),
        (Integrator::Midpoint, 4.0, 3.4, 4.6),
        (Integrator::Euler, 2.0, 1.7, 2.3),
    ] {
        let err = |dt: f64| rel_err(&run(integ, dt), &reference);
        let ratio = err(0.01) / err(0.005);
        assert!(
            (lo..hi).contains(&ratio),
            "{}: ratio {ratio}, expected ~{want}",
            integ.name()
        );
    }
}

/// ∂loss/∂θ from Burn's autodiff (through the forward-mode Jacobians, Coriolis term, solve and
/// RK4) vs central differences of the loss. Relative to the largest sampled gradient.
#[test]
fn loss_gradients_match_finite_differences() {
    let dev = f64_device().autodiff();
    for (name, template) in [("MVF", None), ("W-B", Some(Template::DoublePendulum))] {
        let ds = simulate(
            &Template::DoublePendulum,
            PAPER.to_vec(),
            &SimConfig {
                count: 8,
                seed: 1,
                ..SimConfig::default()
            },
        )
        .unwrap();
        let (x, y) = ds.states();
        let rows = |a: &[f64], w: usize| a.chunks(w).map(<[f64]>::to_vec).collect::<Vec<_>>();
        let (xt, ut, yt) = (
            tensor(&rows(&x, 4), &dev),
            tensor(&rows(&ds.u, 2), &dev),
            tensor(&rows(&y, 4), &dev),
        );
        let m0 = model(name, template.clone(), 2, 2, 7, &dev);
        let m0 = if template.is_some() {
            let p = [12.0, 8.0, 1.2, 0.9, 9.0, 1.1, 0.8, -0.4, -0.6];
            Model::init(m0.config.clone(), Some(p.to_vec()), 7, &dev).unwrap()
        } else {
            m0
        };
        let loss_of = |m: &Model| {
            m.loss_sum(xt.clone(), ut.clone(), yt.clone())
                .div_scalar(8.0)
        };
        let grads = loss_of(&m0).backward();
        let mut gc = GradCollector {
            grads: &grads,
            out: vec![],
        };
        m0.params.visit(&mut gc);
        let arrays = m0.params.export();
        let mut r = Rng::new(3);
        let mut worst: f64 = 0.0;
        let mut gmax: f64 = 0.0;
        for _ in 0..24 {
            let a = r.below(arrays.len());
            let e = r.below(arrays[a].values.len());
            let h = 1e-6 * (1.0 + arrays[a].values[e].abs());
            let eval = |delta: f64| {
                let mut arr = arrays.clone();
                arr[a].values[e] += delta;
                let p = import(m0.params.clone(), &arr, &dev).unwrap();
                let m = Model::from_parts(m0.config.clone(), p, &dev);
                loss_of(&m).into_data().iter::<f64>().next().unwrap()
            };
            let fd = (eval(h) - eval(-h)) / (2.0 * h);
            let ad = gc.out[a][e];
            worst = worst.max((fd - ad).abs());
            gmax = gmax.max(fd.abs());
        }
        assert!(gmax > 0.0);
        assert!(
            worst / gmax < 1e-6,
            "{name}: max |Δ| {worst} vs max |g| {gmax}"
        );
    }
}

/// The white-box model recovers the dynamics from 16 samples (the paper's W-B data budget) from
/// ±30% perturbed starts; raw parameters are not identifiable, their ratios are. Slow (tens of
/// seconds): 3000 epochs in f64 from each of three starts, what reaching a loss
/// below 1e-5 and the ratios within 1 % takes.
#[test]
fn white_box_recovers_dynamics_and_identifiable_ratios() {
    let dev = f64_device().autodiff();
    let t = Template::DoublePendulum;
    let truth = graybox::model::report::identifiable(
        &t,
        &ModelSpec::named("W-B", Some(t.clone()))
            .unwrap()
            .white_box_parts(),
        &t.params()
            .iter()
            .map(|p| p.name.to_string())
            .zip(PAPER)
            .collect::<Vec<_>>(),
    );
    for seed in 0..3u64 {
        let data = simulate(
            &t,
            PAPER.to_vec(),
            &SimConfig {
                count: 16,
                seed: 100 + seed,
                ..SimConfig::default()
            },
        )
        .unwrap();
        let val = simulate(
            &t,
            PAPER.to_vec(),
            &SimConfig {
                count: 1024,
                seed: 200 + seed,
                ..SimConfig::default()
            },
        )
        .unwrap();
        let mut r = Rng::new(300 + seed);
        let init: Vec<(String, f64)> = t
            .params()
            .iter()
            .zip(PAPER)
            .map(|(p, v)| (p.name.to_string(), v * r.uniform_in(0.7, 1.3)))
            .collect();
        let cfg = TrainConfig {
            epochs: 3000,
            batch_size: 16,
            lr: 1e-2,
            seed,
            ..TrainConfig::default()
        };
        let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
        let mut trainer = Trainer::new("W-B", spec, &init, &data, Some(&val), cfg, &dev).unwrap();
        trainer.run(&Default::default(), |_, _| {}).unwrap();
        let report = trainer.report();
        let best = report.best_val_loss.unwrap();
        assert!(best < 1e-5, "seed {seed}: best validation loss {best}");
        // A good run on the paper's data raises no training warning.
        assert_eq!(report.warnings, [], "seed {seed}");
        for (got, want) in report.identifiable.iter().zip(&truth) {
            assert_eq!(got.name, want.name);
            let rel = (got.value - want.value).abs() / want.value.abs();
            assert!(
                rel < 0.01,
                "seed {seed}: {} = {} vs {}",
                got.name,
                got.value,
                want.value
            );
        }
    }
}

/// A batch split into shards (train/shards.rs) has the loss and gradient of the whole batch:
/// each shard's loss is divided by the whole batch's rows and the shards' gradients summed.
/// In f64 only the summation order differs, ~1e-16 relative per addition over a few hundred
/// rows, so 1e-11 relative to the largest entry catches a wrong scale (×2 for 2 shards) or a
/// dropped or doubled shard by ten orders of magnitude.
#[test]
fn sharded_batches_have_the_whole_batch_gradient() {
    let dev = f64_device().autodiff();
    let ds = simulate(
        &Template::DoublePendulum,
        PAPER.to_vec(),
        &SimConfig {
            count: 400,
            seed: 3,
            ..SimConfig::default()
        },
    )
    .unwrap();
    // 400 rows: 2 shards of 200 and 3 of 133–134 (each at least 128 rows).
    let batch: Vec<usize> = (0..400).rev().collect();
    for name in ["MVF", "naive", "MVB"] {
        let spec = ModelSpec::named(name, Some(Template::DoublePendulum)).unwrap();
        let cfg = TrainConfig {
            val_fraction: 0.0,
            ..TrainConfig::default()
        };
        let trainer = |threads| {
            Trainer::new(name, spec.clone(), &[], &ds, None, cfg.clone(), &dev)
                .unwrap()
                .with_threads(threads)
                .unwrap()
        };
        // A parameter the loss does not depend on (V's last bias: only ∂V/∂q enters) has
        // no gradient: NaN marks it, so that a shard losing a gradient is a mismatch.
        let host = |g: Vec<Option<Tensor<1>>>| -> Vec<f64> {
            g.into_iter()
                .flat_map(|g| match g {
                    Some(g) => g.into_data().iter::<f64>().collect(),
                    None => vec![f64::NAN],
                })
                .collect()
        };
        let (whole, g1) = trainer(1).loss_and_grads(&batch);
        let g1 = host(g1);
        for threads in [2, 3] {
            let t = trainer(threads);
            assert_eq!(t.shards(), threads);
            let (loss, g) = t.loss_and_grads(&batch);
            assert!(
                (loss - whole).abs() <= 1e-12 * whole.abs(),
                "{name}, {threads} shards: loss {loss} vs {whole}"
            );
            let g = host(g);
            let missing = |g: &[f64]| g.iter().map(|v| v.is_nan()).collect::<Vec<_>>();
            assert_eq!(missing(&g), missing(&g1), "{name}, {threads} shards");
            let known = |g: &[f64]| {
                g.iter()
                    .copied()
                    .filter(|v| !v.is_nan())
                    .collect::<Vec<_>>()
            };
            assert!(
                rel_err(&known(&g), &known(&g1)) < 1e-11,
                "{name}, {threads} shards"
            );
        }
    }
}
