//! The MVF ensemble's spread against the truth: per held-out sample the true one-step error of
//! the members' mean and the members' σ, per coordinate and as norms; coverage of mean ± 2σ,
//! the error by bucket with the σ in it, and Spearman's rank correlation of σ and error.

use serde::Serialize;

use graybox::data::Dataset;
use graybox::error::{Error, Result};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;

/// The state's coordinates, in x's order.
pub const COORDS: [&str; 4] = ["q1", "q2", "q̇1", "q̇2"];
/// Buckets of the true error: its deciles.
const BUCKETS: usize = 10;

/// Per sample: ‖mean − truth‖ and ‖σ‖ (the plot's points), and per coordinate.
pub struct Points {
    pub error: Vec<f64>,
    pub sigma: Vec<f64>,
    /// [B, 4] row-major: |mean − truth| and σ.
    coord_error: Vec<f64>,
    coord_sigma: Vec<f64>,
    /// Whether the sample's q̇ lies inside the training range in every coordinate.
    inside: Vec<bool>,
}

impl Points {
    fn subset(&self, keep: impl Fn(usize) -> bool) -> Points {
        let rows: Vec<usize> = (0..self.error.len()).filter(|&i| keep(i)).collect();
        let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect();
        let pick4 = |v: &[f64]| -> Vec<f64> {
            rows.iter()
                .flat_map(|&i| v[4 * i..4 * i + 4].to_vec())
                .collect()
        };
        Points {
            error: pick(&self.error),
            sigma: pick(&self.sigma),
            coord_error: pick4(&self.coord_error),
            coord_sigma: pick4(&self.coord_sigma),
            inside: rows.iter().map(|&i| self.inside[i]).collect(),
        }
    }
}

/// One set's figures.
#[derive(Debug, Clone, Serialize)]
pub struct SetResult {
    pub name: String,
    pub samples: usize,
    /// Per coordinate, the share of true values inside mean ± 2σ.
    pub coverage_2sigma: [f64; 4],
    /// Per coordinate, the factor σ would need for 95% coverage: the 95th percentile of
    /// |error| / σ (2 for a calibrated Gaussian).
    pub factor_for_95: [f64; 4],
    pub mean_error: f64,
    pub median_error: f64,
    pub mean_sigma: f64,
    pub median_sigma: f64,
    /// Spearman's ρ of ‖σ‖ and ‖error‖, and per coordinate of σᵢ and |errorᵢ|.
    pub spearman: f64,
    pub spearman_coord: [f64; 4],
    pub buckets: Vec<Bucket>,
}

/// Samples whose true error lies in one decile.
#[derive(Debug, Clone, Serialize)]
pub struct Bucket {
    /// Quantiles of the true error bounding the bucket, and its errors' range.
    pub from_quantile: f64,
    pub to_quantile: f64,
    pub error_min: f64,
    pub error_max: f64,
    pub samples: usize,
    pub mean_error: f64,
    pub mean_sigma: f64,
    /// The bucket's share of samples with every coordinate inside mean ± 2σ.
    pub coverage_all: f64,
}

/// The evaluation: the in-distribution and out-of-distribution sets' figures, and the latter's
/// samples outside the training range on their own.
pub struct Calibration {
    pub sets: Vec<SetResult>,
    pub in_dist: Points,
    pub ood: Points,
}

pub fn evaluate(
    file: &ModelFile,
    in_dist: &Dataset,
    ood: &Dataset,
    train_range: f64,
) -> Result<Calibration> {
    let eval = Evaluator::from_file(file)?;
    let in_dist = points(&eval, in_dist, train_range)?;
    let ood = points(&eval, ood, train_range)?;
    let outside = ood.subset(|i| !ood.inside[i]);
    let sets = vec![
        summarize("in distribution", &in_dist),
        summarize("out of distribution", &ood),
        summarize("out of distribution, q̇ outside training range", &outside),
    ];
    Ok(Calibration { sets, in_dist, ood })
}

/// Each sample's true error and spread.
fn points(eval: &Evaluator, ds: &Dataset, train_range: f64) -> Result<Points> {
    // The double pendulum's data: q and q̇ of one width.
    let (n, rows) = (ds.nv, ds.count());
    let mut x = Vec::with_capacity(rows * 2 * n);
    let mut truth = Vec::with_capacity(rows * 2 * n);
    for i in 0..rows {
        let r = i * n..(i + 1) * n;
        x.extend_from_slice(&ds.q[r.clone()]);
        x.extend_from_slice(&ds.qdot[r.clone()]);
        truth.extend_from_slice(&ds.q_next[r.clone()]);
        truth.extend_from_slice(&ds.qdot_next[r]);
    }
    let p = eval
        .predict_members_until(&x, &ds.u, eval.config.dt, false, &|| false)
        .ok_or_else(|| Error::Internal("prediction stopped".into()))?;
    if eval.member_count() < 2 {
        return Err(Error::Internal(
            "the calibration model is one member".into(),
        ));
    }
    let periodic = &eval.config.space.periodic();
    let coord_error: Vec<f64> = (0..rows * 2 * n)
        .map(|k| {
            let d = p.mean[k] - truth[k];
            let j = k % (2 * n);
            match periodic.get(j) {
                Some(true) if j < n => wrap(d).abs(),
                _ => d.abs(),
            }
        })
        .collect();
    let norm = |v: &[f64]| -> Vec<f64> {
        (v.chunks(2 * n))
            .map(|r| r.iter().map(|e| e * e).sum::<f64>().sqrt())
            .collect()
    };
    let inside = (ds.qdot.chunks(n))
        .map(|qd| qd.iter().all(|v| v.abs() <= train_range))
        .collect();
    Ok(Points {
        error: norm(&coord_error),
        sigma: norm(&p.std),
        coord_error,
        coord_sigma: p.std,
        inside,
    })
}

