//! Small dense row-major f64 matrices for control (n ≤ a few dozen): products, transposes,
//! Cholesky factorization and solves (`linalg::cholesky`, in the [`StdSum`] order control's
//! recorded answers were computed in). Nothing forms an inverse.

use crate::array::Array;
use crate::error::{Error, Result};
use crate::linalg::cholesky::{self, Square, StdSum};

/// A row-major matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Mat {
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
}

impl Mat {
    pub fn new(rows: usize, cols: usize, data: Vec<f64>) -> Self {
        assert_eq!(
            data.len(),
            rows * cols,
            "matrix data does not fit its shape"
        );
        Self { rows, cols, data }
    }

    /// A `[rows ≥ 1, cols]` array of finite values as a matrix; `field` names it in errors.
    pub fn from_array(field: &str, a: Array) -> Result<Self> {
        if a.shape.len() != 2 {
            return Err(Error::invalid(
                field,
                format!("shape must be [rows, cols], got {:?}", a.shape),
            ));
        }
        let cols = a.dim(1);
        let rows = a.rows(field, cols)?;
        Ok(Self::new(rows, cols, a.data))
    }

    /// The matrices' values one after another, with the shape `[count, rows, cols]` (every
    /// matrix `rows × cols`; `[0, 0, 0]` when there are none).
    pub fn stack(mats: Vec<Mat>) -> Array {
        let (rows, cols) = mats.first().map_or((0, 0), |m| (m.rows, m.cols));
        let count = mats.len();
        Array::new(
            &[count, rows, cols],
            mats.into_iter().flat_map(|m| m.data).collect(),
        )
    }

    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self::new(rows, cols, vec![0.0; rows * cols])
    }

    /// The square matrix with `v` on its diagonal.
    pub fn diag(v: &[f64]) -> Self {
        let n = v.len();
        let mut m = Self::zeros(n, n);
        for (i, x) in v.iter().enumerate() {
            m.data[i * n + i] = *x;
        }
        m
    }

    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.cols + j]
    }

    pub fn t(&self) -> Mat {
        let mut out = Mat::zeros(self.cols, self.rows);
        for i in 0..self.rows {
            for j in 0..self.cols {
                out.data[j * self.rows + i] = self.at(i, j);
            }
        }
        out
    }

    pub fn mul(&self, o: &Mat) -> Mat {
        assert_eq!(self.cols, o.rows, "inner dimensions differ");
        let mut out = Mat::zeros(self.rows, o.cols);
        for i in 0..self.rows {
            for k in 0..self.cols {
                let a = self.at(i, k);
                if a == 0.0 {
                    continue;
                }
                let row = &o.data[k * o.cols..(k + 1) * o.cols];
                for (x, b) in out.data[i * o.cols..(i + 1) * o.cols].iter_mut().zip(row) {
                    *x += a * b;
                }
            }
        }
        out
    }

    pub fn add(&self, o: &Mat) -> Mat {
        Mat::new(
            self.rows,
            self.cols,
            self.data.iter().zip(&o.data).map(|(a, b)| a + b).collect(),
        )
    }

    pub fn sub(&self, o: &Mat) -> Mat {
        Mat::new(
            self.rows,
            self.cols,
            self.data.iter().zip(&o.data).map(|(a, b)| a - b).collect(),
        )
    }

    /// (M + Mᵀ)/2: removes the asymmetry rounding leaves in a Riccati recursion.
    pub fn symmetrized(&self) -> Mat {
        let t = self.t();
        Mat::new(
            self.rows,
            self.cols,
            self.data
                .iter()
                .zip(&t.data)
                .map(|(a, b)| 0.5 * (a + b))
                .collect(),
        )
    }

    /// max |M_ij − M_ji| relative to max(1, max |M_ij|).
    pub fn asymmetry(&self) -> f64 {
        let scale = self.data.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        let mut worst = 0.0f64;
        for i in 0..self.rows {
            for j in 0..i {
                worst = worst.max((self.at(i, j) - self.at(j, i)).abs());
            }
        }
        worst / scale
    }

    /// The lower Cholesky factor of a symmetric positive-definite matrix (zero above its
    /// diagonal), or `None` when a pivot is not positive and finite (the matrix is not positive
    /// definite).
    pub fn cholesky(&self) -> Option<Mat> {
        debug_assert_eq!(self.rows, self.cols, "a square matrix");
        let n = self.rows;
        let mut l = Mat::zeros(n, n);
        cholesky::factor_checked(&self.data, n, &mut l.data, StdSum).ok()?;
        Some(l)
    }
}

/// Solves (L Lᵀ) X = B for X, every column of B a right-hand side, given the lower Cholesky
/// factor L.
pub fn cholesky_solve(l: &Mat, b: &Mat) -> Mat {
    let mut x = b.clone();
    cholesky::solve_by(&l.data, Square(l.rows), &mut x.data, b.cols, StdSum);
    x
}
