//! How stiff a template's velocity forces make it near rest, against an explicit integrator's
//! step (docs/robots.md#joint-forces). Linearised in q̇ at rest, M q̈ = F(q, q̇, u) gives
//! q̈ ≈ −M⁻¹ D q̇ with D = −∂F/∂q̇ at q̇ = 0: velocities decay at the rates λ of D v = λ M v
//! (D's symmetric part: its antisymmetric, gyroscopic part only turns them), the fastest in
//! the time constant τ = 1/λ_max. For a URDF joint D_ii = d_i + f_i/ε, so a Coulomb friction
//! f on a light link is very stiff: f/ε with ε = 0.01 is 100 f.
//!
//! The criterion is λ_max Δt ≤ `limit(integrator)`: about 70% of the integrator's stability
//! edge on the negative real axis, where its step still damps the fastest mode without turning
//! its sign. RK4's edge is 2.785 (its amplification R(x) = 1 + x + x²/2 + x³/6 + x⁴/24 reaches
//! 1 there, so a mode at the edge no longer decays at all); R(−2) = 1/3. Euler's and midpoint's
//! edge is 2; R(−1) = 0 and ½. Past the limit a Coulomb friction chatters around q̇ = 0 by up to
//! f (M⁻¹)ᵢᵢ Δt per step (tanh saturates, so it need not diverge), and a stiff damping diverges.
//! The recommended ε puts λ_max Δt at the limit: measured on a UR5 against Pinocchio with the
//! sharp law at a fine step, it is closer to that law than ε = 0.01 is (which chatters), in one
//! step and over a coast to rest, and steps its own law to a fifth of the chatter; what it
//! loses is sticking (bench-results/2026-11-26-coulomb-stiffness.md).

use super::dual::{Dual, groups};
use super::dynamics::constants;
use super::eigen::symmetric_eigen;
use super::integrator::Integrator;
use super::templates::Template;
use crate::linalg::cholesky::{Square, StdSum, factor_rows};

/// The largest λ_max Δt `integrator` is given (module docs).
pub fn limit(integrator: Integrator) -> f64 {
    match integrator {
        Integrator::Rk4 => 2.0,
        Integrator::Euler | Integrator::Midpoint => 1.0,
    }
}

/// Where `integrator` stops being stable for a real negative λΔt.
fn edge(integrator: Integrator) -> f64 {
    match integrator {
        Integrator::Rk4 => 2.785,
        Integrator::Euler | Integrator::Midpoint => 2.0,
    }
}

/// The fastest decay near rest over the configurations looked at.
#[derive(Debug, Clone, PartialEq)]
pub struct Stiffness {
    /// 1/λ_max, s (∞ when nothing decays).
    pub tau: f64,
    /// The configuration where τ is shortest.
    pub q: Vec<f64>,
    /// The coordinate with the largest rate on its own there, D_ii (M⁻¹)_ii.
    pub coordinate: usize,
    /// For a URDF robot past the limit, the smallest `coulomb_eps` that makes λ_max Δt ≤ the
    /// limit at every configuration; None otherwise: within the limit, not a URDF, without
    /// friction, or when the damping alone is too stiff.
    pub eps: Option<f64>,
    /// For a URDF robot past the limit, the shortest time constant of the forces but the
    /// Coulomb friction's (its damping's), where it is past: no ε lengthens it.
    pub tau_without_coulomb: Option<f64>,
}