/// An angle difference in (−π, π].
fn wrap(d: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let w = d - tau * (d / tau).round();
    if w <= -std::f64::consts::PI {
        w + tau
    } else {
        w
    }
}

fn summarize(name: &str, p: &Points) -> SetResult {
    let b = p.error.len();
    let coord = |j: usize| -> (Vec<f64>, Vec<f64>) {
        (0..b)
            .map(|i| (p.coord_error[4 * i + j], p.coord_sigma[4 * i + j]))
            .unzip()
    };
    let mut coverage = [0.0; 4];
    let mut factor = [0.0; 4];
    let mut rho = [0.0; 4];
    for j in 0..4 {
        let (e, s) = coord(j);
        coverage[j] = share(b, |i| e[i] <= 2.0 * s[i]);
        let ratios: Vec<f64> = e.iter().zip(&s).map(|(e, s)| e / s).collect();
        factor[j] = quantile(&ratios, 0.95);
        rho[j] = spearman(&s, &e);
    }
    let all_inside =
        |i: usize| (0..4).all(|j| p.coord_error[4 * i + j] <= 2.0 * p.coord_sigma[4 * i + j]);
    let mut order: Vec<usize> = (0..b).collect();
    order.sort_by(|&i, &j| p.error[i].total_cmp(&p.error[j]));
    let buckets = (0..BUCKETS)
        .filter_map(|k| {
            let rows = &order[k * b / BUCKETS..(k + 1) * b / BUCKETS];
            let (first, last) = (rows.first()?, rows.last()?);
            let mean = |v: &[f64]| rows.iter().map(|&i| v[i]).sum::<f64>() / rows.len() as f64;
            Some(Bucket {
                from_quantile: k as f64 / BUCKETS as f64,
                to_quantile: (k + 1) as f64 / BUCKETS as f64,
                error_min: p.error[*first],
                error_max: p.error[*last],
                samples: rows.len(),
                mean_error: mean(&p.error),
                mean_sigma: mean(&p.sigma),
                coverage_all: share(rows.len(), |r| all_inside(rows[r])),
            })
        })
        .collect();
    SetResult {
        name: name.to_string(),
        samples: b,
        coverage_2sigma: coverage,
        factor_for_95: factor,
        mean_error: mean_of(&p.error),
        median_error: quantile(&p.error, 0.5),
        mean_sigma: mean_of(&p.sigma),
        median_sigma: quantile(&p.sigma, 0.5),
        spearman: spearman(&p.sigma, &p.error),
        spearman_coord: rho,
        buckets,
    }
}

fn share(count: usize, inside: impl Fn(usize) -> bool) -> f64 {
    (0..count).filter(|&i| inside(i)).count() as f64 / count.max(1) as f64
}

fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// The `p`-quantile of `v` (linear between order statistics; NaN when empty).
fn quantile(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = p * (s.len() - 1) as f64;
    let (lo, hi) = (at.floor() as usize, at.ceil() as usize);
    s[lo] + (s[hi] - s[lo]) * (at - lo as f64)
}

/// Ranks from 1, ties given their mean rank.
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
    let mut r = vec![0.0; v.len()];
    let mut k = 0;
    while k < order.len() {
        let mut end = k + 1;
        while end < order.len() && v[order[end]] == v[order[k]] {
            end += 1;
        }
        let rank = (k + end + 1) as f64 / 2.0;
        order[k..end].iter().for_each(|&i| r[i] = rank);
        k = end;
    }
    r
}

/// Spearman's rank correlation: Pearson's of the ranks.
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let (ra, rb) = (ranks(a), ranks(b));
    let (ma, mb) = (mean_of(&ra), mean_of(&rb));
    let mut sab = 0.0;
    let mut saa = 0.0;
    let mut sbb = 0.0;
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_of_monotone_reversed_and_tied() {
        let a = [1.0, 2.0, 3.0, 4.0];
        assert!((spearman(&a, &[1.0, 4.0, 9.0, 16.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&a, &[4.0, 3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert_eq!(ranks(&[5.0, 1.0, 5.0, 2.0]), vec![3.5, 1.0, 3.5, 2.0]);
    }

    #[test]
    fn quantiles_and_wrapped_angles() {
        assert_eq!(quantile(&[3.0, 1.0, 2.0], 0.5), 2.0);
        assert_eq!(quantile(&[0.0, 10.0], 0.95), 9.5);
        assert!((wrap(2.0 * std::f64::consts::PI + 0.1) - 0.1).abs() < 1e-12);
        assert_eq!(wrap(-std::f64::consts::PI), std::f64::consts::PI);
    }
}
