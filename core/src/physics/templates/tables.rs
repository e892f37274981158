//! The built-in templates' parameters and the combinations of them the data can pin down.

use std::borrow::Cow;

use super::Combination;
use crate::physics::params::{ParamInfo, Part};

use Part::{Forces as F, Mass as M, Potential as V};

pub(super) const fn p(
    name: &'static str,
    default: f64,
    positive: bool,
    used_by: &'static [Part],
) -> ParamInfo {
    ParamInfo {
        name: Cow::Borrowed(name),
        default,
        positive,
        min: None,
        max: None,
        fixed: false,
        used_by: Cow::Borrowed(used_by),
    }
}

pub(super) const DOUBLE_PENDULUM: &[ParamInfo] = &[
    p("m1", 10.0, true, &[M, V]),
    p("m2", 10.0, true, &[M, V]),
    p("l1", 1.0, true, &[M, V]),
    p("l2", 1.0, true, &[M, V]),
    p("g", 10.0, true, &[V]),
    p("b1", 1.0, false, &[F]),
    p("b2", 1.0, false, &[F]),
    p("eta1", -0.5, false, &[F]),
    p("eta2", -0.5, false, &[F]),
];

pub(super) const PENDULUM: &[ParamInfo] = &[
    p("m", 1.0, true, &[M, V]),
    p("l", 1.0, true, &[M, V]),
    p("g", 10.0, true, &[V]),
    p("b", 1.0, false, &[F]),
    p("eta", -0.1, false, &[F]),
];

pub(super) const CARTPOLE: &[ParamInfo] = &[
    p("mc", 1.0, true, &[M]),
    p("mp", 0.5, true, &[M, V]),
    p("l", 1.0, true, &[M, V]),
    p("g", 10.0, true, &[V]),
    p("b", 1.0, false, &[F]),
    p("eta_x", -0.1, false, &[F]),
    p("eta_th", -0.1, false, &[F]),
];

macro_rules! combo {
    ($name:literal, [$($part:ident),*], |$v:ident| $e:expr) => {
        Combination { name: $name, needs: &[$($part),*], eval: |$v| $e }
    };
}

pub(super) const DOUBLE_PENDULUM_COMBOS: &[Combination] = &[
    combo!("m1/m2", [M], |v| v("m1") / v("m2")),
    combo!("l1/l2", [M], |v| v("l1") / v("l2")),
    combo!("g/l1", [M, V], |v| v("g") / v("l1")),
    combo!("b1/(m1*l1^2)", [M, F], |v| v("b1")
        / (v("m1") * v("l1").powi(2))),
    combo!("b2/(m1*l1^2)", [M, F], |v| v("b2")
        / (v("m1") * v("l1").powi(2))),
    combo!("eta1/(m1*l1^2)", [M, F], |v| v("eta1")
        / (v("m1") * v("l1").powi(2))),
    combo!("eta2/(m1*l1^2)", [M, F], |v| v("eta2")
        / (v("m1") * v("l1").powi(2))),
    combo!("b1/b2", [F], |v| v("b1") / v("b2")),
    combo!("eta1/b1", [F], |v| v("eta1") / v("b1")),
    combo!("eta2/b2", [F], |v| v("eta2") / v("b2")),
];

pub(super) const PENDULUM_COMBOS: &[Combination] = &[
    combo!("g/l", [M, V], |v| v("g") / v("l")),
    combo!("b/(m*l^2)", [M, F], |v| v("b") / (v("m") * v("l").powi(2))),
    combo!("eta/(m*l^2)", [M, F], |v| v("eta")
        / (v("m") * v("l").powi(2))),
    combo!("eta/b", [F], |v| v("eta") / v("b")),
];

pub(super) const CARTPOLE_COMBOS: &[Combination] = &[
    combo!("mc/mp", [M], |v| v("mc") / v("mp")),
    combo!("l", [M], |v| v("l")),
    combo!("g", [M, V], |v| v("g")),
    combo!("b/mp", [M, F], |v| v("b") / v("mp")),
    combo!("eta_x/mp", [M, F], |v| v("eta_x") / v("mp")),
    combo!("eta_th/mp", [M, F], |v| v("eta_th") / v("mp")),
    combo!("eta_x/b", [F], |v| v("eta_x") / v("b")),
];

pub(super) const PLANAR_BODY: &[ParamInfo] = &[
    p("m", 1.0, true, &[M, V]),
    p("I", 0.1, true, &[M]),
    p("d", 0.2, false, &[M, V]),
    p("g", 9.81, true, &[V]),
    p("eta_xy", -0.1, false, &[F]),
    p("eta_th", -0.05, false, &[F]),
];

pub(super) const PLANAR_BODY_COMBOS: &[Combination] = &[
    combo!("m*d", [M], |v| v("m") * v("d")),
    combo!("I+m*d^2", [M], |v| v("I") + v("m") * v("d").powi(2)),
    combo!("m*g", [V], |v| v("m") * v("g")),
];