/// τ and its remedy for `t` at physical values `p`, step `dt` and largest accepted λ_max Δt
/// `limit`, at q = 0 and at `configurations`; a configuration whose M(q) is not positive
/// definite is skipped.
pub fn stiffness(
    t: &Template,
    p: &[f64],
    dt: f64,
    limit: f64,
    configurations: &[Vec<f64>],
) -> Stiffness {
    // The configuration at the origin (a rotation's is (1, 0)), nq wide; velocities nv.
    let (n, zero) = (t.n(), t.space().origin());
    let mut out = Stiffness {
        tau: f64::INFINITY,
        q: zero.clone(),
        coordinate: 0,
        eps: None,
        tau_without_coulomb: None,
    };
    // The Coulomb part of D at ε = 1 (f_i) and the ε now, for a URDF robot.
    let coulomb = match t {
        Template::Urdf(u) => Some((
            (0..n)
                .map(|i| u.joint_dynamics(p, i).1)
                .collect::<Vec<f64>>(),
            u.doc.coulomb_eps,
        )),
        _ => None,
    };
    let (mut eps, mut fastest_rest, mut curable) = (0.0f64, 0.0f64, true);
    let qs = std::iter::once(&zero).chain(configurations.iter().filter(|q| q.len() == zero.len()));
    let mass_at = t.mass_at(p);
    for q in qs {
        let mass = mass_at(q);
        let Some(l) = cholesky(&mass) else { continue };
        let d = symmetric(&velocity_stiffness(t, p, q));
        let rate = largest_eigenvalue(&congruence(&l, &d));
        if rate > 0.0 && 1.0 / rate < out.tau {
            let inv = inverse_diagonal(&l, n);
            let own = |i: usize| d[i][i] * inv[i];
            out.tau = 1.0 / rate;
            out.q = q.clone();
            out.coordinate = (0..n).fold(0, |b, i| if own(i) > own(b) { i } else { b });
        }
        // Where the step is within the limit any larger ε keeps it there (D only shrinks).
        if let Some((f, now)) = coulomb.as_ref().filter(|_| rate * dt > limit) {
            // λ_max(R + C/ε) ≤ λ_max(R) + λ_max(C)/ε (Rayleigh quotients add), with C the
            // Coulomb part at ε = 1 and R the rest: ε ≥ λ_C Δt / (limit − λ_R Δt) is enough.
            let c: Vec<Vec<f64>> = diagonal(f);
            let r: Vec<Vec<f64>> = (0..n)
                .map(|i| (0..n).map(|j| d[i][j] - c[i][j] / now).collect())
                .collect();
            let (lc, lr) = (
                largest_eigenvalue(&congruence(&l, &c)),
                largest_eigenvalue(&congruence(&l, &r)),
            );
            fastest_rest = fastest_rest.max(lr);
            if lr * dt < limit && lc > 0.0 {
                eps = eps.max(lc * dt / (limit - lr * dt));
            } else {
                curable = false;
            }
        }
    }
    if coulomb.is_some() && fastest_rest > 0.0 {
        out.tau_without_coulomb = Some(1.0 / fastest_rest);
    }
    out.eps = (curable && eps > 0.0).then_some(eps);
    out
}

/// What to tell a user when λ_max Δt exceeds `integrator`'s limit, else None.
pub fn warning(
    t: &Template,
    p: &[f64],
    dt: f64,
    integrator: Integrator,
    configurations: &[Vec<f64>],
) -> Option<String> {
    let limit = limit(integrator);
    let s = stiffness(t, p, dt, limit, configurations);
    if dt <= limit * s.tau {
        return None;
    }
    let what = match t {
        Template::Urdf(_) => "joint",
        _ => "coordinate",
    };
    let head = format!(
        "the forces of template '{}' are too stiff for a step of {dt} s: near rest their fastest \
         time constant is {:.3e} s (at {}, mostly {what} '{}'), {:.1} times shorter than the \
         step, where {} takes at most {limit} (it is unstable beyond {}: the velocity chatters \
         or diverges)",
        t.name(),
        s.tau,
        configuration(&s.q),
        t.coordinates()[s.coordinate],
        dt / s.tau,
        integrator.name(),
        edge(integrator)
    );
    let step = format!("a step of at most {:.3e} s", limit * s.tau);
    Some(match (t, s.eps, s.tau_without_coulomb) {
        (Template::Urdf(u), Some(eps), _) => format!(
            "{head}: set coulomb_eps to at least {eps} (now {}: a smoother Coulomb friction that \
             this step resolves) — in the URDF file, <graybox coulomb_eps=\"{eps}\"/> inside \
             <robot>; in a template document, \"coulomb_eps\": {eps} — or take {step}",
            u.doc.coulomb_eps,
            eps = round_up(eps),
        ),
        (Template::Urdf(_), None, Some(rest)) if rest > s.tau => format!(
            "{head}: even without the Coulomb friction the damping's time constant is {rest:.3e} \
             s, which no coulomb_eps lengthens; take {step}, or at most {:.3e} s with a larger \
             coulomb_eps",
            limit * rest
        ),
        _ => format!("{head}: take {step}"),
    })
}

