//! The URDF files robotics users have, as they are written: what does not enter the dynamics
//! does not keep a file from loading.

use std::sync::Arc;

use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;

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

#[path = "urdf_files/bounds.rs"]
mod bounds;

#[path = "urdf_files/exact.rs"]
mod exact;

#[path = "urdf_files/coulomb.rs"]
mod coulomb;
