//! Hermite–Simpson collocation in its separated form, with the inputs held over each interval
//! as the model's one-step map holds them (zero-order hold): interval k's input u_k drives f at
//! its start, its midpoint and its end, and its midpoint state x_c is a variable of its own.
//! Two defects per interval,
//!
//!   Simpson:  x_{k+1} − x_k − h/6 (f_s + 4 f_c + f_e) = 0
//!   Hermite:  x_c − (x_k + x_{k+1})/2 − h/8 (f_s − f_e) = 0,
//!
//! f_s = f(x_k, u_k), f_c = f(x_c, u_k), f_e = f(x_{k+1}, u_k). Separated rather than
//! compressed (x_c eliminated): each defect then touches only its own interval's variables
//! through f's Jacobians at single points, so the constraint Jacobian is block-banded with
//! small dense blocks, which a sparse solver factors in time linear in T; the compressed form
//! saves the midpoint states but couples each f_c to both knots through a chain rule.
//!
//! Held inputs rather than inputs interpolated between knots: the collocated trajectory then
//! approximates the very ODE the one-step map integrates, so a plan's inputs are the ones the
//! map (and a tracking controller) applies, its cost is iLQR's term for term with no
//! midpoint or final input left uncosted, and the rollout of its inputs departs from its
//! states only by the two integrators' differences. The price is a third evaluation of f per
//! interval (at x_{k+1} under u_k as well as under u_{k+1}).
//!
//! Variables are ordered knot by knot, `[x_0, u_0, x_c0, x_1, u_1, x_c1, …, x_T]`, so that the
//! KKT system's bandwidth is one interval's.

use super::Continuous;
use crate::control::linalg::Mat;

/// One entry of a sparse matrix: (row, column, value).
pub type Entry = (usize, usize, f64);

/// Where each variable of a T-interval transcription sits in the decision vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    pub nx: usize,
    pub m: usize,
    /// Intervals (T): T + 1 knots, T inputs, T midpoints.
    pub intervals: usize,
}

impl Layout {
    /// One interval's variables: its knot state, its input and its midpoint state.
    fn stride(&self) -> usize {
        2 * self.nx + self.m
    }
    pub fn x(&self, k: usize) -> usize {
        k * self.stride()
    }
    pub fn u(&self, k: usize) -> usize {
        self.x(k) + self.nx
    }
    pub fn xc(&self, k: usize) -> usize {
        self.u(k) + self.m
    }
    /// Decision variables: T intervals, then the last knot's state.
    pub fn len(&self) -> usize {
        self.x(self.intervals) + self.nx
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Where every state after x_0 (which is fixed) starts: the knots', then the midpoints'.
    pub fn free_states(&self) -> impl Iterator<Item = usize> + '_ {
        (1..=self.intervals)
            .map(|k| self.x(k))
            .chain((0..self.intervals).map(|k| self.xc(k)))
    }
    /// Defects: two states' worth per interval.
    pub fn defects(&self) -> usize {
        2 * self.nx * self.intervals
    }

    /// The points f is needed at, as one batch `[3T, nx]`, `[3T, m]`: every interval's start,
    /// then every midpoint, then every end, each under the interval's input.
    fn points(&self, z: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let t = self.intervals;
        let (mut x, mut u) = (
            Vec::with_capacity(3 * t * self.nx),
            Vec::with_capacity(3 * t * self.m),
        );
        for at in [
            |l: &Self, k| l.x(k),
            |l: &Self, k| l.xc(k),
            |l: &Self, k| l.x(k + 1),
        ] {
            for k in 0..t {
                x.extend_from_slice(&z[at(self, k)..][..self.nx]);
                u.extend_from_slice(&z[self.u(k)..][..self.m]);
            }
        }
        (x, u)
    }
}

/// The defects at `z`, interval by interval: Simpson's nx rows, then Hermite's.
pub fn defects(sys: &dyn Continuous, l: &Layout, z: &[f64], h: f64) -> Vec<f64> {
    let (x, u) = l.points(z);
    let f = sys.derivative(&x, &u);
    let (nx, t) = (l.nx, l.intervals);
    let mut out = Vec::with_capacity(l.defects());
    for k in 0..t {
        let (x0, x1) = (&z[l.x(k)..][..nx], &z[l.x(k + 1)..][..nx]);
        let mid = &z[l.xc(k)..][..nx];
        let (fs, fc, fe) = (
            &f[k * nx..][..nx],
            &f[(t + k) * nx..][..nx],
            &f[(2 * t + k) * nx..][..nx],
        );
        out.extend((0..nx).map(|i| x1[i] - x0[i] - h / 6.0 * (fs[i] + 4.0 * fc[i] + fe[i])));
        out.extend((0..nx).map(|i| mid[i] - 0.5 * (x0[i] + x1[i]) - h / 8.0 * (fs[i] - fe[i])));
    }
    out
}

