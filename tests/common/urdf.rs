//! The URDF fixtures (tests/fixtures/urdf: robots and the Pinocchio values written beside them
//! by scripts/urdf_fixtures.py), read one way by every test binary that compares with them,
//! and the Jacobian form of a robot's M and V (`jacobian_form`): a reference of the multibody
//! algorithms written here, with forward kinematics of its own, so that it shares nothing with
//! them but the reader's tree.

use graybox::physics::dual::{Dual, Jet};
use graybox::physics::multibody::Inertial;
use graybox::physics::multibody::spatial::body_inertia;
use graybox::physics::scalar::Scalar;
use graybox::physics::urdf::Tree;
use serde_json::Value;

use super::jacobian_form;

/// The path of fixture `name` (e.g. "arm4", "robots/panda") with extension `ext`.
pub fn fixture_path(name: &str, ext: &str) -> String {
    format!(
        "{}/tests/fixtures/urdf/{name}.{ext}",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// A robot's tree and its Pinocchio fixture.
pub fn fixture(name: &str) -> (Tree, Value) {
    let urdf = std::fs::read_to_string(fixture_path(name, "urdf")).unwrap();
    let json = std::fs::read_to_string(fixture_path(name, "json")).unwrap();
    (
        Tree::parse(&urdf, graybox::physics::MAX_DOF).unwrap(),
        serde_json::from_str(&json).unwrap(),
    )
}

/// A JSON matrix (an array of rows of numbers), row after row.
pub fn flat_matrix(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().flat_map(floats).collect()
}

/// A JSON array of numbers.
pub fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// A dual number wide enough for every fixture robot's q at once.
pub type Wide = Jet<64>;

/// M, g = ∂V/∂q and C q̇ (from ∂M/∂q: Σⱼₖ (∂ₖMᵢⱼ − ½ ∂ᵢMⱼₖ) q̇ⱼ q̇ₖ) at (q, q̇) of a robot's M
/// and V over dual numbers in q.
pub fn terms_of(
    q: &[f64],
    qd: &[f64],
    mass: impl Fn(&[Wide]) -> Vec<Vec<Wide>>,
    potential: impl Fn(&[Wide]) -> Wide,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = q.len();
    let qv: Vec<Wide> = Dual::seeded(q, &1.0, 0..n);
    let (m, v) = (mass(&qv), potential(&qv));
    let d = |x: &Wide, k: usize| x.tangent(k).copied().unwrap_or(0.0);
    let g = (0..n).map(|k| d(&v, k)).collect();
    let c = (0..n)
        .map(|i| {
            let mut s = 0.0;
            for j in 0..n {
                for k in 0..n {
                    s += (d(&m[i][j], k) - 0.5 * d(&m[j][k], i)) * qd[j] * qd[k];
                }
            }
            s
        })
        .collect();
    (m.iter().flatten().map(|x| x.v).collect(), g, c)
}

/// `terms_of` the Jacobian form for `inertias` (through θ, so the θ ↦ body map is checked
/// with it).
pub fn jacobian_terms(
    tree: &Tree,
    inertias: &[Inertial],
    gravity: &[f64; 3],
    q: &[f64],
    qd: &[f64],
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let bodies = |like: &Wide| -> Vec<Inertial<Wide>> {
        (inertias.iter())
            .map(|i| body_inertia(&i.theta().unwrap().map(|t| like.lift(t))))
            .collect()
    };
    terms_of(
        q,
        qd,
        |qv| jacobian_form::mass_matrix(tree, &bodies(&qv[0]), qv),
        |qv| jacobian_form::potential(tree, &bodies(&qv[0]), gravity, qv),
    )
}
