//! Issue 28, item 5: learned damping and friction stay physical (≥ 0) through training and
//! export, and values that enter below 0 (the file, `init`, `--set`) are refused naming the
//! field. After a UR5 identification all six dampings came out negative and Pinocchio refused
//! the exported file.

use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

use graybox::backend::{Backend, Precision};
use graybox::error::Error;
use graybox::model::network::param;
use graybox::model::params::{Components, Params};
use graybox::model::spec::ModelSpec;
use graybox::physics::params::bounds;
use graybox::physics::urdf::UrdfTemplate;
use graybox::sim::{SimConfig, parse_assignments, simulate};
use graybox::train::setup::physical_init;
use graybox::train::{TrainConfig, Trainer};

use super::{fixture, template};

fn unprocessable<T: std::fmt::Debug>(r: graybox::error::Result<T>) -> (String, String) {
    match r {
        Err(Error::Unprocessable { field, message }) => (field, message),
        other => panic!("expected a 422, got {other:?}"),
    }
}

/// A negative `<dynamics>` value in the file, in `init` or in `--set` is a 422 naming it.
#[test]
fn negative_damping_or_friction_is_refused_naming_the_field() {
    let plain = fixture("double_pendulum");
    let (field, message) = unprocessable(UrdfTemplate::from_urdf(&plain.replacen(
        r#"damping="0.5""#,
        r#"damping="-0.5""#,
        1,
    )));
    assert_eq!(field, "urdf");
    assert!(
        message.contains("joint 'q1'") && message.contains("damping"),
        "{message}"
    );
    let (_, message) = unprocessable(UrdfTemplate::from_urdf(&plain.replacen(
        r#"<dynamics damping="0.5"/>"#,
        r#"<dynamics damping="0.5" friction="-0.01"/>"#,
        2,
    )));
    assert!(message.contains("friction"), "{message}");

    let t = template(&plain);
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let init = [("q2.friction".to_string(), -1e-3)];
    let (field, _) = unprocessable(physical_init(&spec, &init));
    assert_eq!(field, "init.q2.friction");
    let (field, _) = unprocessable(parse_assignments(&t, Some("q1.damping=-0.1"), "set"));
    assert_eq!(field, "set.q1.damping");
    // 0 itself is the bound, not beyond it.
    parse_assignments(&t, Some("q1.damping=0,q1.friction=0"), "set").unwrap();
}

/// The projection puts only the bounded values below their bound back onto it, and keeps
/// the parameter trainable.
#[test]
fn the_projection_clamps_only_bounded_values_below_their_bound() {
    let t = template(&fixture("double_pendulum"));
    let k = t.params().len();
    let bounds = bounds(t.params(), &vec![0.0; k]).expect("damping and friction are bounded");
    let device = graybox::backend::device(Backend::Flex, Precision::F32)
        .unwrap()
        .autodiff();
    // A step that pushed everything to −0.25: the inertial raw values are free, the joint
    // values (the last four) are not.
    let params = Params::Structured(Components {
        mass: None,
        potential: None,
        forces: None,
        physical: Some(param(vec![-0.25; k], [1, k], &device)),
        physical_as_is: false,
    });
    let c = params.projected(&bounds);
    let p = c.components().unwrap().physical.as_ref().unwrap().val();
    assert!(p.is_require_grad());
    let got: Vec<f64> = p.into_data().iter::<f64>().collect();
    for (i, name) in t.params().iter().map(|p| &p.name).enumerate() {
        let want = if name.ends_with(".damping") || name.ends_with(".friction") {
            0.0
        } else {
            -0.25
        };
        assert_eq!(got[i], want, "{name}");
    }
}

/// Data from a double pendulum whose joints give energy (damping −0.3, which a free damping
/// would fit) pulls both dampings and the frictions below 0; training ends with each ≥ 0 and
/// some exactly at the bound (so without the projection this test fails), and the export
/// writes `<dynamics>` values ≥ 0 that the reader (like Pinocchio's) takes back.
#[test]
fn training_keeps_damping_and_friction_non_negative_through_the_export() {
    let t = template(&fixture("double_pendulum"));
    let mut truth = t.defaults();
    for (k, p) in t.params().iter().enumerate() {
        if p.name.ends_with(".damping") {
            truth[k] = -0.3;
        }
    }
    let sim = |seed| {
        let cfg = SimConfig {
            count: 512,
            seed,
            dt: 0.01,
            q_range: PI,
            qdot_range: 3.0,
            u_std: 20.0,
            u_stds: vec![],
        };
        simulate(&t, truth.clone(), &cfg).unwrap()
    };
    let (data, val) = (sim(1), sim(2));
    let device = graybox::backend::device(Backend::Flex, Precision::F32)
        .unwrap()
        .autodiff();
    let cfg = TrainConfig {
        epochs: 30,
        batch_size: 128,
        lr: 1e-2,
        ..TrainConfig::default()
    };
    let init: Vec<(String, f64)> = ["q1.damping", "q2.damping"]
        .iter()
        .map(|n| (n.to_string(), 0.05))
        .collect();
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let mut tr = Trainer::new("W-B", spec, &init, &data, Some(&val), cfg, &device).unwrap();
    tr.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let file = tr.model_file();
    let learned = &file.report.as_ref().unwrap().physical_parameters;
    let joint: Vec<(&String, f64)> = learned
        .iter()
        .filter(|(n, _)| n.ends_with(".damping") || n.ends_with(".friction"))
        .map(|(n, v)| (n, *v))
        .collect();
    assert_eq!(joint.len(), 4, "{learned:?}");
    assert!(joint.iter().all(|(_, v)| *v >= 0.0), "{joint:?}");
    assert!(joint.iter().any(|(_, v)| *v == 0.0), "{joint:?}");

    let text = file.urdf().unwrap();
    let mut written = 0;
    for part in text.split("<dynamics ").skip(1) {
        let tag = &part[..part.find("/>").unwrap()];
        for attr in ["damping", "friction"] {
            let at = tag.find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
            let v: f64 = tag[at..at + tag[at..].find('"').unwrap()].parse().unwrap();
            assert!(v >= 0.0, "{tag}");
            written += 1;
        }
    }
    assert_eq!(written, 4, "{text}");
    UrdfTemplate::from_urdf(&text).unwrap();
}

/// A model file trained before the bound (here: its stored damping made negative) still
/// loads, but its export is refused naming the parameter: no URDF Pinocchio would refuse, and
/// no silently clamped robot.
#[test]
fn an_old_model_with_negative_damping_does_not_export() {
    use graybox::model::file::ModelFile;
    use graybox::physics::integrator::Integrator;
    let t = template(&fixture("double_pendulum"));
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&file.to_bytes().unwrap()).unwrap();
    // Written before checksums, as such a file was (else its checksum would refuse the edit).
    json.as_object_mut().unwrap().remove("checksum");
    let values = json["params"][0]["values"].as_array_mut().unwrap();
    // The joints' values come last, as (damping, friction) per joint: q2's damping.
    let k = values.len() - 2;
    values[k] = serde_json::json!(-0.2);
    let old = ModelFile::from_bytes(&serde_json::to_vec(&json).unwrap()).unwrap();
    match old.urdf() {
        Err(Error::FailedPrecondition(m)) => assert!(m.contains("q2.damping"), "{m}"),
        other => panic!("expected a failed precondition, got {other:?}"),
    }
}
