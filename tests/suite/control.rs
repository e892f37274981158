//! TVLQR against independent references: the batch least-squares solution of the same
//! finite-horizon problem, the discrete algebraic Riccati equation for a long constant
//! horizon, and the closed-loop cost x₀ᵀS₀x₀.

use crate::common;

use common::{gauss_solve, rel_err};
use graybox::control::linalg::Mat;
use graybox::control::tvlqr::tvlqr;
use graybox::error::Error;
use graybox::rng::Rng;

fn random(rows: usize, cols: usize, scale: f64, r: &mut Rng) -> Mat {
    Mat::new(
        rows,
        cols,
        (0..rows * cols).map(|_| scale * r.normal()).collect(),
    )
}

/// A symmetric positive-definite matrix: G Gᵀ + εI.
fn spd(n: usize, r: &mut Rng) -> Mat {
    let g = random(n, n, 1.0, r);
    let mut s = g.mul(&g.t());
    for i in 0..n {
        s.data[i * n + i] += 0.1;
    }
    s
}

fn quad(x: &[f64], w: &Mat) -> f64 {
    let v = Mat::new(x.len(), 1, x.to_vec());
    v.t().mul(w).mul(&v).data[0]
}

/// Minimizes the cost over the whole input sequence at once: x = Φx₀ + Γu makes it a
/// quadratic uᵀHu + 2uᵀg + c, solved by Gaussian elimination. The first input must be
/// −K₀x₀, the policy's rollout must reproduce every input, and the optimal cost is x₀ᵀS₀x₀.
#[test]
fn matches_batch_least_squares_on_a_time_varying_problem() {
    let mut r = Rng::new(4);
    let (nx, m, horizon) = (3, 2, 6);
    let a: Vec<Mat> = (0..horizon).map(|_| random(nx, nx, 0.6, &mut r)).collect();
    let b: Vec<Mat> = (0..horizon).map(|_| random(nx, m, 0.8, &mut r)).collect();
    let (q, rr, qf) = (spd(nx, &mut r), spd(m, &mut r), spd(nx, &mut r));
    let gains = tvlqr(&a, &b, &q, &rr, &qf).unwrap();
    assert_eq!((gains.k.len(), gains.s.len()), (horizon, horizon + 1));
    let x0: Vec<f64> = (0..nx).map(|_| r.normal()).collect();

    // x_t = Φ_t x0 + Σ_{s<t} Γ_{t,s} u_s; build the cost's Hessian and gradient in u.
    let nu = m * horizon;
    let mut phi = vec![Mat::new(
        nx,
        nx,
        (0..nx * nx)
            .map(|k| if k / nx == k % nx { 1.0 } else { 0.0 })
            .collect(),
    )];
    let mut gamma: Vec<Mat> = vec![Mat::zeros(nx, nu)];
    for t in 0..horizon {
        phi.push(a[t].mul(&phi[t]));
        let mut g = a[t].mul(&gamma[t]);
        for i in 0..nx {
            for j in 0..m {
                g.data[i * nu + t * m + j] += b[t].at(i, j);
            }
        }
        gamma.push(g);
    }
    let mut h = Mat::zeros(nu, nu);
    let mut grad = Mat::zeros(nu, 1);
    let x0m = Mat::new(nx, 1, x0.clone());
    for t in 0..=horizon {
        let w = if t == horizon { &qf } else { &q };
        h = h.add(&gamma[t].t().mul(w).mul(&gamma[t]));
        grad = grad.add(&gamma[t].t().mul(w).mul(&phi[t]).mul(&x0m));
    }
    for t in 0..horizon {
        for i in 0..m {
            for j in 0..m {
                h.data[(t * m + i) * nu + t * m + j] += rr.at(i, j);
            }
        }
    }
    let hrows: Vec<Vec<f64>> = h.data.chunks(nu).map(<[f64]>::to_vec).collect();
    let u_star = gauss_solve(hrows, grad.data.iter().map(|g| -g).collect());

    // Roll the policy u_t = −K_t x_t out on the same linear system.
    let mut x = x0.clone();
    let mut cost = 0.0;
    for t in 0..horizon {
        let xm = Mat::new(nx, 1, x.clone());
        let u: Vec<f64> = gains.k[t].mul(&xm).data.iter().map(|v| -v).collect();
        assert!(
            rel_err(&u, &u_star[t * m..(t + 1) * m]) < 1e-9,
            "u_{t}: {u:?} vs {:?}",
            &u_star[t * m..(t + 1) * m]
        );
        cost += quad(&x, &q) + quad(&u, &rr);
        x = a[t].mul(&xm).add(&b[t].mul(&Mat::new(m, 1, u))).data;
    }
    cost += quad(&x, &qf);
    let predicted = quad(&x0, &gains.s[0]);
    assert!(
        (cost - predicted).abs() < 1e-9 * cost.abs().max(1.0),
        "closed-loop cost {cost} vs x0ᵀS0x0 {predicted}"
    );
}

