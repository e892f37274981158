use super::*;

fn planar() -> Space {
    Space::new(vec![Joint::Real, Joint::Circle, Joint::Angle])
}

fn unit(th: f64) -> [f64; 2] {
    [th.cos(), th.sin()]
}

#[test]
fn sizes_follow_the_joints() {
    let s = planar();
    assert_eq!(
        (s.nq(), s.nv(), s.is_flat(), s.q_features()),
        (4, 3, false, 5)
    );
    let flat = Space::flat(3, &[false, true, false]);
    assert_eq!((flat.nq(), flat.nv(), flat.is_flat()), (3, 3, true));
    assert_eq!(flat.periodic(), vec![false, true, false]);
    assert_eq!(Space::flat(2, &[]).periodic(), Vec::<bool>::new());
}

/// A line's integrate is the integrators' x + a·v to the bit.
#[test]
fn a_flat_space_integrates_by_addition() {
    let s = Space::flat(2, &[true]);
    let (q, v) = ([0.3, -1.7], [0.11, 2.5]);
    let mut out = vec![];
    s.integrate_into(&q, 0.01, &v, &mut out);
    assert_eq!(out, vec![q[0] + v[0] * 0.01, q[1] + v[1] * 0.01]);
    assert_eq!(s.difference(&q, &out), vec![out[0] - q[0], out[1] - q[1]]);
}

/// difference undoes integrate, a rotation by its shortest way round, and keeps a unit
/// complex number on the circle.
#[test]
fn difference_undoes_integrate() {
    let s = planar();
    let [c, sn] = unit(2.9);
    let q = [0.4, c, sn, -1.2];
    for v in [[0.3, 0.2, -0.5], [-2.0, 3.0, 7.0], [0.0, -3.1, 0.0]] {
        let q1 = s.integrate(&q, &v);
        let d = s.difference(&q, &q1);
        for (a, b) in d.iter().zip(&v) {
            // Rounding of a few operations on values of order one.
            assert!((a - b).abs() < 1e-12, "{d:?} vs {v:?}");
        }
        assert!((q1[1].hypot(q1[2]) - 1.0).abs() < 1e-15);
    }
    // Past half a turn the rotation goes the other way round.
    let q1 = s.integrate(&q, &[0.0, 4.0, 0.0]);
    let d = s.difference(&q, &q1)[1];
    assert!(
        (d - (4.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12,
        "{d}"
    );
}

/// The dual seeding is ∂ integrate(q, v)/∂v at 0, against central differences.
#[test]
fn seeds_are_integrates_derivative() {
    let s = planar();
    let [c, sn] = unit(-0.7);
    let q = [0.4, c, sn, 1.1];
    let a = Arena::new();
    let seeded: AVec<Dual<f64>> = s.seeded_in(&a, &q, &1.0, 0..3);
    let basis = s.integrate_basis(&q);
    let h = 1e-6;
    for k in 0..3 {
        let mut e = [0.0; 3];
        e[k] = h;
        let plus = s.integrate(&q, &e);
        e[k] = -h;
        let minus = s.integrate(&q, &e);
        for i in 0..4 {
            let fd = (plus[i] - minus[i]) / (2.0 * h);
            let t = seeded[i].tangent(k).copied().unwrap_or(0.0);
            // Central differences of sin/cos at h = 1e-6: truncation ~h², rounding ~1e-10.
            assert!((t - fd).abs() < 1e-9, "q{i} along v{k}: {t} vs {fd}");
            assert_eq!(basis[i * 3 + k], t);
        }
    }
}

/// `tangent_rows` maps a change of q to the change of difference(q̄, q), against central
/// differences, for a q̄ off the unit circle too (a model's output may drift from it).
#[test]
fn tangent_rows_are_differences_derivative() {
    let s = planar();
    let [c, sn] = unit(1.9);
    let q = [0.4, 1.01 * c, 1.01 * sn, 1.1];
    let h = 1e-6;
    for i in 0..4 {
        let mut dq = [0.0; 4];
        dq[i] = 1.0;
        let mut rows = vec![];
        s.tangent_rows(&q, &dq, 1, &mut rows);
        let at = |e: f64| {
            let mut q1 = q;
            q1[i] += e;
            s.difference(&q, &q1)
        };
        let (p, m) = (at(h), at(-h));
        for k in 0..3 {
            let fd = (p[k] - m[k]) / (2.0 * h);
            assert!(
                (rows[k] - fd).abs() < 1e-9,
                "v{k} along q{i}: {} vs {fd}",
                rows[k]
            );
        }
    }
}

/// The chart is the state's inverse, and moving in it is integrate on the space: the
/// chart's addition of a tangent δ lands where state_integrate does.
#[test]
fn the_chart_adds_as_the_space_integrates() {
    let s = planar();
    let [c, sn] = unit(2.9);
    let x = [0.4, c, sn, -1.2, 0.5, -0.3, 2.0];
    let chart = s.state_chart(&x);
    assert_eq!(chart.len(), 6);
    let back = s.state_from_chart(&chart);
    for (a, b) in back.iter().zip(&x) {
        // One atan2 and one cos/sin of order-one values.
        assert!((a - b).abs() < 1e-15, "{back:?} vs {x:?}");
    }
    let d = [0.1, 0.9, -0.2, 0.3, 0.0, -1.0];
    let moved: Vec<f64> = chart.iter().zip(&d).map(|(a, b)| a + b).collect();
    let there = s.state_integrate(&x, &d);
    for (a, b) in s.state_from_chart(&moved).iter().zip(&there) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
}
