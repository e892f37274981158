//! The classic identification of a robot (docs/robots.md#least-squares): its torques are
//! linear in the bodies' standard parameters π (with the armatures, when it has them) and the
//! joints' damping and friction,
//!
//!   S u = Y(q, q̇, q̈) π + Σ_j (d_j g_j² q̇_c + f_j g_j tanh(g_j q̇_c / ε)) e_c,
//!
//! so the rows of a log stack into W x = b, solved in the least-squares sense. W's columns
//! are scaled to unit norm first (mass, lever and inertia columns differ by orders), and of
//! the minimizers the one nearest the starting values is taken (motion data determine only
//! the base parameters: the rest of π stays where it was). The solution's bodies are then
//! made physical (mass > 0, inertia about the centre of mass positive definite and meeting
//! the triangle inequality) and its friction not negative, so that it can start training.

use super::delay;
use super::parameters::{PER_BODY, PER_JOINT};
use super::template::UrdfTemplate;
use crate::error::{Error, Result};
use crate::physics::eigen::symmetric_eigen;
use crate::physics::multibody::regressor::{regressor, standard_parameters};
use crate::physics::multibody::spatial::{Inertial, physical_values};

/// A rank below this share of the largest scaled eigenvalue is a direction the data do not
/// determine: rounding in WᵀW of unit columns is ~1e-16 of its largest eigenvalue, squared
/// conditioning leaves ~1e-8 of real signal resolvable.
const RANK_TOLERANCE: f64 = 1e-14;

/// A body's smallest mass and principal moment after the projection, relative to the
/// starting body's (a massless link keeps its zero).
const FLOOR: f64 = 1e-6;

/// The normal equations WᵀW (upper triangle) and Wᵀ(b − W x) at some x, and |b − W x|².
type Normal = (Vec<Vec<f64>>, Vec<f64>, f64);

/// What the solve found.
#[derive(Debug, Clone)]
pub struct LeastSquares {
    /// Physical values (the template's order), physical bodies and friction ≥ 0.
    pub physical: Vec<f64>,
    /// The directions of x the data determined (the regressor's rank, friction included).
    pub rank: usize,
    /// Bodies the projection moved (their least-squares π was not a physical body).
    pub projected: Vec<String>,
}

impl UrdfTemplate {
    /// The least-squares physical values for torque rows [q, q̇, q̈, inputs] (the inputs'
    /// block as `delay` lays it out for `lags` earlier samples), starting from and nearest to
    /// `start`; `stop` is polled every row. A robot with an effort delay takes the delay
    /// whose solution leaves the least residual (`best_delay`).
    pub fn least_squares(
        &self,
        start: &[f64],
        gravity: bool,
        (rows, lags): (&[f64], usize),
        stop: &dyn Fn() -> bool,
    ) -> Result<LeastSquares> {
        let (n, nb) = (self.n(), self.nb());
        let width = 3 * n + delay::input_width(self.m(), lags);
        let model = self.multibody_model(start, gravity);
        let joints = model.parameter_count() + PER_JOINT * nb;
        let cols = joints + self.effort_offset(start).len();
        // x of physical values: π (and the armatures), damping and friction, offsets.
        let x_of = |physical: &[f64]| {
            let mut x = standard_parameters(&self.multibody_model(physical, gravity));
            x.extend_from_slice(&physical[PER_BODY * nb..][..PER_JOINT * nb]);
            x.extend_from_slice(self.effort_offset(physical));
            x
        };
        let gains = self.effort_gain(start);
        // WᵀW, Wᵀ(b − W x) and |b − W x|², one pass over the rows, the efforts delayed by δ.
        let pass_at = |delta: f64| {
            let model = &model;
            move |x: &[f64]| -> Result<Normal> {
                let (mut a, mut g) = (vec![vec![0.0; cols]; cols], vec![0.0; cols]);
                let mut rss = 0.0;
                for row in rows.chunks_exact(width) {
                    if stop() {
                        return Err(Error::Cancelled);
                    }
                    let (q, qd, qdd) = (&row[..n], &row[n..2 * n], &row[2 * n..3 * n]);
                    let mut w = regressor(model, q, qd, qdd);
                    self.joint_columns(model.parameter_count(), qd, &mut w);
                    let u = match lags {
                        0 => row[3 * n..].to_vec(),
                        _ => delay::delayed(&row[3 * n..], self.m(), delta).0,
                    };
                    let mut r = self.input_torques(&u, gains);
                    for (r, w) in r.iter_mut().zip(&w) {
                        *r -= w.iter().zip(x).map(|(w, x)| w * x).sum::<f64>();
                    }
                    rss += r.iter().map(|r| r * r).sum::<f64>();
                    accumulate(&w, &r, &mut a, &mut g);
                }
                Ok((a, g, rss))
            }
        };
        let bounded = PER_BODY * nb..joints;
        let fit = |delta: f64, x: Vec<f64>, held: Vec<bool>| {
            bounded_solve(&pass_at(delta), x, held, bounded.clone())
        };
        let delta = match self.doc.effort_delay {
            Some(bound) if lags > 0 => {
                let residual = |d: f64| Ok(fit(d, x_of(start), vec![false; cols])?.2);
                delay::best_delay(bound, median_step(rows, width, n)?, &residual)?
            }
            _ => 0.0,
        };
        let (x, rank, _) = fit(delta, x_of(start), vec![false; cols])?;
        let first = self.physical_of(&x, rank, start, delta);
        if first.projected.is_empty() {
            return Ok(first);
        }
        // Making bodies physical moved them off the solution; what the data still ask of
        // them goes to the joints' values, solved again with the bodies held (an armature
        // shares its column with its link's inertia about a world-fixed axis, and takes what
        // the link could not).
        let held = (0..cols).map(|k| k < PER_BODY * nb).collect();
        let (x, _, _) = fit(delta, x_of(&first.physical), held)?;
        Ok(LeastSquares {
            physical: self.physical_of(&x, rank, start, delta).physical,
            ..first
        })
    }

