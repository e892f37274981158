//! Physically consistent inertial parameters (docs/robots.md#physically-consistent-inertia; Wensing, Kim & Slotine 2017;
//! Rucker & Wensing 2022). A body's mass m, first moment h = m c and rotational inertia Ī
//! about its frame's origin form the pseudo-inertia J = [[Σ, h], [hᵀ, m]] with
//! Σ = ½ tr(Ī) 𝟙 − Ī; the body is physically realisable exactly when J ≻ 0. Training moves
//! ten unconstrained values θ = (α, d₁, d₂, d₃, s₁₂, s₁₃, s₂₃, t₁, t₂, t₃) through
//!
//!     U = e^α [[e^d₁, s₁₂, s₁₃, t₁], [0, e^d₂, s₂₃, t₂], [0, 0, e^d₃, t₃], [0, 0, 0, 1]],
//!     J = U Uᵀ,
//!
//! so every value the optimiser visits is a rigid body: m = e^{2α}, c = t, and Σ, Ī follow.

use super::term::{C, Mat3, Term, V, Vec3};
use crate::error::{Error, Result};
use crate::physics::scalar::Scalar;

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
    at_com: Option<([f64; 3], [[f64; 3]; 3])>,
}

/// The same over any scalar (the trainable form's image).
pub struct BodyInertia<S> {
    pub mass: Term<S>,
    pub h: Vec3<S>,
    pub inertia: Mat3<S>,
}

/// The smallest mass a body is given (kg) and the smallest second moment about its centre
/// of mass per unit mass (m², a spread of 1 mm): a link without `<inertial>`, a point mass or
/// a thin rod has a singular pseudo-inertia, outside the open set every θ maps to.
pub const MIN_MASS: f64 = 1e-6;
pub const MIN_SPREAD: f64 = 1e-6;

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

    /// The pseudo-inertia J (4×4).
    pub fn pseudo(&self) -> [[f64; 4]; 4] {
        let tr = self.inertia[0][0] + self.inertia[1][1] + self.inertia[2][2];
        // Σ = ½ tr(Ī) 𝟙 − Ī, bordered by h and m.
        std::array::from_fn(|a| {
            std::array::from_fn(|b| match (a, b) {
                (3, 3) => self.mass,
                (3, k) | (k, 3) => self.h[k],
                _ if a == b => 0.5 * tr - self.inertia[a][b],
                _ => -self.inertia[a][b],
            })
        })
    }

    /// θ with J(θ) = this body's pseudo-inertia (the upper-triangular, "UL", Cholesky factor
    /// of J); an error when the body is not physically realisable.
    pub fn theta(&self) -> Result<[f64; 10]> {
        let u = ul_cholesky(&self.pseudo()).ok_or_else(|| {
            Error::invalid(
                "inertial",
                "is not physically consistent: the pseudo-inertia [[½tr(I)𝟙 − I, m c], \
                 [m cᵀ, m]] is not positive definite (a negative mass or principal moments \
                 that break the triangle inequality)",
            )
        })?;
        let ea = u[3][3];
        Ok([
            ea.ln(),
            (u[0][0] / ea).ln(),
            (u[1][1] / ea).ln(),
            (u[2][2] / ea).ln(),
            u[0][1] / ea,
            u[0][2] / ea,
            u[1][2] / ea,
            u[0][3] / ea,
            u[1][3] / ea,
            u[2][3] / ea,
        ])
    }

    /// The body for θ.
    pub fn from_theta(theta: &[f64; 10]) -> Inertial {
        let b = body_inertia::<f64>(&theta.map(V));
        let f = |t: &Term<f64>| match t {
            C(c) | V(c) => *c,
        };
        Inertial {
            mass: f(&b.mass),
            h: b.h.each_ref().map(f),
            inertia: b.inertia.each_ref().map(|r| r.each_ref().map(f)),
            at_com: None,
        }
    }

    /// This body made realisable when it is only just not: a mass below `MIN_MASS` is
    /// raised to it, and a second moment about the centre of mass below `MIN_SPREAD` per
    /// unit mass in some direction (a point mass, a thin rod) gets `MIN_SPREAD` added in
    /// every direction. A body that is clearly not physical is left as it is (and `theta`
    /// refuses it).
    pub fn regularised(&self) -> Inertial {
        if self.mass < 0.0 {
            return self.clone();
        }
        let mass = self.mass.max(MIN_MASS);
        let c = if self.mass > 0.0 {
            self.com()
        } else {
            [0.0; 3]
        };
        let ic = if self.mass > 0.0 {
            self.inertia_at_com()
        } else {
            [[0.0; 3]; 3]
        };
        let body = Inertial::from_com(mass, c, ic);
        // Σ_c = ½ tr(Ī_c) 𝟙 − Ī_c: the second moment about the centre of mass.
        let tr = ic[0][0] + ic[1][1] + ic[2][2];
        let sigma: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| if i == j { 0.5 * tr } else { 0.0 } - ic[i][j])
        });
        let floor = MIN_SPREAD * mass;
        let shifted = |by: f64| -> [[f64; 4]; 4] {
            let mut j = [[0.0; 4]; 4];
            for a in 0..3 {
                for b in 0..3 {
                    j[a][b] = sigma[a][b] - if a == b { by } else { 0.0 };
                }
            }
            j[3][3] = 1.0;
            j
        };
        let well_spread = ul_cholesky(&shifted(floor)).is_some();
        let nearly_physical = ul_cholesky(&shifted(-floor)).is_some();
        if well_spread || !nearly_physical {
            return body;
        }
        // Adding s 𝟙 to Σ_c adds 2s 𝟙 to Ī_c.
        let ic2 = std::array::from_fn(|i| {
            std::array::from_fn(|j| ic[i][j] + if i == j { 2.0 * floor } else { 0.0 })
        });
        Inertial::from_com(mass, c, ic2)
    }
}

