use super::*;
use crate::physics::dual::Dual;
use crate::rng::Rng;

/// Higham's γ_k = k u / (1 − k u), u the unit roundoff: the bound on the relative error of k
/// roundings, in which his error analyses of Cholesky are stated.
fn gamma(k: usize) -> f64 {
    let ku = k as f64 * f64::EPSILON / 2.0;
    ku / (1.0 - ku)
}

/// B Bᵀ + n I for a normal B: symmetric positive definite, n×n row-major. With `signed_zeros`
/// row and column 0 are zero off the diagonal, half of them −0.0 (still positive definite:
/// block diagonal), for the orders that differ only in a zero's sign.
fn spd(rng: &mut Rng, n: usize, signed_zeros: bool) -> Vec<f64> {
    let b: Vec<f64> = (0..n * n).map(|_| rng.normal()).collect();
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            let dot: f64 = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum();
            a[i * n + j] = dot + if i == j { n as f64 } else { 0.0 };
        }
    }
    if signed_zeros {
        for i in 1..n {
            let z = if i % 2 == 0 { -0.0 } else { 0.0 };
            (a[i * n], a[i]) = (z, z);
        }
    }
    a
}

fn packed(a: &[f64], n: usize) -> Vec<f64> {
    (0..n).flat_map(|i| a[i * n..=i * n + i].to_vec()).collect()
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The code this module replaced, as it was: the multibody workspace's running sums…
fn old_data(a: &[f64], n: usize, x: &mut [f64], cols: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = if i == j { s.sqrt() } else { s / l[j * n + j] };
        }
    }
    for c in 0..cols {
        for i in 0..n {
            for k in 0..i {
                x[i * cols + c] -= l[i * n + k] * x[k * cols + c];
            }
            x[i * cols + c] /= l[i * n + i];
        }
        for i in (0..n).rev() {
            for k in i + 1..n {
                x[i * cols + c] -= l[k * n + i] * x[k * cols + c];
            }
            x[i * cols + c] /= l[i * n + i];
        }
    }
    l
}

/// …the manipulator equation's sums, subtracted only when there are terms (`reduce`)…
/// …and control's and the stiffness check's `sum()` (`std = true`), which starts at −0.0.
fn old_summed(a: &[f64], n: usize, x: &mut [f64], std: bool) -> Vec<f64> {
    let minus = |a: f64, terms: Vec<f64>| match (terms.into_iter().reduce(|s, t| s + t), std) {
        (Some(t), _) => a - t,
        (None, true) => a - (-0.0),
        (None, false) => a,
    };
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let d = minus(
            a[j * n + j],
            (0..j).map(|k| l[j * n + k] * l[j * n + k]).collect(),
        );
        l[j * n + j] = d.sqrt();
        for i in j + 1..n {
            let t = (0..j).map(|k| l[i * n + k] * l[j * n + k]).collect();
            l[i * n + j] = minus(a[i * n + j], t) / l[j * n + j];
        }
    }
    for i in 0..n {
        x[i] = minus(x[i], (0..i).map(|k| l[i * n + k] * x[k]).collect()) / l[i * n + i];
    }
    for i in (0..n).rev() {
        x[i] = minus(x[i], (i + 1..n).map(|k| l[k * n + i] * x[k]).collect()) / l[i * n + i];
    }
    l
}

/// Each order is, to the bit, the arithmetic of the callers that use it, in both layouts
/// (−0.0 included: answers.json compares bits).
#[test]
fn each_order_is_the_arithmetic_its_callers_had() {
    let mut rng = Rng::new(74);
    for (n, signed_zeros) in [(1, false), (2, true), (5, false), (7, true), (12, false)] {
        let a = spd(&mut rng, n, signed_zeros);
        let cols = 3;
        let mut b: Vec<f64> = (0..n * cols).map(|_| rng.normal()).collect();
        (b[0], b[n * cols - 1]) = (-0.0, -0.0);

        // One column and several: `Running` solves them in differently shaped loops.
        for cols in [1, cols] {
            let b = &b[..n * cols];
            let (mut want_x, mut got_x) = (b.to_vec(), b.to_vec());
            let want = old_data(&a, n, &mut want_x, cols);
            let mut got = vec![0.0; n * n];
            factor(&a, n, &mut got);
            solve(&got, n, &mut got_x, cols);
            assert_eq!(bits(&got), bits(&want), "running, n = {n}");
            assert_eq!(
                bits(&got_x),
                bits(&want_x),
                "running solve, n = {n}, {cols}"
            );
        }

        for std in [false, true] {
            let column: Vec<f64> = (0..n).map(|i| b[i * cols]).collect();
            let (mut want_x, mut got_x) = (column.clone(), column.clone());
            let want = old_summed(&a, n, &mut want_x, std);
            let mut got = packed(&a, n);
            if std {
                factor_in_place(&mut got, Packed(n), StdSum);
                solve_by(&got, Packed(n), &mut got_x, 1, StdSum);
            } else {
                factor_in_place(&mut got, Packed(n), Summed);
                solve_by(&got, Packed(n), &mut got_x, 1, Summed);
            }
            assert_eq!(bits(&got), bits(&packed(&want, n)), "std {std}, n = {n}");
            assert_eq!(bits(&got_x), bits(&want_x), "std {std} solve, n = {n}");
        }
        let mut square = vec![0.0; n * n];
        factor_checked(&a, n, &mut square, StdSum).unwrap();
        let old = old_summed(&a, n, &mut vec![0.0; n], true);
        assert_eq!(bits(&square), bits(&old), "checked, n = {n}");
    }
}