    /// Damping's and friction's columns after the regressor's `base`, then the effort
    /// offsets' (their law in `forces.rs`: an offset is a force the input side gives).
    fn joint_columns(&self, base: usize, qd: &[f64], w: &mut [Vec<f64>]) {
        let per_eps = 1.0 / self.doc.coulomb_eps;
        let nb = self.nb();
        let offsets = if self.doc.effort_offset { self.m() } else { 0 };
        for row in w.iter_mut() {
            row.resize(base + PER_JOINT * nb + offsets, 0.0);
        }
        for (k, &c) in self.actuated.iter().enumerate().take(offsets) {
            w[c][base + PER_JOINT * nb + k] = -1.0;
        }
        for (i, b) in self.tree.bodies.iter().enumerate() {
            let (c, g) = (b.drive.coordinate, b.drive.multiplier);
            let v = g * qd[c];
            w[c][base + PER_JOINT * i] += g * v;
            w[c][base + PER_JOINT * i + 1] += g * (v * per_eps).tanh();
        }
    }

    /// S (g∘u): each actuated coordinate's input at its gain (1 without gains). The gains
    /// stay at their start: with them free every parameter scales with them, and zero fits.
    fn input_torques(&self, u: &[f64], gains: &[f64]) -> Vec<f64> {
        let mut b = vec![0.0; self.n()];
        for (a, &c) in self.actuated.iter().enumerate() {
            b[c] += gains.get(a).unwrap_or(&1.0) * u[a];
        }
        b
    }

    /// x = [π, armatures, damping and friction, offsets] and the delay as physical values
    /// (bodies, damping and friction, armatures, gains as they started, offsets, delay), each
    /// body made physical.
    fn physical_of(&self, x: &[f64], rank: usize, start: &[f64], delay: f64) -> LeastSquares {
        let nb = self.nb();
        let mut physical = Vec::with_capacity(start.len());
        let mut projected = vec![];
        for (i, p) in x.chunks(PER_BODY).take(nb).enumerate() {
            let own = &start[i * PER_BODY..(i + 1) * PER_BODY];
            let (values, moved) = physical_body(p, own);
            if moved {
                projected.push(self.tree.bodies[i].link.clone());
            }
            physical.extend(values);
        }
        let armatures = self.armature(start).len();
        let (armature, rest) = x[PER_BODY * nb..].split_at(armatures);
        let (joints, offsets) = rest.split_at(PER_JOINT * nb);
        physical.extend_from_slice(joints);
        physical.extend_from_slice(armature);
        physical.extend_from_slice(self.effort_gain(start));
        physical.extend_from_slice(offsets);
        if self.doc.effort_delay.is_some() {
            physical.push(delay);
        }
        LeastSquares {
            physical,
            rank,
            projected,
        }
    }
}