/// J = U Uᵀ with U upper triangular and a positive diagonal; None unless J ≻ 0.
fn ul_cholesky(j: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut u = [[0.0; 4]; 4];
    for c in (0..4).rev() {
        let d = j[c][c] - (c + 1..4).map(|k| u[c][k] * u[c][k]).sum::<f64>();
        // NaN fails `d > 0.0` too.
        if !(d.is_finite() && d > 0.0) {
            return None;
        }
        u[c][c] = d.sqrt();
        for r in 0..c {
            u[r][c] = (j[r][c] - (c + 1..4).map(|k| u[r][k] * u[c][k]).sum::<f64>()) / u[c][c];
        }
    }
    Some(u)
}

/// m, h and Ī about the frame's origin for θ, over any scalar.
pub fn body_inertia<S: Scalar>(theta: &[Term<S>; 10]) -> BodyInertia<S> {
    let [a, d1, d2, d3, s12, s13, s23, t1, t2, t3] = theta.clone();
    let exp = |t: Term<S>| match t {
        C(c) => C(c.exp()),
        V(x) => V(x.exp()),
    };
    let m = exp(a.clone() + a);
    // Rows of U / e^α.
    let rows: [[Term<S>; 4]; 3] = [
        [exp(d1), s12, s13, t1.clone()],
        [C(0.0), exp(d2), s23, t2.clone()],
        [C(0.0), C(0.0), exp(d3), t3.clone()],
    ];
    let dot4 = |x: &[Term<S>; 4], y: &[Term<S>; 4]| {
        (0..4)
            .map(|k| x[k].clone() * y[k].clone())
            .reduce(|p, q| p + q)
            .expect("four terms")
    };
    // Σ = e^{2α} (rows · rows) on the 3×3 block.
    let sigma: Mat3<S> =
        std::array::from_fn(|i| std::array::from_fn(|j| m.clone() * dot4(&rows[i], &rows[j])));
    let tr = sigma[0][0].clone() + sigma[1][1].clone() + sigma[2][2].clone();
    let inertia = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            if i == j {
                tr.clone() - sigma[i][j].clone()
            } else {
                -sigma[i][j].clone()
            }
        })
    });
    BodyInertia {
        h: [t1, t2, t3].map(|t| m.clone() * t),
        mass: m,
        inertia,
    }
}
