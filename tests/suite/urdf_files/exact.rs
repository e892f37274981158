//! Issue 28, item 10: links without mass and point masses. `graybox model` trains nothing, so
//! it takes the file's values as they are (no floors: those are for the trainable form), and
//! holding the robot at Pinocchio's gravity torque keeps it at rest.

use std::collections::BTreeMap;
use std::process::Command;

use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::physics::templates::Template;
use graybox::sim::TemplateSystem;
use serde_json::Value;

use crate::common::urdf::{fixture_path, flat_matrix, floats};

use super::{fixture, template};

/// `graybox model --template <file>.urdf`: the file written, and what stdout says.
fn graybox_model(name: &str) -> (ModelFile, Value) {
    let dir = std::env::temp_dir().join(format!("graybox-exact-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join(format!("{name}.gbx"));
    let run = Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args([
            "model",
            "--template",
            &fixture_path(name, "urdf"),
            "--dt",
            "0.01",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = serde_json::from_slice(&run.stdout).unwrap();
    (ModelFile::load(&out).unwrap(), stdout)
}

/// The point_masses robot's values as its file writes them, by hand: a massless gimbal, an arm
/// without `<inertial>` that carries a 0.5 kg point mass on a fixed joint (the body is the
/// point mass, at the fixed joint's origin), and a 0.2 kg point-mass slider.
fn file_values() -> BTreeMap<String, f64> {
    let mut v = BTreeMap::new();
    let moments = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
    let bodies: [(&str, f64, [f64; 3], [f64; 6]); 5] = [
        (
            "turret",
            1.0,
            [0.01, 0.0, 0.05],
            [0.004, 0.0, 0.0, 0.004, 0.0, 0.002],
        ),
        (
            "upper",
            0.7,
            [0.12, 0.0, 0.0],
            [0.0005, 0.0, 0.0, 0.004, 0.0, 0.004],
        ),
        ("gimbal", 0.0, [0.0; 3], [0.0; 6]),
        ("arm", 0.5, [0.1, 0.05, -0.05], [0.0; 6]),
        ("slider", 0.2, [0.0, 0.02, 0.0], [0.0; 6]),
    ];
    for (link, mass, com, inertia) in bodies {
        v.insert(format!("{link}.mass"), mass);
        for (axis, c) in ["com_x", "com_y", "com_z"].iter().zip(com) {
            v.insert(format!("{link}.{axis}"), c);
        }
        for (m, i) in moments.iter().zip(inertia) {
            v.insert(format!("{link}.{m}"), i);
        }
    }
    for joint in ["yaw", "pitch", "wrist_pitch", "wrist_roll", "slide"] {
        v.insert(format!("{joint}.damping"), 0.0);
        v.insert(format!("{joint}.friction"), 0.0);
    }
    v
}

/// The model's physical values are the file's, bit for bit, wherever they are read: what
/// `graybox model` prints, the file's `made`, the values the model evaluates, and its export
/// read back (the massless links written massless).
#[test]
fn graybox_model_keeps_the_files_values_exactly() {
    let (file, stdout) = graybox_model("point_masses");
    let want = file_values();
    let printed: BTreeMap<String, f64> =
        serde_json::from_value(stdout["physical_parameters"].clone()).unwrap();
    assert_eq!(printed, want);
    assert_eq!(file.made.as_ref().unwrap().physical_parameters, want);
    let t = file.config.template().unwrap().clone();
    let by_name = |values: Vec<f64>| -> BTreeMap<String, f64> {
        t.params()
            .iter()
            .map(|p| p.name.to_string())
            .zip(values)
            .collect()
    };
    assert_eq!(by_name(file.physical_values().unwrap()), want);
    assert_eq!(by_name(t.defaults()), want);
    let back = template(&file.urdf().unwrap());
    assert_eq!(by_name(back.defaults()), want);
}

/// At 50 states, u = Pinocchio's g(q) (`computeGeneralizedGravity`, scripts/urdf_fixtures.py)
/// holds the model of `graybox model` at rest: |q̈| ≤ 1e-12. Both are f64 evaluations of the
/// same bodies: g differs by rounding (a few 1e-16 of |g| ≤ 3.5 N·m) and the entries of M⁻¹
/// of these light bodies reach 3.2·10³, so q̈ is ~1e-13 (2e-13 measured). The floors
/// training needs (1e-6 kg on the gimbal 0.25 m out, a 1 mm spread on the point masses) move
/// q̈ by ~4e-4: they would fail it, as the file's values did before.
#[test]
fn graybox_model_holds_massless_links_at_rest_at_pinocchio_gravity_torque() {
    let (file, _) = graybox_model("point_masses");
    let t = file.config.template().unwrap().clone();
    let eval = Evaluator::from_file(&file).unwrap();
    let fx: Value = serde_json::from_str(
        &std::fs::read_to_string(fixture_path("point_masses", "json")).unwrap(),
    )
    .unwrap();
    let coords: Vec<String> = serde_json::from_value(fx["coordinates"].clone()).unwrap();
    assert_eq!(coords, t.coordinates());
    let values = file.physical_values().unwrap();
    let floored = TemplateSystem::new(
        t.clone(),
        t.physical_from_raw(&t.raw_from_physical(&values).unwrap()),
    );
    let (mut worst, mut worst_floored) = (0.0f64, 0.0f64);
    for state in fx["states"].as_array().unwrap() {
        let (q, g) = (floats(&state["q"]), floats(&state["g"]));
        let rest = vec![0.0; q.len()];
        let qdd = eval.accel(&q, &rest, &g);
        worst = qdd.iter().fold(worst, |w, a| w.max(a.abs()));
        let qdd = floored.acceleration(&q, &rest, &g);
        worst_floored = qdd.iter().fold(worst_floored, |w, a| w.max(a.abs()));
        // M(q) is Pinocchio's too (`crba`), to rounding.
        let m: Vec<f64> = t.mass(&values, &q).into_iter().flatten().collect();
        let m_ref: Vec<f64> = flat_matrix(&state["M"]);
        for (a, b) in m.iter().zip(&m_ref) {
            assert!((a - b).abs() < 1e-12, "M {m:?} vs {m_ref:?}");
        }
    }
    eprintln!("max |q̈| {worst:e}; with the training floors {worst_floored:e}");
    assert!(worst <= 1e-12, "max |q̈| {worst:e}");
    assert!(
        worst_floored > 1e-9,
        "the floors would not show: {worst_floored:e}"
    );
}

/// A robot without massless links is its file's too: arm4's `graybox model` values are the
/// template's defaults, bit for bit (no round trip through the trainable form).
#[test]
fn graybox_model_of_a_plain_robot_is_its_defaults() {
    let (file, _) = graybox_model("arm4");
    let t: Template = template(&fixture("arm4"));
    assert_eq!(file.physical_values().unwrap(), t.defaults());
}

/// Taken as it is, a joint that moves only a massless link has no dynamics (M has a zero row,
/// and Pinocchio's ABA gives NaN): `graybox model` and `simulate` say so naming the joint,
/// where they used to write NaN or fail on it later.
#[test]
fn a_joint_that_moves_no_mass_is_named() {
    let leaf = fixture("double_pendulum").replace(
        "</robot>",
        r#"<joint name="tip_joint" type="revolute"><origin xyz="0 0 -1"/>
           <parent link="rod2"/><child link="tip"/><axis xyz="0 1 0"/>
           <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
           <link name="tip"/></robot>"#,
    );
    let t = template(&leaf);
    match graybox::sim::parse_assignments(&t, None, "set") {
        Err(graybox::error::Error::Unprocessable { field, message }) => {
            assert_eq!(field, "template");
            assert!(message.contains("'tip_joint'"), "{message}");
        }
        other => panic!("expected a 422, got {other:?}"),
    }
    // With mass on the link the robot is fine.
    let massive = leaf.replace(
        r#"<link name="tip"/>"#,
        r#"<link name="tip"><inertial><origin xyz="0 0 -0.1"/><mass value="0.1"/>
           <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>"#,
    );
    graybox::sim::parse_assignments(&template(&massive), None, "set").unwrap();
}
