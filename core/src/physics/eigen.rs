//! Eigenvalues and eigenvectors of a small symmetric matrix by cyclic Jacobi rotations
//! (robust for any spectrum, O(n³) per sweep: microseconds for a robot's n).

/// The eigenvalues of the symmetric `a` and its eigenvectors as columns (`vectors[i][k]` is
/// component i of the k-th, of unit length), in no particular order.
pub fn symmetric_eigen(a: &[Vec<f64>]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = a.len();
    let mut a = a.to_vec();
    let mut v: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    let norm: f64 = a.iter().flatten().map(|x| x * x).sum();
    // Each column pair (p, q) of A·J, and of V·J, turned by the rotation.
    let turn = |m: &mut Vec<Vec<f64>>, p: usize, q: usize, c: f64, s: f64| {
        for row in m.iter_mut() {
            let (kp, kq) = (row[p], row[q]);
            row[p] = c * kp - s * kq;
            row[q] = s * kp + c * kq;
        }
    };
    for _ in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|p| (p + 1..n).map(move |q| (p, q)))
            .map(|(p, q)| a[p][q] * a[p][q])
            .sum();
        if off <= 1e-30 * norm {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                if a[p][q] == 0.0 {
                    continue;
                }
                // The rotation that zeroes a_pq (the smaller root t of t² + 2θt − 1 = 0).
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                turn(&mut a, p, q, c, s);
                turn(&mut v, p, q, c, s);
                let (mut rp, mut rq) = (std::mem::take(&mut a[p]), std::mem::take(&mut a[q]));
                for (x, y) in rp.iter_mut().zip(rq.iter_mut()) {
                    (*x, *y) = (c * *x - s * *y, s * *x + c * *y);
                }
                (a[p], a[q]) = (rp, rq);
            }
        }
    }
    ((0..n).map(|i| a[i][i]).collect(), v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A v = λ v for every pair, the vectors orthonormal, on a 4×4 with a double eigenvalue.
    #[test]
    fn pairs_satisfy_the_definition() {
        let a = vec![
            vec![4.0, 1.0, 0.0, 0.0],
            vec![1.0, 4.0, 0.0, 0.0],
            vec![0.0, 0.0, 5.0, 0.0],
            vec![0.0, 0.0, 0.0, 2.0],
        ];
        let (values, v) = symmetric_eigen(&a);
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        for (got, want) in sorted.iter().zip([2.0, 3.0, 5.0, 5.0]) {
            assert!((got - want).abs() < 1e-12, "{sorted:?}");
        }
        for k in 0..4 {
            for i in 0..4 {
                let av: f64 = (0..4).map(|j| a[i][j] * v[j][k]).sum();
                assert!((av - values[k] * v[i][k]).abs() < 1e-12);
            }
            for l in 0..4 {
                let d: f64 = (0..4).map(|i| v[i][k] * v[i][l]).sum();
                assert!((d - if k == l { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }
}
