//! A body's inertia in every form graybox uses, and the conversions between them
//! (docs/robots.md#inertia-forms, where the forms have one table):
//!
//! - [`Inertial`]: m, h = m c and Ī about the body frame's origin, in f64 (what a producer
//!   such as the URDF reader builds a `Model` from; `from_com` takes URDF's own form);
//! - [`BodyInertia`]: the same over any scalar (a URDF template's M(q) and V(q) over
//!   trainable values, `rnea::crba_with`);
//! - [`Inertia`]: the symmetric 6×6 spatial inertia [[A, B], [Bᵀ, C]] the algorithms take;
//! - the standard parameters π = (m, m c, Ī about the origin), ten per body, linear in τ
//!   (`Inertia::standard`, `Inertia::of_standard`);
//! - the physical values (m, c, Ī about c), ten per body, which a template's parameters are
//!   named by (`of_physical`, `body_of_physical`, `standard_of_physical`);
//! - the raw values θ the optimiser moves (`raw.rs`).

use super::{Force, M3, Motion, V3, add, cdot, lift3x3, mat_op, mtv, mv};
use crate::physics::scalar::Scalar;

/// Values per body in every ten-value form (π, the physical values, θ).
pub const PER_BODY: usize = 10;

/// π's names after the link's, in its order.
pub const STANDARD_NAMES: [&str; PER_BODY] = [
    "mass", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
];

/// A symmetric 6×6 spatial inertia [[A, B], [Bᵀ, C]]: the force I m = (A ω + B v, Bᵀ ω + C v).
#[derive(Clone, Debug)]
pub struct Inertia<S> {
    pub a: M3<S>,
    pub b: M3<S>,
    pub c: M3<S>,
}

impl Inertia<f64> {
    /// A rigid body of mass m, first moment h = m c and rotational inertia Ī about the
    /// frame's origin: A = Ī, B = [h]×, C = m 𝟙.
    pub fn rigid(mass: f64, h: &[f64; 3], inertia: &[[f64; 3]; 3]) -> Self {
        let b = [[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]];
        let c = std::array::from_fn(|i| std::array::from_fn(|j| if i == j { mass } else { 0.0 }));
        Self { a: *inertia, b, c }
    }

    /// A body of standard parameters π (m, h, Ixx, Ixy, Ixz, Iyy, Iyz, Izz).
    pub fn of_standard(p: &[f64]) -> Self {
        let i = [[p[4], p[5], p[6]], [p[5], p[7], p[8]], [p[6], p[8], p[9]]];
        Self::rigid(p[0], &[p[1], p[2], p[3]], &i)
    }

    /// The mass, from C = m 𝟙.
    pub fn mass(&self) -> f64 {
        self.c[0][0]
    }

    /// The first moment h, from B = [h]×.
    pub fn first_moment(&self) -> [f64; 3] {
        [self.b[2][1], self.b[0][2], self.b[1][0]]
    }

    /// The body's standard parameters π.
    pub fn standard(&self) -> [f64; PER_BODY] {
        let (a, [hx, hy, hz]) = (&self.a, self.first_moment());
        [
            self.mass(),
            hx,
            hy,
            hz,
            a[0][0],
            a[0][1],
            a[0][2],
            a[1][1],
            a[1][2],
            a[2][2],
        ]
    }

    pub fn lift<S: Scalar>(&self, zero: &S) -> Inertia<S> {
        Inertia {
            a: lift3x3(&self.a, zero),
            b: lift3x3(&self.b, zero),
            c: lift3x3(&self.c, zero),
        }
    }

    /// I m for a constant I (zero entries skipped).
    pub fn apply_const<S: Scalar>(&self, m: &Motion<S>, zero: &S) -> Force<S> {
        let row = |r: &[f64; 3], x: &V3<S>| cdot(r, x, zero);
        let bt = |k: usize| [self.b[0][k], self.b[1][k], self.b[2][k]];
        Force {
            n: std::array::from_fn(|k| row(&self.a[k], &m.w) + row(&self.b[k], &m.v)),
            f: std::array::from_fn(|k| row(&bt(k), &m.w) + row(&self.c[k], &m.v)),
        }
    }
}

impl<S: Scalar> Inertia<S> {
    pub fn apply(&self, m: &Motion<S>) -> Force<S> {
        Force {
            n: add(&mv(&self.a, &m.w), &mv(&self.b, &m.v)),
            f: add(&mtv(&self.b, &m.w), &mv(&self.c, &m.v)),
        }
    }

    pub fn add_assign(&mut self, o: &Self) {
        self.a = mat_op(&self.a, &o.a, |x, y| x + y);
        self.b = mat_op(&self.b, &o.b, |x, y| x + y);
        self.c = mat_op(&self.c, &o.c, |x, y| x + y);
    }

    /// I − u uᵀ / d for a force-like column u = (uₙ, u_f).
    pub fn minus_outer(&self, u: &Force<S>, d: &S) -> Self {
        let (un, uf) = (
            u.n.clone().map(|x| x / d.clone()),
            u.f.clone().map(|x| x / d.clone()),
        );
        let outer = |m: &M3<S>, x: &V3<S>, y: &V3<S>| -> M3<S> {
            std::array::from_fn(|i| {
                std::array::from_fn(|j| m[i][j].clone() - x[i].clone() * y[j].clone())
            })
        };
        Self {
            a: outer(&self.a, &u.n, &un),
            b: outer(&self.b, &u.n, &uf),
            c: outer(&self.c, &u.f, &uf),
        }
    }
}

impl Inertial {
    /// Its spatial inertia.
    pub fn spatial(&self) -> Inertia<f64> {
        Inertia::rigid(self.mass, &self.h, &self.inertia)
    }
}

/// A body's inertial parameters in its own frame: m, h = m c, and Ī about the frame's origin.
#[derive(Debug, Clone, PartialEq)]
pub struct Inertial {
    pub mass: f64,
    pub h: [f64; 3],
    pub inertia: [[f64; 3]; 3],
    /// The centre of mass and the inertia about it as given (URDF's form), when the body was
    /// made from them: `com` and `inertia_at_com` return them as they are, where h/m and the
    /// parallel-axis difference would round (m c / m ≠ c for one (m, c) in ten), so that a
    /// file's values come back exactly (docs/robots.md#physically-consistent-inertia).
    pub(super) at_com: Option<([f64; 3], [[f64; 3]; 3])>,
}

/// The same over any scalar (the trainable form's image).
pub struct BodyInertia<S> {
    pub mass: S,
    pub h: V3<S>,
    pub inertia: M3<S>,
}

impl Inertial {
    pub const ZERO: Inertial = Inertial {
        mass: 0.0,
        h: [0.0; 3],
        inertia: [[0.0; 3]; 3],
        at_com: None,
    };

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

/// A body of physical values (m, c, Ī about c).
pub fn of_physical(v: &[f64]) -> Inertial {
    let ic = [[v[4], v[5], v[6]], [v[5], v[7], v[8]], [v[6], v[8], v[9]]];
    Inertial::from_com(v[0], [v[1], v[2], v[3]], ic)
}

/// A body of physical values over any scalar: h = m c, Ī_o = Ī_c + m(|c|² 𝟙 − c cᵀ).
pub fn body_of_physical<S: Scalar>(v: &[S]) -> BodyInertia<S> {
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
    BodyInertia {
        h: c.clone().map(|ci| m.clone() * ci),
        mass: m,
        inertia,
    }
}

/// π of a body from its physical values, over any scalar (Burn tensors in training).
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
