//! The URDF files robotics users have, as they are written: what does not enter the dynamics
//! does not keep a file from loading.

use std::sync::Arc;

use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;

#[path = "urdf_files/actuators.rs"]
mod actuators;
#[path = "urdf_files/bounds.rs"]
mod bounds;
#[path = "urdf_files/coulomb.rs"]
mod coulomb;
#[path = "urdf_files/exact.rs"]
mod exact;
#[path = "urdf_files/mimic.rs"]
mod mimic;
#[path = "urdf_files/reader.rs"]
mod reader;

pub(crate) fn fixture(name: &str) -> String {
    let path = format!(
        "{}/tests/fixtures/urdf/{name}.urdf",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(path).unwrap()
}

pub(crate) fn template(text: &str) -> Template {
    Template::Urdf(Arc::new(UrdfTemplate::from_urdf(text).unwrap()))
}

/// The root link is welded to the world, so its inertia never enters M(q) or V(q); HyQ and
/// ANYmal B carry a dummy, unphysical one there (here: moments that break the triangle
/// inequality, and a negative mass) and were refused. The robot loads and its M and V are
/// those of the file without it, exactly (the root's values are not read at all).
#[test]
fn a_dummy_inertia_on_the_root_link_is_ignored() {
    let plain = fixture("double_pendulum");
    let dummy = plain.replace(
        r#"<link name="world"/>"#,
        r#"<link name="world"><inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="-1"/>
           <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="100"/></inertial></link>"#,
    );
    assert_ne!(plain, dummy);
    let (a, b) = (template(&plain), template(&dummy));
    let p = a.defaults();
    assert_eq!(p, b.defaults());
    for q in [[0.0, 0.0], [0.7, -1.9], [3.0, 2.5]] {
        assert_eq!(a.mass(&p, &q), b.mass(&p, &q));
        assert_eq!(a.potential(&p, &q), b.potential(&p, &q));
    }
    // A moving link's unphysical inertia is still refused, naming the link.
    let bad = plain.replacen(r#"izz="0.0001""#, r#"izz="100""#, 1);
    let err = UrdfTemplate::from_urdf(&bad).unwrap_err().to_string();
    assert!(err.contains("rod1"), "{err}");
}

/// HyQ's feet are welded to the lower legs with a dummy inertia (1e-6 kg, every moment 1e-6:
/// not a physical body by itself) and the file was refused naming `lf_foot`. Only the whole
/// body a joint moves has to be physical: the leg absorbs the foot, and the body's values are
/// the file's sum (the rod's mass plus the foot's 1e-6 kg).
#[test]
fn a_dummy_inertia_on_a_welded_link_is_absorbed_by_its_body() {
    let plain = fixture("double_pendulum");
    let foot = plain.replace(
        "</robot>",
        r#"<joint name="ankle" type="fixed"><parent link="rod2"/><child link="foot"/>
             <origin xyz="0 0 -1"/></joint>
           <link name="foot"><inertial><mass value="1e-6"/>
             <inertia ixx="1e-6" ixy="1e-6" ixz="1e-6" iyy="1e-6" iyz="1e-6" izz="1e-6"/>
           </inertial></link></robot>"#,
    );
    let (a, b) = (template(&plain), template(&foot));
    let mass = a.index_of("rod2.mass").unwrap();
    assert_eq!(b.defaults()[mass], a.defaults()[mass] + 1e-6);
}

/// What does not enter the dynamics never refuses a file: icub's empty `<texture/>`, a
/// `<limit>` without `velocity`, Gazebo and transmission elements, an unknown element. The
/// robot is the same as without them.
#[test]
fn elements_outside_the_dynamics_are_ignored() {
    let plain = fixture("double_pendulum");
    let decorated = plain
        .replace(
            r#"<link name="world"/>"#,
            r#"<link name="world"><visual><geometry><box size="1 1 1"/></geometry>
                 <material name="m"><texture/><color rgba="0 0 0 1"/></material></visual>
               </link>
               <gazebo reference="rod1"><mu1>0.2</mu1></gazebo>
               <transmission name="t"><joint name="q1"/><actuator name="m1"/></transmission>"#,
        )
        .replacen(
            r#"<dynamics damping="0.5"/>"#,
            r#"<dynamics damping="0.5"/><limit effort="10"/><safety_controller/><anything/>"#,
            1,
        );
    let (a, b) = (template(&plain), template(&decorated));
    assert_eq!(a.defaults(), b.defaults());
    assert_eq!(a.coordinates(), b.coordinates());
}

/// Errors name the element and the line: a joint whose link is missing, a file without links
/// (it used to say "the joints form a loop"), a non-number.
#[test]
fn errors_name_the_element_and_its_line() {
    let plain = fixture("double_pendulum");
    let cases = [
        (
            plain.replace(r#"<child link="rod2"/>"#, r#"<child link="rod3"/>"#),
            "joint 'q2' (line 23): its child link 'rod3' does not exist",
        ),
        (
            r#"<robot name="r"><!-- nothing --></robot>"#.to_string(),
            "the robot has no <link>",
        ),
        (
            plain.replacen(r#"<mass value="10"/>"#, r#"<mass value="ten"/>"#, 1),
            "<mass> of link 'rod1' (line 16): value=\"ten\" is not a number",
        ),
        (
            plain.replace(
                r#"<link name="world"/>"#,
                r#"<link name="world"/><link name="b"/>"#,
            ),
            "more than one root link (link 'world' (line 8), link 'b' (line 8))",
        ),
        (
            plain.replace(r#"<parent link="world"/>"#, r#"<parent link="rod2"/>"#),
            "link 'rod1' (line 16), link 'rod2' (line 30) … are not reachable from the root \
             link 'world'",
        ),
    ];
    for (doc, want) in cases {
        let e = UrdfTemplate::from_urdf(&doc).unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    }
}