/// "q = 0", or the first values of q.
fn configuration(q: &[f64]) -> String {
    if q.iter().all(|&v| v == 0.0) {
        return "q = 0".into();
    }
    let shown: Vec<String> = q.iter().take(6).map(|v| format!("{v:.2}")).collect();
    let more = if q.len() > 6 { ", …" } else { "" };
    format!("q = ({}{more})", shown.join(", "))
}

/// −∂F/∂q̇ at (q, q̇ = 0, u = 0), by dual numbers in q̇.
pub fn velocity_stiffness(t: &Template, p: &[f64], q: &[f64]) -> Vec<Vec<f64>> {
    let n = t.n();
    let (zero, u) = (vec![0.0; n], constants(&vec![0.0; t.m()]));
    let mut rows = vec![Vec::with_capacity(n); n];
    for dirs in groups::<f64>(n) {
        let qd = Dual::seeded(&zero, &1.0, dirs.clone());
        let f: Vec<Dual<f64>> = t.forces(&constants(p), &constants(q), &qd, &u);
        for (row, fi) in rows.iter_mut().zip(&f) {
            row.extend((0..dirs.len()).map(|k| -fi.tangent(k).copied().unwrap_or(0.0)));
        }
    }
    rows
}

/// λ_max of D v = λ M v for symmetric D and M = L Lᵀ (`cholesky`).
pub fn fastest_rate(m: &[Vec<f64>], d: &[Vec<f64>]) -> Option<f64> {
    let l = cholesky(m)?;
    Some(largest_eigenvalue(&congruence(&l, &symmetric(d))))
}

/// x rounded up to two significant digits, as text (0.6312 → "0.64").
fn round_up(x: f64) -> String {
    let k = x.log10().floor() as i32 - 1;
    let scale = 10f64.powi(k);
    // 0.64 / 0.01 is 64.00000000000001: a last-bit excess is not a digit to round up.
    let digits = (x / scale * (1.0 - 1e-12)).ceil();
    format!("{:.*}", (-k).max(0) as usize, digits * scale)
}

fn diagonal(v: &[f64]) -> Vec<Vec<f64>> {
    (0..v.len())
        .map(|i| {
            (0..v.len())
                .map(|j| if i == j { v[i] } else { 0.0 })
                .collect()
        })
        .collect()
}

fn symmetric(d: &[Vec<f64>]) -> Vec<Vec<f64>> {
    (0..d.len())
        .map(|i| (0..d.len()).map(|j| 0.5 * (d[i][j] + d[j][i])).collect())
        .collect()
}

/// L with M = L Lᵀ, n×n row-major; None unless M is positive definite.
fn cholesky(m: &[Vec<f64>]) -> Option<Vec<f64>> {
    factor_rows(m).ok()
}

/// The first coordinate whose pivot fails when M is factored (M is not positive definite
/// there: a joint that moves no mass has a zero row), if any.
pub fn singular_coordinate(m: &[Vec<f64>]) -> Option<usize> {
    factor_rows(m).err()
}

/// L⁻¹ b.
fn forward(l: &[f64], b: &[f64]) -> Vec<f64> {
    let mut x = b.to_vec();
    crate::linalg::cholesky::forward(l, Square(b.len()), &mut x, 1, StdSum);
    x
}

