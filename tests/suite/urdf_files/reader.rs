//! The URDF reader (`urdf::read`) on its own: what it reads, what it leaves, and how its
//! errors say where.

use graybox::error::{Error, Result};
use graybox::physics::urdf::read::{JointType, Mimic, Robot, read};

fn message(r: Result<Robot>) -> String {
    match r {
        Err(Error::Unprocessable { field, message }) => {
            assert_eq!(field, "urdf");
            message
        }
        other => panic!("expected a 422, got {other:?}"),
    }
}

/// Only the elements the dynamics needs are read: an empty `<texture/>`, a `<limit>`
/// without `velocity`, a `<transmission>` with a `<joint>` inside, and unknown elements
/// are not.
#[test]
fn what_does_not_affect_dynamics_is_not_read() {
    let doc = r#"<?xml version="1.0"?>
<robot name="r">
  <material name="m"><texture/><color rgba="0 0 0 1"/></material>
  <link name="base"><visual><material name="x"><texture/></material></visual></link>
  <joint name="j" type="revolute">
<parent link="base"/><child link="l"/><axis xyz="0  0 1"/>
<limit lower="-1" upper="1"/><calibration rising="0"/>
<dynamics damping="0.5"/>
  </joint>
  <link name="l"><contact><lateral_friction value="1"/></contact>
<inertial><origin xyz="0 0 0.1"/><mass value="2"/>
  <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1e-1"/></inertial>
<inertial><mass value="99"/></inertial>
  </link>
  <transmission name="t"><joint name="j"><hardwareInterface/></joint></transmission>
  <gazebo reference="l"><mu1>0.2</mu1></gazebo>
</robot>"#;
    let r = read(doc).unwrap();
    assert_eq!(r.name, "r");
    assert_eq!(r.links.len(), 2);
    assert_eq!(r.joints.len(), 1);
    let j = &r.joints[0];
    assert_eq!(
        (j.line, j.kind, j.axis),
        (5, JointType::Revolute, [0.0, 0.0, 1.0])
    );
    assert_eq!(j.dynamics, Some((0.5, 0.0)));
    let i = r.links[1].inertial.as_ref().unwrap();
    assert_eq!((i.mass, i.origin.xyz[2], i.inertia[5]), (2.0, 0.1, 0.1));
    assert!(r.links[0].inertial.is_none());
}

#[test]
fn mimic_joints_are_read_with_their_defaults() {
    let doc = r#"<robot name="r"><link name="a"/><link name="b"/>
        <joint name="f" type="prismatic"><parent link="a"/><child link="b"/>
        <mimic joint="g" offset="0.5"/></joint></robot>"#;
    let m = read(doc).unwrap().joints[0].mimic.clone().unwrap();
    assert_eq!(
        m,
        Mimic {
            joint: "g".into(),
            multiplier: 1.0,
            offset: 0.5
        }
    );
}

/// Every error names the element (and the link or joint it is in) and the line.
#[test]
fn errors_name_the_element_and_the_line() {
    let cases = [
        (
            "<robot>\n<link name=\"a\">\n<inertial><mass/></inertial></link></robot>",
            "<mass> of link 'a' (line 2) needs the attribute value",
        ),
        (
            "<robot>\n\n<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/></joint></robot>",
            "joint 'j' (line 3) has no <child",
        ),
        (
            "<robot>\n<joint name=\"j\" type=\"ball\"/></robot>",
            "joint 'j' (line 2): type \"ball\"",
        ),
        (
            "<robot><joint name=\"j\" type=\"fixed\">\n<origin xyz=\"1 2\"/></joint></robot>",
            "<origin> of joint 'j' (line 1): xyz=\"1 2\" is not three numbers",
        ),
        (
            "<robot>\n<link name=\"a\"><inertial><inertia ixx=\"x\"/></inertial></link></robot>",
            "<inertia> of link 'a' (line 2): ixx=\"x\" is not a number",
        ),
        (
            "<robot>\n\n<link/></robot>",
            "a <link> at line 3 has no name",
        ),
        ("<model/>", "root element is <model> at line 1"),
    ];
    for (doc, want) in cases {
        let m = message(read(doc));
        assert!(m.contains(want), "{doc}: {m}");
    }
}

/// `<limit effort>` is read (a planner's input bound) and checked: absent is none, 0 is none
/// (files write it for joints without an actuator), a negative or non-numeric one is refused
/// naming the joint and its line.
#[test]
fn effort_limits_are_read_and_checked() {
    let doc = |limit: &str| {
        format!(
            r#"<robot name="r"><link name="base"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="l1"/>{limit}</joint>
  <link name="l1"><inertial><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="b" type="revolute"><parent link="l1"/><child link="l2"/>
    <limit effort="28" velocity="3"/></joint>
  <link name="l2"><inertial><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
</robot>"#
        )
    };
    let efforts = |limit: &str| {
        let t =
            graybox::physics::urdf::UrdfTemplate::from_urdf(&doc(limit)).map_err(|e| e.to_string());
        t.map(|t| t.effort_limits())
    };
    assert_eq!(efforts(""), Ok(vec![None, Some(28.0)]));
    assert_eq!(
        efforts(r#"<limit lower="-1" upper="1"/>"#),
        Ok(vec![None, Some(28.0)])
    );
    assert_eq!(
        efforts(r#"<limit effort="0"/>"#),
        Ok(vec![None, Some(28.0)])
    );
    assert_eq!(
        efforts(r#"<limit effort="150"/>"#),
        Ok(vec![Some(150.0), Some(28.0)])
    );
    let negative = efforts(r#"<limit effort="-5"/>"#).unwrap_err();
    assert!(
        negative.contains("joint 'a' (line 2)") && negative.contains("effort"),
        "{negative}"
    );
    let text = efforts(r#"<limit effort="lots"/>"#).unwrap_err();
    assert!(
        text.contains("effort=\"lots\" is not a number") && text.contains("line 2"),
        "{text}"
    );
}
