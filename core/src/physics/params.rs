//! A template's parameters: what each is ([`ParamInfo`]), which part of the manipulator
//! equation uses it ([`Part`]), and which values are physical, one rule for every place a
//! value enters (built-in and formula templates, URDF robots, a job's `init`).

use std::borrow::Cow;

/// Which white-box component a parameter or an identifiable combination belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    Mass,
    Potential,
    Forces,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ParamInfo {
    pub name: Cow<'static, str>,
    pub default: f64,
    /// Trained in log space so that the optimizer cannot make it negative.
    pub positive: bool,
    /// The smallest physical value it may take (None: no bound). Such a parameter is trained
    /// as itself and put back onto the bound after every optimizer step (projected gradient,
    /// `lower_bounds`): unlike a logarithm it can start at, and rest on, the bound. Only for
    /// a parameter whose raw value is its physical value (not `positive`, not a URDF body's).
    pub min: Option<f64>,
    /// The largest (None: no bound), kept as `min` is (a URDF robot's effort delay).
    pub max: Option<f64>,
    /// Known, not trained: kept at its starting value (a formula template's `fixed`).
    pub fixed: bool,
    pub used_by: Cow<'static, [Part]>,
}

impl ParamInfo {
    /// What is wrong with `v` given this parameter's bounds, if anything.
    pub fn out_of_bounds(&self, v: f64) -> Option<String> {
        match (self.min, self.max) {
            (Some(min), _) if v < min => Some(format!("must be ≥ {min}, got {v}")),
            (_, Some(max)) if v > max => Some(format!("must be ≤ {max}, got {v}")),
            _ => None,
        }
    }
}

/// Each raw parameter's bounds (lower, upper), in parameter order: a parameter's `min` below
/// and `max` above (±∞ where there is none), and for a fixed one its raw value `start` on
/// both sides; None when no parameter has any. Training projects onto them after every step: the physical
/// optimum under a bound is reached by clamping the raw value (equal to the physical one),
/// and a fixed value clamped onto itself never moves.
pub fn bounds(params: &[ParamInfo], start: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let bounded = |p: &ParamInfo| p.min.is_some() || p.max.is_some() || p.fixed;
    params.iter().any(bounded).then(|| {
        params
            .iter()
            .zip(start)
            .map(|(p, &v)| match p.fixed {
                true => (v, v),
                false => (
                    p.min.unwrap_or(f64::NEG_INFINITY),
                    p.max.unwrap_or(f64::INFINITY),
                ),
            })
            .unzip()
    })
}

/// Largest |value| of a physical parameter wherever it enters (a template document, a job's
/// `init`): SI values of real mechanisms are far below it, and larger ones (a mass of 1e308, a
/// parameter of 1e7) passed submission and then overflowed the first epoch's dynamics.
pub const PHYSICAL_MAX: f64 = 1e6;

/// Smallest value of a formula or built-in template's positive parameter: it is trained as
/// its logarithm, and M⁻¹ of a mass of 1e-320 overflows. URDF inertias have floors of their
/// own instead (`urdf::inertia`): real robots carry 1e-9 dummy inertias.
pub const POSITIVE_MIN: f64 = 1e-6;

/// What is wrong with `v` as a physical value (`positive`: a positive parameter's), if
/// anything.
pub fn physical_problem(v: f64, positive: bool) -> Option<String> {
    // Display writes 1e300 with all its digits.
    let got = if v == 0.0 || (1e-4..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    };
    if !(v.is_finite() && v.abs() <= PHYSICAL_MAX) {
        return Some(format!(
            "must be a number with |value| ≤ {PHYSICAL_MAX:e}, got {got}"
        ));
    }
    if positive && v <= 0.0 {
        return Some(format!("must be > 0 for a positive parameter, got {got}"));
    }
    if positive && v < POSITIVE_MIN {
        return Some(format!(
            "must be at least {POSITIVE_MIN:e} for a positive parameter, got {got}"
        ));
    }
    None
}
