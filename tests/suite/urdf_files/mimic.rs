//! Mimic joints (every stock Franka Panda, Baxter, PR2, TALOS and TIAGo file has them): a
//! mimic joint is not a coordinate; its value is multiplier · q + offset of the joint it
//! mimics, and its forces enter that joint's coordinate by the chain rule.

use super::{fixture, template};
use graybox::physics::urdf::UrdfTemplate;

/// A gripper on a fixed base: finger `a` slides along z (the coordinate); finger `b` mimics it
/// with multiplier −2 and offset 0.1, also along z, the axis gravity acts along (so that V
/// sees the offset).
fn gripper(mimic: &str) -> String {
    format!(
        r#"<robot name="gripper"><link name="base"/>
  <joint name="a" type="prismatic"><parent link="base"/><child link="fa"/><axis xyz="0 0 1"/>
    <dynamics damping="0.3"/></joint>
  <link name="fa"><inertial><origin xyz="0 0 0.01"/><mass value="2"/>
    <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>
  <joint name="b" type="prismatic"><parent link="base"/><child link="fb"/><axis xyz="0 0 1"/>
    {mimic}<dynamics damping="0.5" friction="0.2"/></joint>
  <link name="fb"><inertial><origin xyz="0 0 0.03"/><mass value="3"/>
    <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>
</robot>"#
    )
}

/// M, V and F of the gripper against its equations written by hand: x_b = −2 q + 0.1, so
/// M = m_a + 4 m_b, V = g (m_a (q + 0.01) + m_b (x_b + 0.03)), and F = u − d_a q̇ − 2 (−d_b ẋ_b −
/// f_b tanh(ẋ_b / 0.01)) with ẋ_b = −2 q̇ (the mimic's force on q by the chain rule).
#[test]
fn a_mimic_joint_follows_its_joint_through_m_v_and_f() {
    let doc = gripper(r#"<mimic joint="a" multiplier="-2" offset="0.1"/>"#);
    let u = UrdfTemplate::from_urdf(&doc).unwrap();
    assert_eq!(u.coordinates(), ["a"]);
    assert_eq!(u.inputs(), ["a"]);
    let t = template(&doc);
    let p = t.defaults();
    // Both links keep their parameters, both joints their damping and friction.
    for name in ["fb.mass", "fb.com_x", "b.damping", "b.friction"] {
        assert!(t.index_of(name).is_some(), "{name}");
    }
    let (ma, mb, g) = (2.0, 3.0, 9.81);
    for (q, qd, f) in [(0.0, 0.0, 1.0), (0.2, 1.5, -0.5), (-0.4, -0.003, 0.0)] {
        let m = t.mass(&p, &[q]);
        // Sums of a few products of O(1) values: rounding is ~1e-15.
        assert!((m[0][0] - (ma + 4.0 * mb)).abs() < 1e-12, "{m:?}");
        let xb = -2.0 * q + 0.1;
        let v = g * (ma * (q + 0.01) + mb * (xb + 0.03));
        assert!((t.potential(&p, &[q]) - v).abs() < 1e-12);
        let vb = -2.0 * qd;
        let fb = -0.5 * vb - 0.2 * (vb / 0.01f64).tanh();
        let want = f - 0.3 * qd - 2.0 * fb;
        let got = t.forces(&p, &[q], &[qd], &[f]);
        assert!((got[0] - want).abs() < 1e-12, "{got:?} vs {want}");
    }
}

/// The stock Panda loads with its mimic finger: seven arm joints and one finger coordinate.
#[test]
fn the_stock_panda_loads_with_its_mimic_finger() {
    let u = UrdfTemplate::from_urdf(&fixture("robots/panda")).unwrap();
    let c = u.coordinates();
    assert_eq!(c.len(), 8, "{c:?}");
    assert_eq!(c[7], "panda_finger_joint1");
    assert!(!c.iter().any(|j| j == "panda_finger_joint2"), "{c:?}");
}

/// A mimic joint is not a coordinate, so it takes no input and no `periodic` flag; a mimic of
/// a joint that is not there, or mimics in a circle, are refused naming the joint and line.
#[test]
fn mimic_joints_are_checked() {
    let doc = gripper(r#"<mimic joint="a"/>"#);
    let mut d = UrdfTemplate::from_urdf(&doc).unwrap().doc;
    d.actuated = Some(vec!["b".into()]);
    let e = UrdfTemplate::from_doc(d, 64).unwrap_err().to_string();
    assert!(
        e.starts_with("actuated") && e.contains("mimic joint"),
        "{e}"
    );
    let missing = gripper(r#"<mimic joint="c"/>"#);
    let e = UrdfTemplate::from_urdf(&missing).unwrap_err().to_string();
    assert!(
        e.contains("joint 'b' (line 6)") && e.contains("\"c\""),
        "{e}"
    );
    let circle = gripper(r#"<mimic joint="a"/>"#).replacen(
        r#"<axis xyz="0 0 1"/>"#,
        r#"<axis xyz="0 0 1"/><mimic joint="b"/>"#,
        1,
    );
    let e = UrdfTemplate::from_urdf(&circle).unwrap_err().to_string();
    assert!(e.contains("circle"), "{e}");
}
