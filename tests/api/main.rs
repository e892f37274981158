//! Service integration tests: one binary (style.md: zero-to-production), an app per test.

mod chaos;
mod cluster;
mod configuration;
mod crash;
mod datasets;
mod ensemble;
mod ensemble_replay;
mod errors;
mod faults;
mod formula_limits;
mod grpc;
mod helpers;
mod hostile;
mod jobs;
mod logs;
mod model_uploads;
mod multistep;
mod nodes;
mod outage;
mod pg_tls;
mod plan_stop;
mod processes;
mod readiness;
mod replay;
mod shutdown;
mod step;
mod store;
mod tls;
mod uploads;
mod values;
mod web;

/// The paper's double pendulum in closed form (shared with the numerics tests).
#[path = "../common/mod.rs"]
mod common;

pub fn common_dp(p: &[f64; 9], q: &[f64], qd: &[f64], u: &[f64]) -> [f64; 2] {
    common::double_pendulum_accel(p, q, qd, u)
}

pub fn common_rel(a: &[f64], b: &[f64]) -> f64 {
    common::rel_err(a, b)
}

/// Backward Riccati recursion (standard form) for K_t from row-major A_t, B_t.
#[allow(clippy::too_many_arguments)]
pub fn riccati(
    a: &[f64],
    b: &[f64],
    t: usize,
    nx: usize,
    m: usize,
    q: &[f64],
    r: &[f64],
    qf: &[f64],
) -> Vec<f64> {
    use graybox::control::linalg::Mat;
    let (qm, rm) = (Mat::new(nx, nx, q.to_vec()), Mat::new(m, m, r.to_vec()));
    let mut s = Mat::new(nx, nx, qf.to_vec());
    let mut ks = vec![];
    for i in (0..t).rev() {
        let at = Mat::new(nx, nx, a[i * nx * nx..(i + 1) * nx * nx].to_vec());
        let bt = Mat::new(nx, m, b[i * nx * m..(i + 1) * nx * m].to_vec());
        let h = rm.add(&bt.t().mul(&s).mul(&bt));
        let rhs = bt.t().mul(&s).mul(&at);
        let hrows: Vec<Vec<f64>> = h.data.chunks(m).map(<[f64]>::to_vec).collect();
        let mut k = Mat::zeros(m, nx);
        for c in 0..nx {
            let col = common::gauss_solve(hrows.clone(), (0..m).map(|r| rhs.at(r, c)).collect());
            for (r, v) in col.into_iter().enumerate() {
                k.data[r * nx + c] = v;
            }
        }
        // S = Q + AᵀS A − AᵀS B K
        s = qm
            .add(&at.t().mul(&s).mul(&at))
            .sub(&at.t().mul(&s).mul(&bt).mul(&k));
        ks.push(k);
    }
    ks.reverse();
    ks.into_iter().flat_map(|k| k.data).collect()
}