/// The defects' Jacobian at `z` as (row, column, value) triplets, exact from f's Jacobians;
/// rows as [`defects`] orders them, no (row, column) twice. Every entry of every block is
/// listed, zeros too, so that the pattern is the same at every `z` and a solver's symbolic
/// factorisation is reused.
pub fn defect_jacobian(sys: &dyn Continuous, l: &Layout, z: &[f64], h: f64) -> Vec<Entry> {
    let (x, u) = l.points(z);
    let (a, b) = sys.derivative_jacobian(&x, &u);
    let t = l.intervals;
    let mut out = Vec::with_capacity(l.intervals * 2 * l.nx * (4 * l.nx + l.m));
    for k in 0..t {
        let (simpson, hermite) = (2 * l.nx * k, 2 * l.nx * k + l.nx);
        let (s, c, e) = (k, t + k, 2 * t + k);
        // Simpson: ∂/∂x_k = −I − h/6 A_s, ∂/∂x_c = −4h/6 A_c, ∂/∂x_{k+1} = I − h/6 A_e,
        // ∂/∂u_k = −h/6 (B_s + 4 B_c + B_e).
        block(&mut out, simpson, l.x(k), &a[s], -h / 6.0, -1.0);
        let bs = combine(&[
            (&b[s], -h / 6.0),
            (&b[c], -4.0 * h / 6.0),
            (&b[e], -h / 6.0),
        ]);
        block(&mut out, simpson, l.u(k), &bs, 1.0, 0.0);
        block(&mut out, simpson, l.xc(k), &a[c], -4.0 * h / 6.0, 0.0);
        block(&mut out, simpson, l.x(k + 1), &a[e], -h / 6.0, 1.0);
        // Hermite: ∂/∂x_k = −I/2 − h/8 A_s, ∂/∂x_c = I, ∂/∂x_{k+1} = −I/2 + h/8 A_e,
        // ∂/∂u_k = −h/8 (B_s − B_e).
        block(&mut out, hermite, l.x(k), &a[s], -h / 8.0, -0.5);
        let bh = combine(&[(&b[s], -h / 8.0), (&b[e], h / 8.0)]);
        block(&mut out, hermite, l.u(k), &bh, 1.0, 0.0);
        out.extend((0..l.nx).map(|i| (hermite + i, l.xc(k) + i, 1.0)));
        block(&mut out, hermite, l.x(k + 1), &a[e], h / 8.0, -0.5);
    }
    out
}

/// Σ scale · matrix.
fn combine(terms: &[(&Mat, f64)]) -> Mat {
    let (rows, cols) = (terms[0].0.rows, terms[0].0.cols);
    let mut out = Mat::zeros(rows, cols);
    for (m, s) in terms {
        for (o, v) in out.data.iter_mut().zip(&m.data) {
            *o += s * v;
        }
    }
    out
}

