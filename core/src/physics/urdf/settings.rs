//! graybox's settings of a robot beyond what URDF says: `coulomb_eps`, the ε of the Coulomb
//! term tanh(q̇/ε), given in the template document (`"coulomb_eps": 0.2`) or in the URDF
//! file itself (`<graybox coulomb_eps="0.2"/>` under `<robot>`), so that a robot file
//! carries what makes its friction steppable wherever it goes (a template upload, `--template
//! arm.urdf`); and the bound of its efforts' delay (`effort_delay`, docs/robots.md#effort-delay).

use super::tree::Tree;
use crate::error::{Error, Result};
use crate::physics::params::{PHYSICAL_MAX, POSITIVE_MIN};

/// The default ε of the Coulomb term tanh(q̇/ε) (`UrdfDoc::coulomb_eps`): 0.01 rad/s or m/s,
/// a smooth sign that is within 1% of ±1 beyond 0.03.
pub const COULOMB_EPS: f64 = 0.01;

fn bad(message: String) -> Error {
    Error::Unprocessable {
        field: "coulomb_eps".into(),
        message,
    }
}

/// 1/ε scales q̇ in f32 training too: no smaller ε than a positive parameter's.
pub fn check_coulomb_eps(eps: f64) -> Result<()> {
    if eps.is_finite() && (POSITIVE_MIN..=PHYSICAL_MAX).contains(&eps) {
        return Ok(());
    }
    Err(bad(format!(
        "must be a velocity in [{POSITIVE_MIN:e}, {PHYSICAL_MAX:e}] (rad/s or m/s, the scale of \
         the Coulomb term tanh(q̇/ε)), got {eps}"
    )))
}

/// The ε a robot runs with: the document's, else the file's `<graybox coulomb_eps>`, else
/// the default. A document and a file that both set it must agree (the default in a document
/// is its absence).
pub fn coulomb_eps(from_doc: f64, tree: &Tree) -> Result<f64> {
    let Some(in_file) = tree.coulomb_eps else {
        return Ok(from_doc);
    };
    if from_doc != COULOMB_EPS && from_doc != in_file {
        return Err(bad(format!(
            "the document says {from_doc} and the URDF's <graybox coulomb_eps> says \
             {in_file}: give it in one place"
        )));
    }
    check_coulomb_eps(in_file)?;
    Ok(in_file)
}

/// The longest effort delay a robot may be given a bound of, seconds: a log's clocks are
/// off by milliseconds; a second is a different signal, not a delay.
pub const EFFORT_DELAY_MAX: f64 = 1.0;

/// A delay's bound is a positive time up to `EFFORT_DELAY_MAX`.
pub fn check_effort_delay(bound: Option<f64>) -> Result<()> {
    match bound {
        Some(b) if !(b.is_finite() && b > 0.0 && b <= EFFORT_DELAY_MAX) => {
            Err(Error::Unprocessable {
                field: "effort_delay".into(),
                message: format!(
                    "must be the largest delay of the efforts behind the motion, seconds in \
                     (0, {EFFORT_DELAY_MAX}], got {b}"
                ),
            })
        }
        _ => Ok(()),
    }
}