/// The least-squares x from `x` moving no `held` entry, with the entries in `bounded` kept
/// ≥ 0: a value the solve takes below 0 is held there and the rest solved again (an active
/// set, as bounded least squares does), until none is. `pass` gives the normal equations;
/// the residual's |b − W x|² is the refinement's (within rounding of the solution's).
fn bounded_solve(
    pass: &dyn Fn(&[f64]) -> Result<Normal>,
    mut x: Vec<f64>,
    mut held: Vec<bool>,
    bounded: std::ops::Range<usize>,
) -> Result<(Vec<f64>, usize, f64)> {
    loop {
        let (a, g, _) = pass(&x)?;
        let solve = Minimizer::of(&a, &held);
        x.iter_mut().zip(solve.step(&g)).for_each(|(x, d)| *x += d);
        // One refinement with the residual recomputed from the rows: the normal equations
        // square W's conditioning, and a second pass takes back what that lost.
        let (_, g, rss) = pass(&x)?;
        x.iter_mut().zip(solve.step(&g)).for_each(|(x, d)| *x += d);
        let below: Vec<usize> = bounded.clone().filter(|&k| x[k] < 0.0).collect();
        if below.is_empty() {
            return Ok((x, solve.rank, rss));
        }
        for k in below {
            (x[k], held[k]) = (0.0, true);
        }
    }
}