/// `scale · a + identity · I` at (row, col) (`identity` is 0 for the inputs' blocks).
fn block(out: &mut Vec<Entry>, row: usize, col: usize, a: &Mat, scale: f64, identity: f64) {
    for i in 0..a.rows {
        for j in 0..a.cols {
            let diagonal = if i == j { identity } else { 0.0 };
            out.push((row + i, col + j, scale * a.at(i, j) + diagonal));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A damped pendulum driven at its pivot and a second, coupled one: nonlinear in the
    /// state and in the inputs, so that every block of the Jacobian is exercised.
    struct TwoPendulums;

    impl TwoPendulums {
        fn f(x: &[f64], u: &[f64]) -> [f64; 4] {
            let (a, b, va, vb) = (x[0], x[1], x[2], x[3]);
            [
                va,
                vb,
                -9.81 * a.sin() - 0.3 * va + u[0] + 0.5 * (b - a).sin(),
                -9.81 * b.sin() - 0.1 * vb.powi(3) + u[0] * u[1],
            ]
        }
    }

    impl Continuous for TwoPendulums {
        fn nx(&self) -> usize {
            4
        }
        fn m(&self) -> usize {
            2
        }
        fn dt(&self) -> f64 {
            0.1
        }
        fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
            x.chunks(4)
                .zip(u.chunks(2))
                .flat_map(|(x, u)| Self::f(x, u))
                .collect()
        }
        /// Exact, written out: the test compares it with central differences through the
        /// transcription, which checks the transcription's assembly.
        fn derivative_jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
            x.chunks(4)
                .zip(u.chunks(2))
                .map(|(x, u)| {
                    let (a, b, vb) = (x[0], x[1], x[3]);
                    let mut fa = Mat::zeros(4, 4);
                    let mut fb = Mat::zeros(4, 2);
                    fa.data[2] = 1.0;
                    fa.data[4 + 3] = 1.0;
                    let c = 0.5 * (b - a).cos();
                    fa.data[8] = -9.81 * a.cos() - c;
                    fa.data[8 + 1] = c;
                    fa.data[8 + 2] = -0.3;
                    fa.data[12 + 1] = -9.81 * b.cos();
                    fa.data[12 + 3] = -0.3 * vb * vb;
                    fb.data[4] = 1.0;
                    fb.data[6] = u[1];
                    fb.data[7] = u[0];
                    (fa, fb)
                })
                .unzip()
        }
    }

    fn dense(l: &Layout, triplets: &[Entry]) -> Vec<f64> {
        let mut out = vec![0.0; l.defects() * l.len()];
        for &(i, j, v) in triplets {
            out[i * l.len() + j] += v;
        }
        out
    }

    /// Each column of the exact Jacobian against central differences of the defects. Step
    /// 1e-6: the differences' truncation error (ε² f‴ ~ 1e-11) and rounding (1e-16 / ε ~
    /// 1e-10) are far below the 1e-6 tolerance a wrong block (an error of order h ~ 0.1) fails.
    #[test]
    fn the_defect_jacobian_matches_central_differences() {
        let l = Layout {
            nx: 4,
            m: 2,
            intervals: 5,
        };
        let h = 0.1;
        let mut rng = Rng::new(7);
        let z: Vec<f64> = (0..l.len()).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        let exact = dense(&l, &defect_jacobian(&TwoPendulums, &l, &z, h));
        let eps = 1e-6;
        for j in 0..l.len() {
            let (mut up, mut down) = (z.clone(), z.clone());
            up[j] += eps;
            down[j] -= eps;
            let (a, b) = (
                defects(&TwoPendulums, &l, &up, h),
                defects(&TwoPendulums, &l, &down, h),
            );
            for i in 0..l.defects() {
                let fd = (a[i] - b[i]) / (2.0 * eps);
                let got = exact[i * l.len() + j];
                assert!(
                    (fd - got).abs() < 1e-6,
                    "defect {i}, variable {j}: {got} vs {fd}"
                );
            }
        }
        // Every block listed, zeros too: Simpson's three state blocks and one input block,
        // Hermite's two state blocks, its input block and its identity at the midpoint.
        let per_interval = 4 * (3 * 4 + 2) + 4 * (2 * 4 + 2) + 4;
        assert_eq!(
            defect_jacobian(&TwoPendulums, &l, &z, h).len(),
            5 * per_interval
        );
    }

    /// Hermite–Simpson integrates cubics exactly: a double integrator under a constant force
    /// (a quadratic position) has zero defects at its exact states and midpoints.
    #[test]
    fn an_exact_trajectory_has_no_defects() {
        struct DoubleIntegrator;
        impl Continuous for DoubleIntegrator {
            fn nx(&self) -> usize {
                2
            }
            fn m(&self) -> usize {
                1
            }
            fn dt(&self) -> f64 {
                0.05
            }
            fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
                x.chunks(2).zip(u).flat_map(|(x, u)| [x[1], *u]).collect()
            }
            fn derivative_jacobian(&self, x: &[f64], _: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
                let rows = x.len() / 2;
                let a = Mat::new(2, 2, vec![0.0, 1.0, 0.0, 0.0]);
                let b = Mat::new(2, 1, vec![0.0, 1.0]);
                (vec![a; rows], vec![b; rows])
            }
        }
        let (l, h, force) = (
            Layout {
                nx: 2,
                m: 1,
                intervals: 8,
            },
            0.05,
            3.0,
        );
        let state = |t: f64| [0.2 + 0.7 * t + 0.5 * force * t * t, 0.7 + force * t];
        let mut z = vec![force; l.len()];
        for k in 0..=l.intervals {
            z[l.x(k)..l.x(k) + 2].copy_from_slice(&state(k as f64 * h));
            if k < l.intervals {
                z[l.xc(k)..l.xc(k) + 2].copy_from_slice(&state((k as f64 + 0.5) * h));
            }
        }
        // Every variable has one place: 8 intervals of (x_k, u_k, x_c), then x_T.
        assert_eq!(l.len(), 8 * 5 + 2);
        let worst = defects(&DoubleIntegrator, &l, &z, h)
            .iter()
            .fold(0.0f64, |m, d| m.max(d.abs()));
        assert!(worst < 1e-14, "{worst}");
    }
}