/// A long constant horizon converges to the infinite-horizon solution: S₀ satisfies the
/// discrete algebraic Riccati equation P = Q + AᵀPA − AᵀPB(R + BᵀPB)⁻¹BᵀPA (the condition
/// python-control's dlqr solves), in the standard form rather than the Joseph form used inside.
#[test]
fn long_constant_horizon_solves_the_algebraic_riccati_equation() {
    let mut r = Rng::new(8);
    let (nx, m) = (4, 2);
    let a = random(nx, nx, 0.5, &mut r);
    let b = random(nx, m, 1.0, &mut r);
    let (q, rr) = (spd(nx, &mut r), spd(m, &mut r));
    let horizon = 400;
    let gains = tvlqr(
        &vec![a.clone(); horizon],
        &vec![b.clone(); horizon],
        &q,
        &rr,
        &q,
    )
    .unwrap();
    let p = &gains.s[0];
    let bpb = rr.add(&b.t().mul(p).mul(&b));
    let bpa = b.t().mul(p).mul(&a);
    let rows: Vec<Vec<f64>> = bpb.data.chunks(m).map(<[f64]>::to_vec).collect();
    // (R + BᵀPB)⁻¹ BᵀPA column by column with an independent solver.
    let mut kinf = Mat::zeros(m, nx);
    for c in 0..nx {
        let col = gauss_solve(rows.clone(), (0..m).map(|i| bpa.at(i, c)).collect());
        for (i, v) in col.into_iter().enumerate() {
            kinf.data[i * nx + c] = v;
        }
    }
    let residual = q
        .add(&a.t().mul(p).mul(&a))
        .sub(&a.t().mul(p).mul(&b).mul(&kinf))
        .sub(p);
    let scale = p.data.iter().fold(1.0f64, |s, x| s.max(x.abs()));
    let worst = residual.data.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    assert!(worst < 1e-9 * scale, "DARE residual {worst}");
    assert!(rel_err(&gains.k[0].data, &kinf.data) < 1e-9);
}

#[test]
fn bad_weights_are_refused_naming_them() {
    let mut r = Rng::new(2);
    let a = vec![random(2, 2, 1.0, &mut r)];
    let b = vec![random(2, 1, 1.0, &mut r)];
    let eye2 = Mat::new(2, 2, vec![1.0, 0.0, 0.0, 1.0]);
    let one = Mat::new(1, 1, vec![1.0]);
    let field = |res: Result<_, Error>| match res {
        Err(Error::Invalid { field, .. }) => field,
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("accepted"),
    };
    let asym = Mat::new(2, 2, vec![1.0, 0.5, 0.0, 1.0]);
    assert_eq!(field(tvlqr(&a, &b, &asym, &one, &eye2)), "Q");
    let indefinite = Mat::new(2, 2, vec![1.0, 0.0, 0.0, -1.0]);
    assert_eq!(field(tvlqr(&a, &b, &eye2, &one, &indefinite)), "Qf");
    assert_eq!(
        field(tvlqr(&a, &b, &eye2, &Mat::new(1, 1, vec![0.0]), &eye2)),
        "R"
    );
    assert_eq!(field(tvlqr(&a, &b, &eye2, &eye2, &eye2)), "R");
    assert_eq!(field(tvlqr(&a, &[], &eye2, &one, &eye2)), "horizon");
    // PSD (not PD) state weights are fine.
    assert!(
        tvlqr(
            &a,
            &b,
            &Mat::new(2, 2, vec![1.0, 0.0, 0.0, 0.0]),
            &one,
            &Mat::zeros(2, 2)
        )
        .is_ok()
    );
}

/// Golden TVLQR problems written by `scripts/tvlqr_fixtures.py` with numpy, scipy and
/// python-control (regenerate with the test venv: `.venv/bin/python scripts/tvlqr_fixtures.py`).
struct Fixture {
    a: Vec<Mat>,
    b: Vec<Mat>,
    q: Mat,
    r: Mat,
    qf: Mat,
    k: Vec<Mat>,
    s: Vec<Mat>,
    x0: Vec<f64>,
    cost: f64,
    dlqr: Option<(Mat, Mat)>,
}