/// An independent reference: L with small integers, A = L Lᵀ and b = A x formed exactly.
/// Every sum, product, quotient and square root on the way back to L and x is an integer
/// below 2⁵³, so each order and layout must return them exactly.
#[test]
fn an_integer_factor_comes_back_exactly() {
    let l: [&[f64]; 4] = [
        &[2.0],
        &[-1.0, 3.0],
        &[4.0, 0.0, 1.0],
        &[1.0, 5.0, -2.0, 7.0],
    ];
    let n = l.len();
    let entry = |i: usize, j: usize| if j <= i { l[i][j] } else { 0.0 };
    let a: Vec<f64> = (0..n * n)
        .map(|e| (0..n).map(|k| entry(e / n, k) * entry(e % n, k)).sum())
        .collect();
    let x = [3.0, -1.0, 2.0, 5.0];
    let b: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| a[i * n + j] * x[j]).sum())
        .collect();
    let want: Vec<f64> = l.concat();
    fn check(order: impl Order, a: &[f64], b: &[f64], want: &[f64], x: &[f64]) {
        let n = x.len();
        let mut square = vec![f64::NAN; n * n];
        factor_checked(a, n, &mut square, order).unwrap();
        assert_eq!(packed(&square, n), want);
        // The strict upper triangle is never written.
        assert!((0..n).all(|i| (i + 1..n).all(|j| square[i * n + j].is_nan())));
        let mut in_place = packed(a, n);
        factor_in_place(&mut in_place, Packed(n), order);
        assert_eq!(in_place, want);
        let (mut xs, mut xp) = (b.to_vec(), b.to_vec());
        solve_by(&square, Square(n), &mut xs, 1, order);
        solve_by(&in_place, Packed(n), &mut xp, 1, order);
        assert_eq!((xs.as_slice(), xp.as_slice()), (x, x));
    }
    check(Running, &a, &b, &want, &x);
    check(Summed, &a, &b, &want, &x);
    check(StdSum, &a, &b, &want, &x);
}

/// |L Lᵀ − A| ≤ γ_{n+1} |L| |Lᵀ| entrywise (Higham, Accuracy and Stability of Numerical
/// Algorithms, 2nd ed., Thm 10.3, for any order of the sums). Forming L Lᵀ and |L||Lᵀ| here
/// rounds again by up to γ_n of the same, so the test allows 3 γ_{n+1}: a misplaced index
/// or term is off by O(1) of A, twelve orders of magnitude more.
#[test]
fn the_factor_reproduces_a_random_matrix_to_rounding() {
    let mut rng = Rng::new(7);
    for n in [1, 3, 8, 20] {
        let a = spd(&mut rng, n, false);
        let mut l = vec![0.0; n * n];
        factor(&a, n, &mut l);
        for i in 0..n {
            for j in 0..=i {
                let llt: f64 = (0..=j).map(|k| l[i * n + k] * l[j * n + k]).sum();
                let scale: f64 = (0..=j).map(|k| (l[i * n + k] * l[j * n + k]).abs()).sum();
                let bound = 3.0 * gamma(n + 1) * scale;
                assert!((llt - a[i * n + j]).abs() <= bound, "n = {n}, ({i}, {j})");
            }
        }
    }
}

/// The computed x solves (A + ΔA) x = b with |ΔA| ≤ γ_{3n+1} |L||Lᵀ| (Higham Thm 10.4), so
/// |b − A x| ≤ γ_{3n+1} |L||Lᵀ||x|; forming A x here adds up to γ_n |A||x|. Twice both,
/// for the roundings of the bounds themselves. Every order, several right-hand sides.
#[test]
fn a_solve_leaves_a_residual_at_rounding() {
    fn residual_within_bound(order: impl Order, a: &[f64], n: usize, b: &[f64], cols: usize) {
        let mut l = vec![0.0; n * n];
        factor_checked(a, n, &mut l, order).unwrap();
        let mut x = b.to_vec();
        solve_by(&l, Square(n), &mut x, cols, order);
        let abs_llt = |i: usize, j: usize| -> f64 {
            (0..=i.min(j))
                .map(|k| (l[i * n + k] * l[j * n + k]).abs())
                .sum()
        };
        for c in 0..cols {
            for i in 0..n {
                let ax: f64 = (0..n).map(|j| a[i * n + j] * x[j * cols + c]).sum();
                let ll_x: f64 = (0..n).map(|j| abs_llt(i, j) * x[j * cols + c].abs()).sum();
                let a_x: f64 = (0..n).map(|j| (a[i * n + j] * x[j * cols + c]).abs()).sum();
                let bound = 2.0 * (gamma(3 * n + 1) * ll_x + gamma(n) * a_x);
                let r = (b[i * cols + c] - ax).abs();
                assert!(
                    r <= bound,
                    "n = {n}, row {i}, column {c}: {r:e} > {bound:e}"
                );
            }
        }
    }
    let mut rng = Rng::new(11);
    for n in [1, 4, 9, 20] {
        let a = spd(&mut rng, n, false);
        let cols = 3;
        let b: Vec<f64> = (0..n * cols).map(|_| rng.normal() * 10.0).collect();
        residual_within_bound(Running, &a, n, &b, cols);
        residual_within_bound(Summed, &a, n, &b, cols);
        residual_within_bound(StdSum, &a, n, &b, cols);
    }
}