/// L⁻¹ D L⁻ᵀ, whose eigenvalues are those of D v = λ L Lᵀ v.
fn congruence(l: &[f64], d: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = d.len();
    // Y = L⁻¹ D column by column; as D is symmetric, L⁻¹ D L⁻ᵀ = L⁻¹ Yᵀ.
    let y: Vec<Vec<f64>> = (0..n)
        .map(|j| forward(l, &(0..n).map(|i| d[i][j]).collect::<Vec<_>>()))
        .collect(); // y[j] is column j of Y
    let w: Vec<Vec<f64>> = (0..n)
        .map(|i| forward(l, &(0..n).map(|j| y[j][i]).collect::<Vec<_>>()))
        .collect(); // w[i] is column i of L⁻¹ Yᵀ
    symmetric(&w)
}

/// The diagonal of M⁻¹ = L⁻ᵀ L⁻¹: (M⁻¹)_ii = Σ_k (L⁻¹)_ki².
fn inverse_diagonal(l: &[f64], n: usize) -> Vec<f64> {
    let columns: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            forward(
                l,
                &(0..n)
                    .map(|k| f64::from(u8::from(k == i)))
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    columns
        .iter()
        .map(|c| c.iter().map(|v| v * v).sum())
        .collect()
}

/// The largest eigenvalue of a symmetric matrix (`eigen::symmetric_eigen`).
pub fn largest_eigenvalue(a: &[Vec<f64>]) -> f64 {
    symmetric_eigen(a)
        .0
        .into_iter()
        .fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Symmetric 2×2 and the tridiagonal (2, −1) 3×3 against their closed forms:
    /// (a + c)/2 + √(((a − c)/2)² + b²), and 2 + √2.
    #[test]
    fn the_largest_eigenvalue_is_the_closed_forms() {
        for (a, b, c) in [(2.0f64, 1.0, 3.0), (1e-3, -0.5, 40.0), (5.0, 0.0, -1.0)] {
            let want = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
            let got = largest_eigenvalue(&[vec![a, b], vec![b, c]]);
            assert!((got - want).abs() < 1e-12 * want.abs(), "{got} vs {want}");
        }
        let t = [
            vec![2.0, -1.0, 0.0],
            vec![-1.0, 2.0, -1.0],
            vec![0.0, -1.0, 2.0],
        ];
        let got = largest_eigenvalue(&t);
        assert!((got - (2.0 + 2f64.sqrt())).abs() < 1e-12, "{got}");
    }

    /// D v = λ M v for 2×2: the larger root of det(D − λM) = 0, a quadratic in λ.
    #[test]
    fn the_fastest_rate_is_the_generalized_eigenvalue() {
        let m = [vec![2.0f64, 0.7], vec![0.7, 0.5]];
        let d = [vec![3.0f64, 0.2], vec![0.2, 40.0]];
        // (d11 − λm11)(d22 − λm22) − (d12 − λm12)² = aλ² + bλ + c
        let a = m[0][0] * m[1][1] - m[0][1] * m[0][1];
        let b = -(d[0][0] * m[1][1] + d[1][1] * m[0][0]) + 2.0 * d[0][1] * m[0][1];
        let c = d[0][0] * d[1][1] - d[0][1] * d[0][1];
        let want = (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a);
        let got = fastest_rate(&m, &d).unwrap();
        assert!((got - want).abs() < 1e-12 * want, "{got} vs {want}");
        assert!(fastest_rate(&[vec![1.0, 2.0], vec![2.0, 1.0]], &d).is_none());
    }

    #[test]
    fn epsilons_are_rounded_up_to_two_digits() {
        assert_eq!(round_up(0.6312), "0.64");
        assert_eq!(round_up(0.64), "0.64");
        assert_eq!(round_up(0.0123), "0.013");
        assert_eq!(round_up(12.3), "13");
        assert_eq!(round_up(1234.0), "1300");
    }
}
