//! Training's forward dynamics for URDF models (`model/multibody.rs`: one Burn op per batch,
//! the articulated-body algorithm forward and forward dynamics' adjoint backward) against
//! Burn's autodiff through the template's assembly (M = Σ JᵀIJ with its q-derivatives over
//! dual numbers, the Coriolis term from them, a Cholesky solve, V's gradient): one RK4 step's
//! loss and every parameter's gradient, for white-box robots with mimic joints and branches,
//! and for models whose V or F is a network (gravity then leaves the recursion).

use std::sync::Arc;

use graybox::physics::urdf::UrdfTemplate;

use super::common::urdf::fixture_path;
use super::*;

fn urdf(name: &str) -> Template {
    let text = match name {
        // The branching tree with a second finger that mirrors the prismatic hand, as a
        // gripper's does (Panda's is the same; its assembly is too slow for a test).
        "tree+mimic" => tree_with_mimic(),
        // Every joint with an armature of 1 (perturbed by N(0, 0.3²) it stays positive).
        "ur5+rotors" => std::fs::read_to_string(fixture_path("robots/ur5", "urdf"))
            .unwrap()
            .replace("friction=\"0.0\"/>", "friction=\"0.0\" armature=\"1.0\"/>"),
        _ => std::fs::read_to_string(fixture_path(name, "urdf")).unwrap(),
    };
    Template::Urdf(Arc::new(UrdfTemplate::from_urdf(&text).unwrap()))
}

fn tree_with_mimic() -> String {
    let tree = std::fs::read_to_string(fixture_path("tree", "urdf")).unwrap();
    let finger = r#"
  <joint name="left_finger" type="prismatic">
    <origin xyz="0 0.25 0.05" rpy="0 0 0"/>
    <parent link="left_arm"/>
    <child link="left_finger"/>
    <axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.1" effort="20" velocity="1"/>
    <mimic joint="beta_left_hand" multiplier="-1.0" offset="0.01"/>
    <dynamics damping="0.3" friction="0.1"/>
  </joint>
  <link name="left_finger">
    <inertial>
      <origin xyz="0 0.02 0" rpy="0 0 0"/>
      <mass value="0.2"/>
      <inertia ixx="0.0002" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0002"/>
    </inertial>
  </link>
</robot>"#;
    tree.replace("</robot>", finger)
}

/// One RK4 step's loss on 12 random rows (|x| ≤ 2, |u| ≤ 5) and every gradient, flattened.
fn loss_and_gradients(model: &Model, dev: &Device) -> (f64, Vec<f64>) {
    let (value, g) = random_loss_and_gradients(model, dev, 12);
    (value, g.concat())
}

/// max |a − b| over max |b|, NaN if any difference is.
fn gradient_error(g: &[f64], g_ref: &[f64]) -> f64 {
    let scale = g_ref.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(scale > 0.0, "some gradient is not zero");
    let worst = g.iter().zip(g_ref).fold(0.0f64, |a, (x, y)| {
        let d = (x - y).abs();
        if d.is_nan() || d > a { d } else { a }
    });
    worst / scale
}

/// The two paths agree to 1e-9 relative (loss) and 1e-8 of the largest gradient: both are f64
/// evaluations of the same mechanics by different formulas (recursions over the tree and
/// their adjoint vs the assembled M(q), its Cholesky factor and Burn's tape through them), so
/// rounding separates them by ~1e-16 (measured); a wrong sign, frame, gravity or a missing
/// term of the adjoint moves them by far more.
#[test]
fn multibody_op_loss_and_gradients_equal_the_assembly() {
    let dev = f64_device().autodiff();
    let cases = [
        ("robots/ur5", "W-B"),
        ("ur5+rotors", "W-B"),
        ("ur5+rotors", "F"),
        ("arm4", "V"),
        ("arm4", "F"),
        ("tree", "W-B"),
        ("tree+mimic", "W-B"),
        ("tree+mimic", "V"),
        ("arm4", "M"),
    ];
    for (robot, name) in cases {
        let t = urdf(robot);
        let (n, m) = (t.n(), t.m());
        let fused = perturb(&model(name, Some(t), n, m, 5, &dev), &dev);
        let what = format!("{robot} {name}");
        assert!(
            fused.is_multibody() == (name != "M"),
            "{what}: multibody iff M is the template's"
        );
        let (v, g) = loss_and_gradients(&fused, &dev);
        let (v_ref, g_ref) = loss_and_gradients(&fused.clone().assembled(), &dev);
        assert!(
            (v - v_ref).abs() <= 1e-9 * v_ref.abs(),
            "{what}: loss {v} vs {v_ref}"
        );
        let e = gradient_error(&g, &g_ref);
        eprintln!("{what}: loss {v:e}, gradient error {e:e}");
        assert!(e <= 1e-8, "{what}: gradient error {e:e}");
    }
}

/// The torque loss (inverse dynamics as one node: RNEA forward, Yᵀḡ and RNEA's derivatives
/// backward) against the assembly's residual M q̈ + c + ∂V/∂q − F on the same models, to the
/// same tolerances for the same reasons.
#[test]
fn multibody_torque_loss_and_gradients_equal_the_assembly() {
    let dev = f64_device().autodiff();
    let cases = [
        ("robots/ur5", "W-B"),
        ("ur5+rotors", "W-B"),
        ("arm4", "V"),
        ("arm4", "F"),
        ("tree+mimic", "W-B"),
        ("tree+mimic", "V"),
    ];
    for (robot, name) in cases {
        let t = urdf(robot);
        let (n, m) = (t.n(), t.m());
        let fused = perturb(&model(name, Some(t), n, m, 5, &dev), &dev);
        let what = format!("{robot} {name} torque");
        let torque = |model: &Model| {
            let (v, g) = random_torque_loss_and_gradients(model, &dev, 12);
            (v, g.concat())
        };
        let (v, g) = torque(&fused);
        let (v_ref, g_ref) = torque(&fused.clone().assembled());
        assert!(
            (v - v_ref).abs() <= 1e-9 * v_ref.abs(),
            "{what}: loss {v} vs {v_ref}"
        );
        let e = gradient_error(&g, &g_ref);
        eprintln!("{what}: loss {v:e}, gradient error {e:e}");
        assert!(e <= 1e-8, "{what}: gradient error {e:e}");
    }
}

/// The op runs on every backend graybox selects: NdArray gives Flex's loss and gradients (the
/// same f64 host code on both; only the tensors' round trip differs, so to rounding).
#[test]
fn multibody_op_on_ndarray_equals_flex() {
    let t = urdf("tree+mimic");
    let (n, m) = (t.n(), t.m());
    let on = |dev: Device| {
        let dev = dev.autodiff();
        let model = perturb(&model("W-B", Some(t.clone()), n, m, 5, &dev), &dev);
        assert!(model.is_multibody());
        loss_and_gradients(&model, &dev)
    };
    let (v, g) = on(f64_device());
    let (v_nd, g_nd) = on(device(Backend::Ndarray, Precision::F64).expect("f64 ndarray"));
    assert!((v - v_nd).abs() <= 1e-12 * v.abs(), "loss {v} vs {v_nd}");
    let e = gradient_error(&g_nd, &g);
    assert!(e <= 1e-12, "gradient error {e:e}");
}
