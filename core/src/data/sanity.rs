//! Sanity checks on uploaded data: findings a person should read before training on it
//! (angles in degrees, velocities that are not the positions' derivative, accelerations at
//! absurd scales). They never block an upload: the data may be right and unusual.
//! The thresholds are documented in README ("Dataset warnings").

use std::f64::consts::PI;

use super::Dataset;
use crate::records::Warning;

/// A coordinate whose values span more than four turns, and whose middle half (between the
/// quartiles) spans more than two, is most likely in degrees (±180 spans 360, its middle half
/// 180) or an angle unwrapped over a long log; the templates and networks expect radians in a
/// few turns. The paper's data spans 2π. Trajectories that wind (swings of 2 s from
/// |q̇| ≤ 10 rad/s, as `graybox simulate --trajectories` makes them) reach 40 rad from end to
/// end, but their middle half stays under 6 rad: most of the time is spent near the start.
pub const SPAN_MAX: f64 = 8.0 * PI;
/// The middle half's bound (see [`SPAN_MAX`]).
pub const MIDDLE_SPAN_MAX: f64 = 4.0 * PI;

/// The velocities must be the derivative of the positions at this Δt: RMS of
/// (q′ − q)/Δt − (q̇ + q̇′)/2 over the larger of the two sides' RMS. Consistent data is near 0
/// (the paper's: below 0.002, the trapezoid's O(Δt²) error); mixed units (q in degrees, q̇ in rad/s)
/// or a wrong Δt give ~1.
pub const VELOCITY_MISMATCH_MAX: f64 = 0.5;

/// RMS of the implied accelerations (q̇′ − q̇)/Δt, in units/s², above which the data's scale is
/// implausible for a mechanical system (about 1000 g on a 1 m link; the paper's systems with
/// inputs of σ = 120: 45–360).
pub const ACCEL_RMS_MAX: f64 = 1e4;

impl Dataset {
    /// Every finding of the checks, per coordinate. Where q and qdot differ in width (a
    /// rotation kept as a unit complex number) a velocity is not one coordinate's rate, so the
    /// velocity check is left out; the spans are q's and the accelerations qdot's.
    pub fn warnings(&self) -> Vec<Warning> {
        let mut out = vec![];
        if self.nq != self.nv {
            out.extend((0..self.nq).filter_map(|i| self.span_warning(i)));
            out.extend((0..self.nv).filter_map(|i| self.accel_warning(i)));
            return out;
        }
        for i in 0..self.nq {
            out.extend(self.span_warning(i));
            out.extend(self.velocity_warning(i));
            out.extend(self.accel_warning(i));
        }
        out
    }

