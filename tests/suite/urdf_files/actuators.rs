//! A robot's actuators beyond its URDF: armature (docs/robots.md#armature), a URDF robot's
//! rotor inertias, are parameters only when its document or its file asks for them (every
//! other robot keeps its parameters' layout), start at the file's values, are refused below 0
//! or on a mimic joint naming the joint, add to M's diagonal, and the export writes them back;
//! effort gains and offsets (docs/robots.md#effort-gain-and-offset) come after them when the
//! document asks, and enter F as g u + o.

use graybox::error::Error;
use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;
use graybox::physics::urdf::export::export;
use serde_json::{Value, json};

use super::{fixture, template};

/// The double pendulum with `armature="a"` on its second joint only.
fn pendulum_with_rotor(a: f64) -> String {
    let text = fixture("double_pendulum");
    let second = text.rfind(r#"<dynamics damping="0.5"/>"#).unwrap();
    let mut out = text.clone();
    out.replace_range(
        second..second + r#"<dynamics damping="0.5"/>"#.len(),
        &format!(r#"<dynamics damping="0.5" armature="{a}"/>"#),
    );
    out
}

fn urdf_of(t: &Template) -> &UrdfTemplate {
    match t {
        Template::Urdf(u) => u,
        _ => unreachable!(),
    }
}

fn names(t: &Template) -> Vec<String> {
    t.params().iter().map(|p| p.name.to_string()).collect()
}

#[test]
fn armature_is_a_parameter_when_the_document_or_the_file_asks() {
    let plain = template(&fixture("double_pendulum"));
    assert!(!names(&plain).iter().any(|n| n.ends_with(".armature")));
    let written = serde_json::to_value(&plain).unwrap();
    assert!(written.get("armature").is_none(), "{written}");

    let doc = json!({"kind": "urdf", "urdf": fixture("double_pendulum"), "armature": true});
    let asked = Template::from_document(&doc).unwrap();
    let n = names(&asked);
    // After every other parameter, one per coordinate: the old layout is a prefix.
    assert_eq!(&n[..names(&plain).len()], &names(&plain)[..]);
    assert_eq!(&n[n.len() - 2..], ["q1.armature", "q2.armature"]);
    assert_eq!(&asked.defaults()[n.len() - 2..], [0.0, 0.0]);

    let in_file = template(&pendulum_with_rotor(0.25));
    assert_eq!(names(&in_file), n);
    assert_eq!(&in_file.defaults()[n.len() - 2..], [0.0, 0.25]);
    let written = serde_json::to_value(&in_file).unwrap();
    assert_eq!(written["armature"], json!(true));
    assert_eq!(Template::from_document(&written).unwrap(), in_file);
}

#[test]
fn a_negative_armature_or_one_on_a_mimic_joint_is_refused_naming_the_joint() {
    let field_and_message = |text: &str| match UrdfTemplate::from_urdf(text) {
        Err(Error::Unprocessable { field, message }) => (field, message),
        other => panic!("expected a 422, got {other:?}"),
    };
    let (field, m) = field_and_message(&pendulum_with_rotor(-0.1));
    assert_eq!(field, "urdf");
    assert!(m.contains("'q2'") && m.contains("armature"), "{m}");

    let mimic = fixture("double_pendulum").replace(
        r#"<dynamics damping="0.5"/>
  </joint>
  <link name="rod2">"#,
        r#"<dynamics damping="0.5" armature="0.1"/>
    <mimic joint="q1" multiplier="2"/>
  </joint>
  <link name="rod2">"#,
    );
    assert!(mimic.contains("<mimic"), "the fixture changed");
    let (field, m) = field_and_message(&mimic);
    assert_eq!(field, "urdf");
    assert!(m.contains("q2") && m.contains("mimic"), "{m}");
}

/// M(q) gains a on its diagonal and nothing else; ½ q̇ᵀ M q̇ is the energy the model reports.
#[test]
fn armature_adds_to_the_mass_matrix_diagonal() {
    let (plain, rotor) = (
        template(&fixture("double_pendulum")),
        template(&pendulum_with_rotor(0.25)),
    );
    let q = [0.3, -0.7];
    let m0 = urdf_of(&plain).mass(&plain.defaults(), &q);
    let m1 = urdf_of(&rotor).mass(&rotor.defaults(), &q);
    for i in 0..2 {
        for j in 0..2 {
            let want = m0[i][j] + if (i, j) == (1, 1) { 0.25 } else { 0.0 };
            assert!(
                (m1[i][j] - want).abs() < 1e-12,
                "M[{i}][{j}] {m1:?} vs {m0:?}"
            );
        }
    }
}

/// The export writes every coordinate's armature into its `<dynamics>`, and reads back as
/// the same template at those values.
#[test]
fn the_export_writes_the_armatures_back() {
    let t = template(&pendulum_with_rotor(0.25));
    let u = urdf_of(&t);
    let mut values = t.defaults();
    let k = values.len();
    values[k - 2] = 0.125;
    values[k - 1] = 0.5;
    let text = export(u, &values).unwrap();
    assert_eq!(text.matches("armature=").count(), 2, "{text}");
    let again = template(&text);
    let got: Vec<f64> = again.defaults();
    assert_eq!(&got[k - 2..], [0.125, 0.5]);
    let doc: Value = serde_json::to_value(&again).unwrap();
    assert_eq!(doc["armature"], json!(true));
}

/// Gains and offsets follow the armatures, one each per input, 1 and 0 to start; F is
/// S (g∘u + o) − the joints' own forces, and the energy report's friction part leaves the
/// offsets to the input's.
#[test]
fn effort_gains_and_offsets_scale_and_shift_the_inputs() {
    let doc = json!({"kind": "urdf", "urdf": pendulum_with_rotor(0.25), "actuated": ["q1"],
                     "effort_gain": true, "effort_offset": true});
    let t = Template::from_document(&doc).unwrap();
    let n = names(&t);
    assert_eq!(
        &n[n.len() - 4..],
        [
            "q1.armature",
            "q2.armature",
            "q1.effort_gain",
            "q1.effort_offset"
        ]
    );
    let mut p = t.defaults();
    assert_eq!(&p[p.len() - 2..], [1.0, 0.0]);
    let k = p.len();
    (p[k - 2], p[k - 1]) = (2.0, 0.5);
    let u = urdf_of(&t);
    let (q, qd) = ([0.1, 0.2], [0.3, -0.4]);
    let with = u.forces(&p, &q, &qd, &[3.0]);
    let without = u.forces(&p, &q, &qd, &[0.0]);
    assert!(
        (with[0] - without[0] - 6.0).abs() < 1e-12,
        "{with:?} vs {without:?}"
    );
    assert_eq!(with[1], without[1]);
    let arena = graybox::arena::Arena::new();
    let passive = u.passive_forces_in(&arena, &p, &qd);
    assert!(
        (without[0] - passive[0] - 0.5).abs() < 1e-12,
        "{without:?} vs {passive:?}"
    );
    let written = serde_json::to_value(&t).unwrap();
    assert_eq!(
        (
            written["effort_gain"].clone(),
            written["effort_offset"].clone()
        ),
        (json!(true), json!(true))
    );
}