fn fixture(name: &str) -> Fixture {
    let path = format!(
        "{}/tests/fixtures/tvlqr/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("fixture")).expect("JSON");
    let (nx, nu) = (
        v["n_x"].as_u64().unwrap() as usize,
        v["n_u"].as_u64().unwrap() as usize,
    );
    let flat = |x: &serde_json::Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_f64().unwrap())
            .collect()
    };
    let mats = |key: &str, r: usize, c: usize| -> Vec<Mat> {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| Mat::new(r, c, flat(m)))
            .collect()
    };
    Fixture {
        a: mats("A", nx, nx),
        b: mats("B", nx, nu),
        q: Mat::new(nx, nx, flat(&v["Q"])),
        r: Mat::new(nu, nu, flat(&v["R"])),
        qf: Mat::new(nx, nx, flat(&v["Qf"])),
        k: mats("K", nu, nx),
        s: mats("S", nx, nx),
        x0: flat(&v["x0"]),
        cost: v["cost"].as_f64().unwrap(),
        dlqr: (!v["dlqr_K"].is_null()).then(|| {
            (
                Mat::new(nu, nx, flat(&v["dlqr_K"])),
                Mat::new(nx, nx, flat(&v["dlqr_S"])),
            )
        }),
    }
}

/// Our gains and cost-to-go vs the fixture's at every step, and the fixture's simulated
/// closed-loop cost vs x₀ᵀS₀x₀ from ours. 1e-9 relative: both sides are f64 recursions on
/// well-conditioned data (the script checks its references agree to ~1e-15), so only a wrong
/// formula, sign or index can move them by more.
fn check_fixture(name: &str) -> Fixture {
    let f = fixture(name);
    let g = tvlqr(&f.a, &f.b, &f.q, &f.r, &f.qf).expect("valid fixture weights");
    assert_eq!((g.k.len(), g.s.len()), (f.k.len(), f.s.len()));
    for (t, (ours, want)) in g.k.iter().zip(&f.k).enumerate() {
        let e = rel_err(&ours.data, &want.data);
        assert!(e < 1e-9, "{name}: K_{t} differs by {e:e}");
    }
    for (t, (ours, want)) in g.s.iter().zip(&f.s).enumerate() {
        let e = rel_err(&ours.data, &want.data);
        assert!(e < 1e-9, "{name}: S_{t} differs by {e:e}");
    }
    let j0 = quad(&f.x0, &g.s[0]);
    assert!(
        (j0 - f.cost).abs() < 1e-9 * f.cost.abs().max(1.0),
        "{name}: x0ᵀS0x0 = {j0} vs simulated cost {}",
        f.cost
    );
    f
}

#[test]
fn golden_time_varying_fixture_equals_batch_least_squares() {
    check_fixture("time_varying_short");
}

#[test]
fn golden_long_constant_horizon_converges_to_python_control_dlqr() {
    let f = check_fixture("constant_long");
    let (k_inf, s_inf) = f.dlqr.expect("the constant fixture carries dlqr's K and S");
    let g = tvlqr(&f.a, &f.b, &f.q, &f.r, &f.qf).unwrap();
    let (ek, es) = (
        rel_err(&g.k[0].data, &k_inf.data),
        rel_err(&g.s[0].data, &s_inf.data),
    );
    assert!(
        ek < 1e-9 && es < 1e-9,
        "K0 vs dlqr {ek:e}, S0 vs dlqr {es:e}"
    );
}

/// A request's array is read only as the shape it claims, and every claim is checked: a shape
/// of the wrong rank or count (one whose product wraps around to the count included) or a
/// non-finite value names the field; a stack keeps the matrices' order.
#[test]
fn arrays_become_matrices_only_when_their_shape_holds() {
    use graybox::array::Array;
    let field = |a: Array| match Mat::from_array("Q", a) {
        Err(Error::Invalid { field, .. }) => field,
        other => panic!("expected an invalid-argument error, got {other:?}"),
    };
    let a = |shape: Vec<u64>, data: Vec<f64>| Array { data, shape };
    assert_eq!(field(a(vec![4], vec![0.0; 4])), "Q");
    assert_eq!(field(a(vec![1, 2, 2], vec![0.0; 4])), "Q");
    assert_eq!(field(a(vec![2, 3], vec![0.0; 4])), "Q");
    assert_eq!(field(a(vec![0, 0], vec![])), "Q");
    // 2⁶³ + 1 rows of 2: the product wraps to 2 in 64 bits.
    assert_eq!(field(a(vec![(1 << 63) + 1, 2], vec![0.0; 2])), "Q");
    assert_eq!(field(a(vec![1, 2], vec![0.0, f64::INFINITY])), "Q");
    let m = Mat::from_array("Q", a(vec![2, 3], (0..6).map(f64::from).collect())).unwrap();
    assert_eq!((m.rows, m.cols, m.at(1, 0)), (2, 3, 3.0));

    let twice = Mat::new(2, 3, m.data.iter().map(|v| 2.0 * v).collect());
    let stacked = Mat::stack(vec![m.clone(), twice.clone()]);
    assert_eq!(stacked.shape, vec![2, 2, 3]);
    assert_eq!(&stacked.data[..6], &m.data[..]);
    assert_eq!(&stacked.data[6..], &twice.data[..]);
}
