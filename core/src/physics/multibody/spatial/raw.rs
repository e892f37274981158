//! The raw form θ of a body's inertia (docs/robots.md#physically-consistent-inertia; Wensing,
//! Kim & Slotine 2017; Rucker & Wensing 2022): the pseudo-inertia J = [[Σ, h], [hᵀ, m]] with
//! Σ = ½ tr(Ī) 𝟙 − Ī is positive definite exactly when the body is physically realisable, and
//! training moves ten unconstrained values θ = (α, d₁, d₂, d₃, s₁₂, s₁₃, s₂₃, t₁, t₂, t₃) through
//!
//!     U = e^α [[e^d₁, s₁₂, s₁₃, t₁], [0, e^d₂, s₂₃, t₂], [0, 0, e^d₃, t₃], [0, 0, 0, 1]],
//!     J = U Uᵀ,
//!
//! so every value the optimiser visits is a rigid body: m = e^{2α}, c = t, and Σ, Ī follow.

use super::M3;
use super::inertia::{Inertial, PER_BODY};
use crate::error::{Error, Result};
use crate::physics::scalar::Scalar;

/// The smallest mass a body is given (kg) and the smallest second moment about its centre
/// of mass per unit mass (m², a spread of 1 mm): a link without `<inertial>`, a point mass or
/// a thin rod has a singular pseudo-inertia, outside the open set every θ maps to.
pub const MIN_MASS: f64 = 1e-6;
pub const MIN_SPREAD: f64 = 1e-6;

impl Inertial {
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
        let b = body_inertia(theta);
        Inertial {
            mass: b.mass,
            h: b.h,
            inertia: b.inertia,
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

/// R Rᵀ for R upper triangular with diagonal `d` and s = (s₁₂, s₁₃, s₂₃) above it, each row
/// extended by `extra`'s entry when there is one: R's zeros never enter and the lower
/// triangle is the upper's, so a tape records no node for them.
fn upper_gram<S: Scalar>(d: &[S; 3], s: &[S; 3], extra: Option<&[S; 3]>) -> M3<S> {
    let p = |x: &S, y: &S| x.clone() * y.clone();
    let [s12, s13, s23] = s;
    let mut upper = [
        p(&d[0], &d[0]) + p(s12, s12) + p(s13, s13),
        p(s12, &d[1]) + p(s13, s23),
        p(s13, &d[2]),
        p(&d[1], &d[1]) + p(s23, s23),
        p(s23, &d[2]),
        p(&d[2], &d[2]),
    ];
    if let Some(t) = extra {
        let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        for (u, (i, j)) in upper.iter_mut().zip(pairs) {
            *u = u.clone() + p(&t[i], &t[j]);
        }
    }
    let [g00, g01, g02, g11, g12, g22] = upper;
    [
        [g00, g01.clone(), g02.clone()],
        [g01, g11, g12.clone()],
        [g02, g12, g22],
    ]
}

/// m, h and Ī about the frame's origin for θ, over any scalar.
pub fn body_inertia<S: Scalar>(theta: &[S; 10]) -> Inertial<S> {
    let [a, d1, d2, d3, s12, s13, s23, t1, t2, t3] = theta.clone();
    let m = (a.clone() + a).exp();
    let t = [t1, t2, t3];
    // Σ = e^{2α} (rows · rows) of U / e^α on the 3×3 block.
    let rows = upper_gram(&[d1.exp(), d2.exp(), d3.exp()], &[s12, s13, s23], Some(&t));
    let sigma: M3<S> = rows.map(|r| r.map(|x| m.clone() * x));
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
    Inertial {
        h: t.map(|t| m.clone() * t),
        mass: m,
        inertia,
        at_com: None,
    }
}

/// θ = (α, d₁, d₂, d₃, s₁₂, s₁₃, s₂₃, t₁, t₂, t₃) → the raw order
/// (α, t₁, t₂, t₃, d₁, s₁₂, s₁₃, d₂, s₂₃, d₃).
pub fn raw_order(t: &[f64; 10]) -> [f64; 10] {
    [t[0], t[7], t[8], t[9], t[1], t[4], t[5], t[2], t[6], t[3]]
}

/// One body's physical values from its raw ones: m = e^{2α}, c = t, and with the factor
/// R = [[e^d₁, s₁₂, s₁₃], [0, e^d₂, s₂₃], [0, 0, e^d₃]] the second moment about the centre of
/// mass Σ_c = m R Rᵀ, so Ī_c = tr(Σ_c) 𝟙 − Σ_c (inertia.rs: J = U Uᵀ).
pub fn physical_of_raw<S: Scalar>(r: &[S]) -> [S; PER_BODY] {
    let [a, t1, t2, t3, d1, s12, s13, d2, s23, d3] =
        std::array::from_fn::<_, 10, _>(|k| r[k].clone());
    let m = (a.clone() + a).exp();
    let rows = upper_gram(&[d1.exp(), d2.exp(), d3.exp()], &[s12, s13, s23], None);
    let sigma = |i: usize, j: usize| m.clone() * rows[i][j].clone();
    let (s00, s11, s22) = (sigma(0, 0), sigma(1, 1), sigma(2, 2));
    let tr = s00.clone() + s11.clone() + s22.clone();
    [
        m.clone(),
        t1,
        t2,
        t3,
        tr.clone() - s00,
        -sigma(0, 1),
        -sigma(0, 2),
        tr.clone() - s11,
        -sigma(1, 2),
        tr - s22,
    ]
}