/// The median of the rows' steps (each input block's first value; the upper middle of an
/// even count).
fn median_step(rows: &[f64], width: usize, n: usize) -> Result<f64> {
    let mut steps: Vec<f64> = rows.chunks_exact(width).map(|r| r[3 * n]).collect();
    if steps.is_empty() {
        return Err(Error::invalid("data", "no transitions to identify from"));
    }
    let middle = steps.len() / 2;
    Ok(*steps.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// A += wᵀw (its upper triangle), g += wᵀr for one row block.
fn accumulate(w: &[Vec<f64>], r: &[f64], a: &mut [Vec<f64>], g: &mut [f64]) {
    for (row, ri) in w.iter().zip(r) {
        for (j, &wj) in row.iter().enumerate() {
            if wj == 0.0 {
                continue;
            }
            g[j] += wj * ri;
            for (k, &wk) in row.iter().enumerate().skip(j) {
                a[j][k] += wj * wk;
            }
        }
    }
}

/// The least-squares step of the normal equations A = WᵀW (upper triangle filled) in W's
/// unit-column scaling, by the eigen-decomposition of the scaled A: for g = Wᵀr, the
/// smallest step (scaled) that minimizes ‖W(x + dx) − b‖² from x with residual r, moving no
/// `held` entry. Directions below RANK_TOLERANCE of the largest eigenvalue are left alone.
struct Minimizer {
    scale: Vec<f64>,
    /// The determined directions' eigenvalues and eigenvectors (scaled).
    directions: Vec<(f64, Vec<f64>)>,
    rank: usize,
}

impl Minimizer {
    fn of(a: &[Vec<f64>], held: &[bool]) -> Self {
        let p = a.len();
        let s: Vec<f64> = (0..p)
            .map(|k| if a[k][k] > 0.0 { a[k][k].sqrt() } else { 1.0 })
            .collect();
        let scaled: Vec<Vec<f64>> = (0..p)
            .map(|j| {
                // A held entry's row and column are zero: its only direction has eigenvalue 0.
                (0..p)
                    .map(|k| match held[j] || held[k] {
                        true => 0.0,
                        false => a[j.min(k)][j.max(k)] / (s[j] * s[k]),
                    })
                    .collect()
            })
            .collect();
        let (values, vectors) = symmetric_eigen(&scaled);
        let top = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let directions: Vec<(f64, Vec<f64>)> = (values.iter().enumerate())
            .filter(|(_, l)| **l > RANK_TOLERANCE * top)
            .map(|(k, &l)| (l, (0..p).map(|i| vectors[i][k]).collect()))
            .collect();
        Self {
            scale: s,
            rank: directions.len(),
            directions,
        }
    }

    fn step(&self, g: &[f64]) -> Vec<f64> {
        let g: Vec<f64> = g.iter().zip(&self.scale).map(|(g, s)| g / s).collect();
        let mut dy = vec![0.0; g.len()];
        for (l, v) in &self.directions {
            let c = v.iter().zip(&g).map(|(v, g)| v * g).sum::<f64>() / l;
            dy.iter_mut().zip(v).for_each(|(d, v)| *d += c * v);
        }
        dy.iter().zip(&self.scale).map(|(d, s)| d / s).collect()
    }
}

/// A body's physical values (m, c, Ī) from its standard parameters, made physical: a body
/// whose mass is not above FLOOR of the start's keeps its starting values (its centre of mass,
/// h / m, means nothing then); Ī's principal moments are at least FLOOR of the start's largest
/// and each at most the sum of the other two. Whether anything moved.
fn physical_body(p: &[f64], start: &[f64]) -> ([f64; PER_BODY], bool) {
    let own: [f64; PER_BODY] = std::array::from_fn(|k| start[k]);
    if start[0] == 0.0 && p.iter().all(|v| v.abs() < 1e-12) {
        return (own, false);
    }
    if p[0] <= FLOOR * start[0].abs().max(1e-3) {
        return (own, true);
    }
    let body = Inertial::of_standard(p);
    let (c, mut ic) = (body.com(), body.inertia_at_com());
    let rows: Vec<Vec<f64>> = ic.iter().map(|r| r.to_vec()).collect();
    let (mut j, v) = symmetric_eigen(&rows);
    let largest = [start[4], start[7], start[9]]
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let floor = FLOOR * largest.max(1e-9);
    let mut moved = false;
    for jk in j.iter_mut() {
        if *jk < floor {
            (*jk, moved) = (floor, true);
        }
    }
    for k in 0..3 {
        let others = j[(k + 1) % 3] + j[(k + 2) % 3];
        if j[k] > others {
            (j[k], moved) = (others, true);
        }
    }
    if moved {
        ic = std::array::from_fn(|a| {
            std::array::from_fn(|b| (0..3).map(|k| v[a][k] * j[k] * v[b][k]).sum::<f64>())
        });
    }
    (physical_values(p[0], c, &ic), moved)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A physical body passes unchanged; one whose inertia has a negative principal moment,
    /// or one moment above the other two's sum, comes back positive definite and within the
    /// triangle inequality; a body the data make massless keeps its start.
    #[test]
    fn the_projection_makes_bodies_physical() {
        let start = [2.0, 0.1, 0.0, 0.0, 0.3, 0.0, 0.0, 0.2, 0.0, 0.15];
        let body =
            |v: &[f64; PER_BODY]| crate::physics::multibody::spatial::of_physical(v).standard();
        let (same, moved) = physical_body(&body(&start), &start);
        assert!(!moved);
        assert!(
            same.iter().zip(&start).all(|(a, b)| (a - b).abs() < 1e-12),
            "{same:?}"
        );
        for bad in [
            [2.0, 0.1, 0.0, 0.0, -0.1, 0.0, 0.0, 0.2, 0.0, 0.15],
            [2.0, 0.1, 0.0, 0.0, 0.9, 0.0, 0.0, 0.2, 0.0, 0.15],
        ] {
            let (p, moved) = physical_body(&body(&bad), &start);
            assert!(moved);
            let j = symmetric_eigen(&[
                vec![p[4], p[5], p[6]],
                vec![p[5], p[7], p[8]],
                vec![p[6], p[8], p[9]],
            ])
            .0;
            assert!(j.iter().all(|&x| x > 0.0), "{j:?}");
            for k in 0..3 {
                assert!(j[k] <= j[(k + 1) % 3] + j[(k + 2) % 3] + 1e-12, "{j:?}");
            }
            assert_eq!(p[0], 2.0);
        }
        let massless = [-0.5, 0.1, 0.0, 0.0, 0.3, 0.0, 0.0, 0.2, 0.0, 0.15];
        assert_eq!(physical_body(&massless, &start), (start, true));
    }
}