/// The first pivot that is not positive and finite is reported, whichever entry makes it
/// so; unchecked, the factor carries NaN from there.
#[test]
fn a_matrix_that_is_not_positive_definite_reports_its_pivot() {
    let cases: [(Vec<Vec<f64>>, usize); 6] = [
        (
            vec![
                vec![4.0, 0.0, 0.0],
                vec![0.0, 1.0, 0.0],
                vec![0.0, 0.0, -1.0],
            ],
            2,
        ),
        // A coordinate that moves no mass: a zero row.
        (
            vec![
                vec![2.0, 0.0, 1.0],
                vec![0.0, 0.0, 0.0],
                vec![1.0, 0.0, 3.0],
            ],
            1,
        ),
        // Indefinite through its off-diagonal: 1 − 2² < 0.
        (vec![vec![1.0, 2.0], vec![2.0, 1.0]], 1),
        (vec![vec![f64::NAN]], 0),
        (vec![vec![1.0, 0.0], vec![0.0, f64::INFINITY]], 1),
        (vec![vec![-0.0]], 0),
    ];
    fn pivot(order: impl Order, m: &[Vec<f64>]) -> Result<(), usize> {
        let n = m.len();
        factor_checked(&m.concat(), n, &mut vec![0.0; n * n], order)
    }
    for (m, want) in cases {
        assert_eq!(factor_rows(&m).map(|_| ()), Err(want), "{m:?}");
        assert_eq!(pivot(Running, &m), Err(want), "{m:?}");
        assert_eq!(pivot(Summed, &m), Err(want), "{m:?}");
    }
    let mut l = vec![0.0; 4];
    factor(&[1.0, 2.0, 2.0, 1.0], 2, &mut l);
    assert_eq!(l[0], 1.0);
    assert!(l[3].is_nan(), "{l:?}");
    assert_eq!(
        factor_rows(&[vec![4.0, 2.0], vec![2.0, 2.0]]),
        Ok(vec![2.0, 0.0, 1.0, 1.0])
    );
}

/// Over dual numbers the factor and the solve carry their derivatives: d/dt of L(A + t Ȧ)
/// and of (A + t Ȧ)⁻¹ b against central differences of the f64 code (step 1e-5: truncation
/// O(h²) ≈ 1e-10 and rounding O(u/h) ≈ 1e-11 of the values, well inside 1e-7).
#[test]
fn dual_numbers_differentiate_the_factor_and_the_solve() {
    let mut rng = Rng::new(3);
    let n = 5;
    let (a, da) = (spd(&mut rng, n, false), spd(&mut rng, n, false));
    let b: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
    let t = Dual::variable(0.0, 0, 1, 1.0);
    let a_t: Vec<Dual<f64>> = (a.iter().zip(&da))
        .map(|(&v, &d)| Dual::constant(v) + Dual::constant(d) * t.clone())
        .collect();
    let mut l = vec![Dual::constant(0.0); n * n];
    factor(&a_t, n, &mut l);
    let mut x: Vec<Dual<f64>> = b.iter().map(|&v| Dual::constant(v)).collect();
    solve(&l, n, &mut x, 1);
    let h = 1e-5;
    let at = |s: f64| -> (Vec<f64>, Vec<f64>) {
        let m: Vec<f64> = (a.iter().zip(&da)).map(|(v, d)| v + s * d).collect();
        let (mut l, mut x) = (vec![0.0; n * n], b.clone());
        factor(&m, n, &mut l);
        solve(&l, n, &mut x, 1);
        (l, x)
    };
    let ((lp, xp), (lm, xm)) = (at(h), at(-h));
    let close = |dual: &Dual<f64>, p: f64, m: f64| {
        let fd = (p - m) / (2.0 * h);
        let got = dual.tangent(0).copied().unwrap_or(0.0);
        assert!((got - fd).abs() <= 1e-7 * (1.0 + fd.abs()), "{got} vs {fd}");
    };
    for i in 0..n {
        (0..=i).for_each(|j| close(&l[i * n + j], lp[i * n + j], lm[i * n + j]));
        close(&x[i], xp[i], xm[i]);
    }
}
