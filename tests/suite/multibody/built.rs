//! A `multibody::Model` built by hand, with no URDF (`Model::new` from bodies, joint models,
//! drives and inertias), is the robot the URDF producer builds from the same description:
//! every algorithm gives the same bits, mimic joint included.

use graybox::physics::multibody::{
    self, Body, Drive, Inertial, JointModel, Placement, crba, forward_dynamics, inverse_dynamics,
    kinetic_energy, potential_energy,
};
use graybox::physics::urdf::Tree;
use graybox::rng::Rng;

const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// A shoulder about z, a slider along x on it, and an elbow about y on the shoulder that
/// mimics the shoulder (−0.5 q₀ + 0.1).
const URDF: &str = r#"<robot name="hand">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0.1 0 0.2"/><mass value="2"/>
    <inertia ixx="0.05" ixy="0" ixz="0" iyy="0.04" iyz="0" izz="0.03"/></inertial></link>
  <link name="slider"><inertial><origin xyz="0 0.05 0"/><mass value="0.5"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.001"/></inertial></link>
  <link name="fore"><inertial><origin xyz="0 0 0.3"/><mass value="1"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.01"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="slider"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 0 0"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <mimic joint="shoulder" multiplier="-0.5" offset="0.1"/></joint>
</robot>"#;

fn body(parent: Option<usize>, joint: JointModel, drive: Drive, mass: f64, c: [f64; 3]) -> Body {
    let i = |d: [f64; 3]| -> [[f64; 3]; 3] {
        std::array::from_fn(|r| std::array::from_fn(|k| if r == k { d[r] } else { 0.0 }))
    };
    let moments = match mass {
        2.0 => [0.05, 0.04, 0.03],
        0.5 => [0.002, 0.003, 0.001],
        _ => [0.02, 0.02, 0.01],
    };
    Body {
        parent,
        joint,
        drive,
        inertia: Inertial::from_com(mass, c, i(moments)),
    }
}

fn by_hand(gravity: [f64; 3]) -> multibody::Model {
    let at = |pos: [f64; 3]| Placement { rot: IDENTITY, pos };
    let mimic = Drive {
        coordinate: 0,
        multiplier: -0.5,
        offset: 0.1,
    };
    // The URDF producer's order: depth first, children in document order.
    let bodies = vec![
        body(
            None,
            JointModel::revolute(&at([0.0, 0.0, 0.5]), [0.0, 0.0, 1.0]),
            Drive::own(0),
            2.0,
            [0.1, 0.0, 0.2],
        ),
        body(
            Some(0),
            JointModel::prismatic(&at([0.2, 0.0, 0.0]), [1.0, 0.0, 0.0]),
            Drive::own(1),
            0.5,
            [0.0, 0.05, 0.0],
        ),
        body(
            Some(0),
            JointModel::revolute(&at([0.0, 0.0, 0.4]), [0.0, 1.0, 0.0]),
            mimic,
            1.0,
            [0.0, 0.0, 0.3],
        ),
    ];
    multibody::Model::new(bodies, 2, gravity)
}

/// Bit for bit: both paths put the same constants through the same arithmetic.
#[test]
fn a_model_built_by_hand_is_the_urdfs_robot() {
    let g = [0.0, 0.0, -9.81];
    let tree = Tree::parse(URDF, 8).unwrap();
    assert_eq!(tree.coordinates.len(), 2, "the elbow mimics the shoulder");
    let (urdf, hand) = (tree.multibody(g), by_hand(g));
    assert!(hand.mimic && urdf.mimic);
    let mut rng = Rng::new(5);
    for _ in 0..20 {
        let [q, qd, x]: [Vec<f64>; 3] =
            std::array::from_fn(|_| (0..2).map(|_| rng.normal()).collect());
        assert_eq!(crba(&urdf, &q), crba(&hand, &q));
        assert_eq!(
            inverse_dynamics(&urdf, &q, &qd, &x),
            inverse_dynamics(&hand, &q, &qd, &x)
        );
        assert_eq!(
            forward_dynamics(&urdf, &q, &qd, &x),
            forward_dynamics(&hand, &q, &qd, &x)
        );
        assert_eq!(
            kinetic_energy(&urdf, &q, &qd),
            kinetic_energy(&hand, &q, &qd)
        );
        assert_eq!(potential_energy(&urdf, &q), potential_energy(&hand, &q));
    }
}