    /// Coordinate `i` of every row of a q array (nq wide).
    fn of_q<'a>(&self, a: &'a [f64], i: usize) -> impl Iterator<Item = f64> + 'a {
        a.iter().skip(i).step_by(self.nq).copied()
    }

    /// Velocity `i` of every row of a qdot array (nv wide).
    fn of_v<'a>(&self, a: &'a [f64], i: usize) -> impl Iterator<Item = f64> + 'a {
        a.iter().skip(i).step_by(self.nv).copied()
    }

    fn span_warning(&self, i: usize) -> Option<Warning> {
        let values = self.of_q(&self.q, i).chain(self.of_q(&self.q_next, i));
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if hi - lo <= SPAN_MAX {
            return None;
        }
        let (q1, q3) = self.quartiles(i);
        (q3 - q1 > MIDDLE_SPAN_MAX).then(|| {
            Warning::new(
                "coordinate_span",
                Some(format!("q[{i}]")),
                format!(
                    "q[{i}] spans {:.4} (from {lo:.4} to {hi:.4}) and its middle half {:.4} \
                     (from {q1:.4} to {q3:.4}), more than four and two turns: angles must be \
                     in radians and wrapped to a few turns",
                    hi - lo,
                    q3 - q1
                ),
            )
        })
    }

    /// The first and third quartiles of coordinate `i` over q and q′ (the values at a quarter
    /// and three quarters of the sorted list), found by selection, not a full sort.
    fn quartiles(&self, i: usize) -> (f64, f64) {
        let mut v: Vec<f64> = (self.of_q(&self.q, i))
            .chain(self.of_q(&self.q_next, i))
            .collect();
        let last = v.len() - 1;
        let mut at = |k: usize| *v.select_nth_unstable_by(k, f64::total_cmp).1;
        (at(last / 4), at(3 * last / 4))
    }

    fn velocity_warning(&self, i: usize) -> Option<Warning> {
        let (mut diff, mut fd, mut mid) = (0.0, 0.0, 0.0);
        let rows = self
            .of_q(&self.q, i)
            .zip(self.of_q(&self.q_next, i))
            .zip(self.of_v(&self.qdot, i).zip(self.of_v(&self.qdot_next, i)));
        for (k, ((q, q1), (v, v1))) in rows.enumerate() {
            let (m, dt) = (0.5 * (v + v1), self.step(k));
            // An angle wrapped to (−π, π] jumps by whole turns: those are not a mismatch.
            let turns = ((q1 - q - m * dt) / std::f64::consts::TAU).round();
            let f = (q1 - q - turns * std::f64::consts::TAU) / dt;
            diff += (f - m) * (f - m);
            fd += f * f;
            mid += m * m;
        }
        let ratio = diff.sqrt() / fd.sqrt().max(mid.sqrt()).max(f64::MIN_POSITIVE);
        (ratio > VELOCITY_MISMATCH_MAX).then(|| {
            let count = self.count() as f64;
            Warning::new(
                "velocity_mismatch",
                Some(format!("qdot[{i}]")),
                format!(
                    "qdot[{i}] does not match the change of q[{i}] over dt = {}: \
                     RMS of (q'−q)/dt is {:.4}, of (qdot+qdot')/2 {:.4}, of their difference \
                     {:.4}; check units (both radians), dt and the column order",
                    self.dt,
                    (fd / count).sqrt(),
                    (mid / count).sqrt(),
                    (diff / count).sqrt()
                ),
            )
        })
    }

    fn accel_warning(&self, i: usize) -> Option<Warning> {
        let sum: f64 = self
            .of_v(&self.qdot, i)
            .zip(self.of_v(&self.qdot_next, i))
            .enumerate()
            .map(|(k, (v, v1))| ((v1 - v) / self.step(k)).powi(2))
            .sum();
        let rms = (sum / self.count() as f64).sqrt();
        (rms > ACCEL_RMS_MAX).then(|| {
            Warning::new(
                "extreme_acceleration",
                Some(format!("qdot[{i}]")),
                format!(
                    "the implied accelerations (qdot'−qdot)/dt of coordinate {i} have RMS \
                     {rms:.4e}, above {ACCEL_RMS_MAX:e}: check the units and dt"
                ),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A pendulum-like coordinate: q(t) = a sin(t), sampled consistently at dt.
    fn consistent(a: f64, dt: f64, count: usize) -> Dataset {
        let (mut q, mut v, mut q1, mut v1) = (vec![], vec![], vec![], vec![]);
        for k in 0..count {
            let t = k as f64 * 0.37;
            q.push(a * t.sin());
            v.push(a * t.cos());
            q1.push(a * (t + dt).sin());
            v1.push(a * (t + dt).cos());
        }
        Dataset::new(dt, (1, 1), 1, [q, v, vec![0.0; count], q1, v1]).unwrap()
    }

    fn codes(d: &Dataset) -> Vec<String> {
        d.warnings().into_iter().map(|w| w.code).collect()
    }

    #[test]
    fn consistent_radians_raise_nothing() {
        assert!(codes(&consistent(3.0, 0.01, 500)).is_empty());
    }

    #[test]
    fn degrees_span_more_than_four_turns() {
        // The same motion with q and q̇ both in degrees: consistent, but it spans 344°.
        let d = consistent(3.0f64.to_degrees(), 0.01, 500);
        assert_eq!(codes(&d), ["coordinate_span"]);
    }

    #[test]
    fn positions_in_degrees_with_velocities_in_radians_mismatch() {
        let mut d = consistent(0.2, 0.01, 500);
        d.q.iter_mut().for_each(|q| *q = q.to_degrees());
        d.q_next.iter_mut().for_each(|q| *q = q.to_degrees());
        assert_eq!(codes(&d), ["velocity_mismatch"]);
    }

    #[test]
    fn wrapped_angles_are_no_mismatch() {
        // A coordinate turning steadily at 3 rad/s, wrapped to (−π, π]: q' jumps by 2π
        // wherever it crosses π.
        let wrap = |x: f64| (x + PI).rem_euclid(2.0 * PI) - PI;
        let dt = 0.01;
        let t: Vec<f64> = (0..500).map(|k| k as f64 * dt).collect();
        let k = t.len();
        let q = t.iter().map(|t| wrap(3.0 * t)).collect();
        let q1 = t.iter().map(|t| wrap(3.0 * (t + dt))).collect();
        let d = Dataset::new(
            dt,
            (1, 1),
            1,
            [q, vec![3.0; k], vec![0.0; k], q1, vec![3.0; k]],
        )
        .unwrap();
        assert!(d.q.iter().zip(&d.q_next).any(|(a, b)| (a - b).abs() > PI));
        assert!(codes(&d).is_empty(), "{:?}", codes(&d));
    }

    #[test]
    fn a_wrong_dt_gives_extreme_accelerations_and_a_mismatch() {
        // Recorded at 0.1 s but labelled 1e-5 s.
        let mut d = consistent(3.0, 0.1, 500);
        d.dt = 1e-5;
        let c = codes(&d);
        assert!(c.contains(&"velocity_mismatch".to_string()), "{c:?}");
        assert!(c.contains(&"extreme_acceleration".to_string()), "{c:?}");
    }
}
