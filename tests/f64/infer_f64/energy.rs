//! Energy and power of the f64 evaluator (`infer::energy`, docs/energy.md): the white-box
//! double pendulum's energy balance along a forced rollout, and the energy report's drift and
//! passivity on models whose answers are known.

use graybox::infer::Evaluator;
use graybox::infer::energy_report::REPORT_SEED;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;

/// The white-box double pendulum at its defaults but for `changes`.
fn double_pendulum(dt: f64, changes: &[(&str, f64)]) -> Evaluator {
    let t = Template::DoublePendulum;
    let mut values = t.defaults();
    for (name, v) in changes {
        values[t.index_of(name).expect("a parameter")] = *v;
    }
    let file = ModelFile::from_template(&t, &values, dt, Integrator::Rk4).expect("a model");
    Evaluator::from_file(&file).expect("an evaluator")
}

/// E(t) − E(0) and the work W(t) = ∫ q̇ᵀF dt along the model's rollout of `seconds` under
/// inputs held for 0.1 s each, W integrated by the same RK4 as the state (the state
/// augmented with W).
fn balance(eval: &Evaluator, dt: f64, seconds: f64) -> (f64, f64) {
    let steps = (seconds / dt).round() as usize;
    let hold = (0.1 / dt).round() as usize;
    let mut rng = Rng::new(54);
    let inputs: Vec<Vec<f64>> = (0..steps.div_ceil(hold))
        .map(|_| vec![20.0 * rng.normal(), 20.0 * rng.normal()])
        .collect();
    let energy = |x: &[f64], u: &[f64]| {
        let e = eval.energy_until(x, u, &|| false).unwrap().unwrap();
        (e.total[0], e.power[0])
    };
    // ẋ = [q̇, q̈, q̇ᵀF] at a state with W appended.
    let f = |x: &[f64], u: &[f64]| -> Vec<f64> {
        let (_, acc) = eval.predict(&x[..4], u, true);
        let mut dx = x[2..4].to_vec();
        dx.extend(acc.unwrap());
        dx.push(energy(&x[..4], u).1);
        dx
    };
    let stage = |x: &[f64], k: &[f64], h: f64| -> Vec<f64> {
        x.iter().zip(k).map(|(x, k)| x + h * k).collect()
    };
    let mut x = vec![0.4, -0.8, 1.0, -2.0, 0.0];
    let e0 = energy(&x[..4], &[0.0, 0.0]).0;
    for t in 0..steps {
        let u = &inputs[t / hold];
        let own = eval.predict(&x[..4], u, false).0;
        let k1 = f(&x, u);
        let k2 = f(&stage(&x, &k1, dt / 2.0), u);
        let k3 = f(&stage(&x, &k2, dt / 2.0), u);
        let k4 = f(&stage(&x, &k3, dt), u);
        for i in 0..5 {
            x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        // The state part is the model's own step: E is read along its own rollout.
        let apart = own
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(apart < 1e-9, "step {t}: {own:?} vs {x:?}");
    }
    (energy(&x[..4], &[0.0, 0.0]).0 - e0, x[4])
}

#[test]
fn energy_changes_by_the_work_of_the_forces_to_the_integrators_order() {
    let (mut gaps, mut scale) = (vec![], 0.0);
    for dt in [0.01, 0.001] {
        let eval = double_pendulum(dt, &[]);
        let (de, work) = balance(&eval, dt, 2.0);
        println!(
            "dt {dt}: E(2 s) − E(0) = {de:.6}, ∫ q̇ᵀF dt = {work:.6}, gap {:.3e}",
            de - work
        );
        gaps.push((de - work).abs());
        // The forces do real work here: the balance is not 0 = 0.
        assert!(work.abs() > 10.0, "{work}");
        scale = work.abs();
    }
    // RK4's global error is O(Δt⁴): 10× smaller steps shrink the gap ~10⁴× (measured: 8e-4
    // J of 54 J at Δt = 0.01, 2e-8 J at 0.001); 10³× leaves room for rounding at Δt = 0.001,
    // while a missing or mis-signed term leaves a gap of the work's order.
    assert!(gaps[0] < 1e-4 * scale, "{gaps:?}");
    assert!(gaps[1] < gaps[0] / 1e3, "{gaps:?}");
}

/// States like the paper's data: q over a turn, q̇ within ±10.
fn data_states(count: usize) -> Vec<f64> {
    let mut rng = Rng::new(7);
    (0..count)
        .flat_map(|_| {
            let q = [rng.uniform_in(-3.0, 3.0), rng.uniform_in(-3.0, 3.0)];
            let qd = [rng.uniform_in(-10.0, 10.0), rng.uniform_in(-10.0, 10.0)];
            [q[0], q[1], qd[0], qd[1]]
        })
        .collect()
}

#[test]
fn the_report_separates_integrator_drift_from_damping_and_injection() {
    let states = data_states(500);
    let report = |eval: &Evaluator| {
        let r = eval.energy_report(&states, REPORT_SEED, &|| false);
        r.unwrap().unwrap()
    };
    // Damped: the rollouts run without the damping the spec names, so E is RK4's to keep.
    let damped = report(&double_pendulum(0.01, &[]));
    assert_eq!(damped.switched_off, ["damping"]);
    assert_eq!((damped.rollouts, damped.passivity.states), (64, 500));
    let [at100, at1000] = &damped.drift[..] else {
        panic!("{:?}", damped.drift)
    };
    assert!(
        at100.median.unwrap() < 1e-4 && at1000.median.unwrap() < 1e-2,
        "{damped:?}"
    );
    // RK4's energy error grows with the steps.
    assert!(at1000.median.unwrap() > at100.median.unwrap(), "{damped:?}");
    // η < 0 only ever takes energy out.
    assert_eq!(damped.passivity.injecting, 0, "{damped:?}");
    assert!(
        damped.summary.starts_with("never creates energy"),
        "{}",
        damped.summary
    );

    // η₁ > 0 pumps energy in wherever q̇₁ ≠ 0 (every sampled state), by η₁ q̇₁² (+ η₂ q̇₂²).
    let pumping = report(&double_pendulum(0.01, &[("eta1", 2.0), ("eta2", 0.0)]));
    assert_eq!(pumping.passivity.injecting, 500, "{pumping:?}");
    let most = (states.chunks(4))
        .map(|x| 2.0 * x[2] * x[2])
        .fold(0.0, f64::max);
    assert!(
        (pumping.passivity.max_power - most).abs() < 1e-9 * most,
        "{pumping:?}"
    );
    assert!(
        pumping
            .summary
            .starts_with("creates energy in 100 % of states"),
        "{}",
        pumping.summary
    );
    // Switched off in the rollouts, the same damping leaves the same drift: it is the
    // conservative rest that is measured.
    assert_eq!(pumping.drift, damped.drift);
}

#[test]
fn a_passive_force_never_injects_energy_whatever_its_weights() {
    let dev = super::f64_device();
    let spec = r#"{"mass": "mlp", "potential": "mlp", "forces": "passive"}"#;
    let spec = ModelSpec::parse(spec, None).unwrap();
    // Random, perturbed weights: nothing trained them to be passive.
    let (_, eval) = super::build(spec, 2, 2, vec![], &dev);
    let states = data_states(500);
    let report = eval
        .energy_report(&states, REPORT_SEED, &|| false)
        .unwrap()
        .unwrap();
    assert_eq!(report.switched_off, ["damping"]);
    assert_eq!(report.passivity.injecting, 0, "{report:?}");
    // Its damping does work at every moving state: q̇ᵀF(q, q̇, 0) = −q̇ᵀD q̇ < 0.
    let idle = vec![0.0; 2 * 500];
    let e = eval
        .energy_until(&states, &idle, &|| false)
        .unwrap()
        .unwrap();
    assert!(e.power.iter().all(|p| *p < 0.0), "{:?}", e.power);
    let damping = &e.parts[1];
    assert_eq!((damping.name, damping.dissipation), ("damping", true));
}
