//! A body's inertia in every form graybox uses, and the conversions between them
//! (docs/robots.md#inertia-forms, where the forms have one table):
//!
//! - [`Inertial`]: m, h = m c and Ī about the body frame's origin, over any scalar (f64 is
//!   what a producer such as the URDF reader builds a `Model` from, `from_com` taking URDF's
//!   own form; dual numbers, jets and batch columns are a template's trainable values);
//! - the 6×6 spatial inertia [[Ī, [h]×], [[h]×ᵀ, m 𝟙]] the algorithms take, in the root
//!   frame (`six::inertia_to_root`);
//! - the standard parameters π = (m, m c, Ī about the origin), ten per body, linear in τ
//!   (`Inertial::standard`, `Inertial::of_standard`);
//! - the physical values (m, c, Ī about c), ten per body, which a template's parameters are
//!   named by (`of_physical`, `body_of_physical`, `standard_of_physical`);
//! - the raw values θ the optimiser moves (`raw.rs`).

use super::{M3, V3, lift3x3};
use crate::physics::scalar::Scalar;

/// Values per body in every ten-value form (π, the physical values, θ).
pub const PER_BODY: usize = 10;

/// π's names after the link's, in its order.
pub const STANDARD_NAMES: [&str; PER_BODY] = [
    "mass", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
];

/// A body's inertial parameters in its own frame: m, h = m c, and Ī about the frame's origin;
/// in f64 (a `Model`'s bodies) or over any scalar (a template's trainable values).
#[derive(Debug, Clone, PartialEq)]
pub struct Inertial<S = f64> {
    pub mass: S,
    pub h: V3<S>,
    pub inertia: M3<S>,
    /// The centre of mass and the inertia about it as given (URDF's form), when the body was
    /// made from them: `com` and `inertia_at_com` return them as they are, where h/m and the
    /// parallel-axis difference would round (m c / m ≠ c for one (m, c) in ten), so that a
    /// file's values come back exactly (docs/robots.md#physically-consistent-inertia).
    pub(super) at_com: Option<([f64; 3], [[f64; 3]; 3])>,
}

impl Inertial {
    pub const ZERO: Inertial = Inertial {
        mass: 0.0,
        h: [0.0; 3],
        inertia: [[0.0; 3]; 3],
        at_com: None,
    };

    /// A body of standard parameters π (m, h, Ixx, Ixy, Ixz, Iyy, Iyz, Izz).
    pub fn of_standard(p: &[f64]) -> Self {
        Self {
            mass: p[0],
            h: [p[1], p[2], p[3]],
            inertia: [[p[4], p[5], p[6]], [p[5], p[7], p[8]], [p[6], p[8], p[9]]],
            at_com: None,
        }
    }

    /// The body's standard parameters π.
    pub fn standard(&self) -> [f64; PER_BODY] {
        let (i, [hx, hy, hz]) = (&self.inertia, self.h);
        [
            self.mass, hx, hy, hz, i[0][0], i[0][1], i[0][2], i[1][1], i[1][2], i[2][2],
        ]
    }

    /// The same body over another scalar (constants: a `Model`'s f64 bodies where an
    /// algorithm runs over dual numbers, jets or batch columns).
    pub fn lift<S: Scalar>(&self, zero: &S) -> Inertial<S> {
        Inertial {
            mass: zero.lift(self.mass),
            h: self.h.map(|x| zero.lift(x)),
            inertia: lift3x3(&self.inertia, zero),
            at_com: None,
        }
    }

    /// No mass and no inertia at all (a link without `<inertial>`).
    pub fn is_nothing(&self) -> bool {
        self.mass == 0.0 && self.h == [0.0; 3] && self.inertia.iter().flatten().all(|&v| v == 0.0)
    }

    /// This body less `o` (both in this frame).
    pub fn minus(&self, o: &Inertial) -> Inertial {
        if o.is_nothing() {
            return self.clone();
        }
        Inertial {
            mass: self.mass - o.mass,
            h: std::array::from_fn(|i| self.h[i] - o.h[i]),
            inertia: std::array::from_fn(|i| {
                std::array::from_fn(|j| self.inertia[i][j] - o.inertia[i][j])
            }),
            at_com: None,
        }
    }

