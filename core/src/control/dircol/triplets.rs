//! A sparse matrix gathered entry by entry, then compressed by column for clarabel: what
//! `CscMatrix::new_from_triplets` does, in time linear in the entries. That sorts every entry
//! by comparison (a collocation of 200 knots pushes ~10⁴ entries per QP, twice per SQP
//! iteration, and the sort took ~7 % of the plan); here a counting sort by column, then each
//! short column by row, gives the same order, so the same matrix to the bit.

use clarabel::algebra::CscMatrix;

/// Entries (i, j, v) in the order they were pushed; a repeated (i, j) is summed.
#[derive(Default)]
pub(super) struct Triplets {
    rows: Vec<usize>,
    cols: Vec<usize>,
    values: Vec<f64>,
}

impl Triplets {
    pub(super) fn push(&mut self, i: usize, j: usize, v: f64) {
        self.rows.push(i);
        self.cols.push(j);
        self.values.push(v);
    }

    /// The `rows × cols` matrix: each column's entries by row, a repeated entry's values
    /// summed in the order they were pushed (as clarabel's stable sort leaves them).
    pub(super) fn matrix(self, rows: usize, cols: usize) -> CscMatrix<f64> {
        let mut start = vec![0; cols + 1];
        for &j in &self.cols {
            start[j + 1] += 1;
        }
        for j in 0..cols {
            start[j + 1] += start[j];
        }
        // Entry indices by column, each column's in the order pushed (a stable counting sort).
        let mut order = vec![0; self.cols.len()];
        let mut next = start.clone();
        for (k, &j) in self.cols.iter().enumerate() {
            order[next[j]] = k;
            next[j] += 1;
        }
        let mut colptr = vec![0; cols + 1];
        let mut rowval = Vec::with_capacity(order.len());
        let mut nzval = Vec::with_capacity(order.len());
        for j in 0..cols {
            let column = &mut order[start[j]..start[j + 1]];
            column.sort_by_key(|&k| self.rows[k]);
            for &k in column.iter() {
                let (i, v) = (self.rows[k], self.values[k]);
                match rowval.len() > colptr[j] && rowval.last() == Some(&i) {
                    true => *nzval.last_mut().expect("an entry in this column") += v,
                    false => {
                        rowval.push(i);
                        nzval.push(v);
                    }
                }
            }
            colptr[j + 1] = rowval.len();
        }
        CscMatrix::new(rows, cols, colptr, rowval, nzval)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Against clarabel's own construction (the reference): random entries over a small
    /// matrix, so that rows repeat within columns, some columns are empty, and a repeated
    /// entry's values sum in a fixed order; equal to the bit, since both add in push order.
    #[test]
    fn compresses_as_clarabel_does() {
        let mut rng = Rng::new(7);
        for (rows, cols, entries) in [(1, 1, 0), (5, 7, 40), (30, 20, 500), (3, 50, 60)] {
            let entries: Vec<(usize, usize, f64)> = (0..entries)
                .map(|_| (rng.below(rows), rng.below(cols), rng.uniform_in(-1.0, 1.0)))
                .collect();
            let mut t = Triplets::default();
            for &(i, j, v) in &entries {
                t.push(i, j, v);
            }
            let is = entries.iter().map(|e| e.0).collect();
            let js = entries.iter().map(|e| e.1).collect();
            let vs = entries.iter().map(|e| e.2).collect();
            let ours = t.matrix(rows, cols);
            let theirs = CscMatrix::new_from_triplets(rows, cols, is, js, vs);
            assert_eq!((ours.m, ours.n), (theirs.m, theirs.n));
            assert_eq!(ours.colptr, theirs.colptr);
            assert_eq!(ours.rowval, theirs.rowval);
            let bits = |m: &CscMatrix<f64>| m.nzval.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&ours), bits(&theirs));
        }
    }
}
