//! Scalings from a dataset's statistics (the `Scaling` type and how the assembly reads it
//! are in `physics::scaling`).

use crate::data::Dataset;
use crate::physics::scaling::Scaling;
use crate::physics::templates::Template;

/// Mean and standard deviation of each column; a (near-)constant column gets std 1 so that
/// standardizing it cannot divide by ~0.
fn column_stats(a: &[f64], width: usize) -> (Vec<f64>, Vec<f64>) {
    let rows = (a.len() / width).max(1) as f64;
    let mean: Vec<f64> = (0..width)
        .map(|j| a.iter().skip(j).step_by(width).sum::<f64>() / rows)
        .collect();
    let std = (0..width)
        .map(|j| {
            let var = a
                .iter()
                .skip(j)
                .step_by(width)
                .map(|x| (x - mean[j]).powi(2))
                .sum::<f64>()
                / rows;
            let s = var.sqrt();
            if s.is_finite() && s > 1e-8 * (1.0 + mean[j].abs()) {
                s
            } else {
                1.0
            }
        })
        .collect();
    (mean, std)
}

impl Scaling {
    /// `mass` gives the analytic M at the initial physical parameters when M is white-box.
    pub fn from_data(ds: &Dataset, mass: Option<(&Template, &[f64])>) -> Self {
        let (nq, n, m) = (ds.nq, ds.nv, ds.m);
        let (q_mean, q_std) = column_stats(&ds.q, nq);
        let (qdot_mean, qdot_std) = column_stats(&ds.qdot, n);
        let (u_mean, u_std) = column_stats(&ds.u, m);
        let acc: Vec<f64> = (ds.qdot_next.iter().zip(&ds.qdot).enumerate())
            .map(|(i, (b, a))| (b - a) / ds.step(i / n))
            .collect();
        let (acc_mean, acc_std) = column_stats(&acc, n);
        let force_scale = match mass {
            None => acc_std.clone(),
            Some((t, p)) => {
                let mass = t.mass_at(p);
                let tau: Vec<f64> =
                    ds.q.chunks(nq)
                        .zip(acc.chunks(n))
                        .flat_map(|(q, a)| {
                            let mm = mass(q);
                            (0..n)
                                .map(move |i| (0..n).map(|j| mm[i][j] * a[j]).sum::<f64>())
                                .collect::<Vec<_>>()
                        })
                        .collect();
                column_stats(&tau, n).1
            }
        };
        Self {
            q_mean,
            q_std,
            qdot_mean,
            qdot_std,
            u_mean,
            u_std,
            acc_mean,
            acc_std,
            force_scale,
        }
    }
}