    /// From URDF's form: mass, the centre of mass c and the inertia about it in this frame.
    pub fn from_com(mass: f64, c: [f64; 3], i_com: [[f64; 3]; 3]) -> Self {
        // Parallel axes: Ī_o = Ī_c + m (|c|² 𝟙 − c cᵀ).
        let c2 = c.iter().map(|v| v * v).sum::<f64>();
        let inertia = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                i_com[i][j] + mass * (if i == j { c2 } else { 0.0 } - c[i] * c[j])
            })
        });
        Self {
            mass,
            h: c.map(|v| mass * v),
            inertia,
            at_com: Some((c, i_com)),
        }
    }

    /// The centre of mass; the origin for a massless body, which has none (URDF files write
    /// their massless links so).
    pub fn com(&self) -> [f64; 3] {
        if let Some((c, _)) = self.at_com {
            return c;
        }
        if self.mass == 0.0 {
            return [0.0; 3];
        }
        self.h.map(|v| v / self.mass)
    }

    /// The inertia about the centre of mass.
    pub fn inertia_at_com(&self) -> [[f64; 3]; 3] {
        if let Some((_, i)) = self.at_com {
            return i;
        }
        let c = self.com();
        let c2 = c.iter().map(|v| v * v).sum::<f64>();
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                self.inertia[i][j] - self.mass * (if i == j { c2 } else { 0.0 } - c[i] * c[j])
            })
        })
    }

    /// Two bodies rigidly joined (both in this frame).
    pub fn plus(&self, o: &Inertial) -> Inertial {
        if self.is_nothing() {
            return o.clone();
        }
        if o.is_nothing() {
            return self.clone();
        }
        Inertial {
            mass: self.mass + o.mass,
            h: std::array::from_fn(|i| self.h[i] + o.h[i]),
            inertia: std::array::from_fn(|i| {
                std::array::from_fn(|j| self.inertia[i][j] + o.inertia[i][j])
            }),
            at_com: None,
        }
    }

    /// This body seen from a frame in which its frame sits at `pos` with orientation `rot`.
    pub fn transformed(&self, rot: &[[f64; 3]; 3], pos: &[f64; 3]) -> Inertial {
        // A massless link has no centre of mass; its moments (if any) do not move with it.
        let massless = self.mass == 0.0;
        let c = if massless { [0.0; 3] } else { self.com() };
        let c_new: [f64; 3] =
            std::array::from_fn(|i| pos[i] + (0..3).map(|k| rot[i][k] * c[k]).sum::<f64>());
        let ic = if massless {
            self.inertia
        } else {
            self.inertia_at_com()
        };
        // R Ī_c Rᵀ
        let rotated = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                (0..3)
                    .flat_map(|k| (0..3).map(move |l| (k, l)))
                    .map(|(k, l)| rot[i][k] * ic[k][l] * rot[j][l])
                    .sum::<f64>()
            })
        });
        Inertial::from_com(self.mass, c_new, rotated)
    }
}

impl Inertial {
    /// The ten physical values (m, c, Ī about c: xx, xy, xz, yy, yz, zz), `of_physical`'s
    /// inverse.
    pub fn physical(&self) -> [f64; PER_BODY] {
        physical_values(self.mass, self.com(), &self.inertia_at_com())
    }
}

/// The ten physical values of a mass, a centre of mass and an inertia about it.
pub fn physical_values(mass: f64, c: [f64; 3], ic: &[[f64; 3]; 3]) -> [f64; PER_BODY] {
    [
        mass, c[0], c[1], c[2], ic[0][0], ic[0][1], ic[0][2], ic[1][1], ic[1][2], ic[2][2],
    ]
}

/// A body of physical values (m, c, Ī about c).
pub fn of_physical(v: &[f64]) -> Inertial {
    let ic = [[v[4], v[5], v[6]], [v[5], v[7], v[8]], [v[6], v[8], v[9]]];
    Inertial::from_com(v[0], [v[1], v[2], v[3]], ic)
}

/// A body of physical values over any scalar: h = m c, Ī_o = Ī_c + m(|c|² 𝟙 − c cᵀ).
pub fn body_of_physical<S: Scalar>(v: &[S]) -> Inertial<S> {
    let m = v[0].clone();
    let c = [v[1].clone(), v[2].clone(), v[3].clone()];
    let ic = [
        [&v[4], &v[5], &v[6]],
        [&v[5], &v[7], &v[8]],
        [&v[6], &v[8], &v[9]],
    ];
    let c2 = c[0].square() + c[1].square() + c[2].square();
    let inertia = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let shift = if i == j {
                c2.clone() - c[i].square()
            } else {
                -(c[i].clone() * c[j].clone())
            };
            ic[i][j].clone() + m.clone() * shift
        })
    });
    Inertial {
        h: c.clone().map(|ci| m.clone() * ci),
        mass: m,
        inertia,
        at_com: None,
    }
}

/// π of a body from its physical values, over any scalar (the tape's values in training).
pub fn standard_of_physical<S: Scalar>(v: &[S]) -> [S; PER_BODY] {
    let b = body_of_physical(v);
    let [hx, hy, hz] = b.h;
    let i = |r: usize, c: usize| b.inertia[r][c].clone();
    [
        b.mass,
        hx,
        hy,
        hz,
        i(0, 0),
        i(0, 1),
        i(0, 2),
        i(1, 1),
        i(1, 2),
        i(2, 2),
    ]
}
