//! The regressor (τ = Y π, `multibody::regressor`) and the base parameters
//! (`multibody::base`): Y π is RNEA's τ for any π; the base parameters reproduce every τ
//! from fewer values; a pendulum's are the ones its axis and gravity leave.

use graybox::physics::multibody::PER_BODY;
use graybox::physics::multibody::base::base_parameters;
use graybox::physics::multibody::regressor::{regressor, standard_parameters, with_parameters};
use graybox::physics::multibody::{self, inverse_dynamics};
use graybox::physics::urdf::Tree;
use graybox::rng::Rng;

use super::{err, models, random, random_state};

fn times(y: &[Vec<f64>], pi: &[f64]) -> Vec<f64> {
    y.iter()
        .map(|row| row.iter().zip(pi).map(|(a, b)| a * b).sum())
        .collect()
}

/// Y(q, q̇, q̈) π equals RNEA with the inertias of π, for the robot's own π and for random
/// ones (ten per body, not physical: linearity does not care), at random states, to 1e-9 of
/// max(1, |τ|): both are the same sums in another order (rounding ~1e-14).
#[test]
fn the_regressor_times_the_parameters_is_inverse_dynamics() {
    let mut rng = Rng::new(17);
    for (name, model) in models() {
        let own = standard_parameters(&model);
        let n = model.n;
        for s in 0..3 {
            let [q, qd, qdd] = random_state(&mut rng, n, 1.0);
            let y = regressor(&model, &q, &qd, &qdd);
            let tau = inverse_dynamics(&model, &q, &qd, &qdd);
            assert!(err(&times(&y, &own), &tau) < 1e-9, "{name} {s}: own π");
            let pi = random(&mut rng, own.len(), 1.0);
            let other = inverse_dynamics(&with_parameters(&model, &pi), &q, &qd, &qdd);
            assert!(err(&times(&y, &pi), &other) < 1e-9, "{name} {s}: random π");
        }
    }
}

/// At states the base parameters were not computed from, the regressor's independent
/// columns times β(π) give Y π for random π: the dropped parameters only ever entered through
/// the combinations. Fewer base parameters than standard ones on every robot.
#[test]
fn base_parameters_reproduce_every_torque() {
    let mut rng = Rng::new(23);
    for (name, model) in models() {
        let base = base_parameters(&model);
        let cols = PER_BODY * model.bodies.len();
        assert!(
            !base.is_empty() && base.len() < cols,
            "{name}: {}",
            base.len()
        );
        let pi = random(&mut rng, cols, 1.0);
        let beta: Vec<f64> = base.iter().map(|b| b.value(&pi)).collect();
        let n = model.n;
        for s in 0..3 {
            let [q, qd, qdd] = random_state(&mut rng, n, 1.0);
            let y = regressor(&model, &q, &qd, &qdd);
            let independent: Vec<Vec<f64>> = y
                .iter()
                .map(|row| base.iter().map(|b| row[b.lead]).collect())
                .collect();
            let want = times(&y, &pi);
            assert!(err(&times(&independent, &beta), &want) < 1e-8, "{name} {s}");
        }
    }
}

fn pendulum(axis: &str) -> multibody::Model {
    let urdf = format!(
        r#"<robot name="p"><link name="base"/>
  <joint name="j" type="revolute"><parent link="base"/><child link="rod"/>
    <axis xyz="{axis}"/></joint>
  <link name="rod"><inertial><origin xyz="0.1 0.2 0.3"/><mass value="2"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
</robot>"#
    );
    Tree::parse(&urdf, 8).unwrap().multibody([0.0, 0.0, -9.81])
}

/// One joint: about y under gravity along −z, τ = I_yy q̈ + g (m c_x cos q + m c_z sin q)
/// up to signs, so the base parameters are I_yy, mx and mz alone; about z, gravity does no
/// work and only I_zz remains.
#[test]
fn a_pendulums_base_parameters_are_what_its_axis_leaves() {
    let singles = |m: &multibody::Model| -> Vec<usize> {
        let base = base_parameters(m);
        assert!(base.iter().all(|b| b.terms.len() == 1), "{base:?}");
        let mut k: Vec<usize> = base.iter().map(|b| b.terms[0].0).collect();
        k.sort_unstable();
        k
    };
    // π = (m, mx, my, mz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz).
    assert_eq!(singles(&pendulum("0 1 0")), vec![1, 3, 7]);
    assert_eq!(singles(&pendulum("0 0 1")), vec![9]);
}

/// A URDF model's base parameters as its report names them: each name is the formula of its
/// value (read back here term by term, signs and coefficients as printed, over the standard
/// parameters of the file's links), 36 for the UR5 (60 standard parameters).
#[test]
fn a_reports_base_parameters_read_as_their_formulas() {
    use graybox::physics::multibody::spatial::STANDARD_NAMES as NAMES;
    use graybox::physics::urdf::UrdfTemplate;
    let path = super::common::urdf::fixture_path("robots/ur5", "urdf");
    let t = UrdfTemplate::from_urdf(&std::fs::read_to_string(path).unwrap()).unwrap();
    let physical: Vec<f64> = t.params().iter().map(|p| p.default).collect();
    let model = t.multibody_model(&physical, true);
    let pi = standard_parameters(&model);
    let lookup = |name: &str| -> f64 {
        let (link, what) = name.rsplit_once('.').unwrap();
        let b = t.tree.bodies.iter().position(|b| b.link == link).unwrap();
        pi[b * PER_BODY + NAMES.iter().position(|n| *n == what).unwrap()]
    };
    let base = t.base_parameters(&physical, true);
    assert_eq!(base.len(), 36);
    for (name, value) in &base {
        let formula: f64 = name
            .replace(" − ", " + −")
            .split(" + ")
            .map(|term| {
                let (sign, term) = match term.strip_prefix('−') {
                    Some(rest) => (-1.0, rest),
                    None => (1.0, term),
                };
                match term.split_once('·') {
                    Some((c, p)) => sign * c.parse::<f64>().unwrap() * lookup(p),
                    None => sign * lookup(term),
                }
            })
            .sum();
        // Coefficients are printed to six digits.
        assert!(
            (formula - value).abs() <= 1e-5 * value.abs().max(1.0),
            "{name} = {value} vs {formula}"
        );
    }
}

/// Past `BASE_PARAMETERS_MAX_BODIES` moving bodies a report lists no base parameters (their
/// QR grows as bodies³) rather than spending minutes on them.
#[test]
fn a_robot_past_the_limit_lists_no_base_parameters() {
    use graybox::physics::urdf::UrdfTemplate;
    use graybox::physics::urdf::template::BASE_PARAMETERS_MAX_BODIES;
    let bodies = BASE_PARAMETERS_MAX_BODIES + 1;
    let mut urdf = String::from(r#"<robot name="chain"><link name="l0"/>"#);
    for i in 1..=bodies {
        urdf += &format!(
            r#"<joint name="j{i}" type="revolute"><parent link="l{}"/><child link="l{i}"/>
  <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint>
<link name="l{i}"><inertial><mass value="1"/>
  <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>"#,
            i - 1
        );
    }
    urdf += "</robot>";
    let t = UrdfTemplate::from_urdf(&urdf).unwrap();
    let physical: Vec<f64> = t.params().iter().map(|p| p.default).collect();
    assert!(t.base_parameters(&physical, true).is_empty());
}
