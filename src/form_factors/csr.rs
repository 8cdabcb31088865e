//! F as a square sparse matrix in compressed sparse row form, with 32-bit
//! column indices: a patch id is a `u32` everywhere else, and a hemicube's
//! rows are nearly dense (the furnace's F at the defaults has 290 M
//! entries), so a `usize` column per entry (nalgebra-sparse's CSR) was 3.5
//! of its 3.7 GB.

/// A square CSR matrix of `f32` with `u32` columns, each row's columns
/// strictly increasing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csr {
    offsets: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f32>,
}

impl Csr {
    /// The matrix of `n` rows whose row i holds `cols[offsets[i]..offsets[i + 1]]`
    /// and the same range of `vals`.
    ///
    /// # Panics
    /// Where the arrays do not make such a matrix: offsets not `n + 1`,
    /// not rising or not ending at the entries' count, columns not rising
    /// within a row or not below `n` (a caller's bug, not bad input).
    pub fn from_parts(n: usize, offsets: Vec<usize>, cols: Vec<u32>, vals: Vec<f32>) -> Csr {
        assert_eq!(offsets.len(), n + 1, "one offset per row, and the end");
        assert_eq!(offsets.first(), Some(&0));
        assert_eq!(offsets.last(), Some(&cols.len()));
        assert_eq!(cols.len(), vals.len());
        for w in offsets.windows(2) {
            let row = &cols[w[0]..w[1]];
            assert!(
                row.windows(2).all(|c| c[0] < c[1]),
                "columns rise within a row"
            );
            assert!(
                row.last().is_none_or(|&c| (c as usize) < n),
                "columns below n"
            );
        }
        Csr {
            offsets,
            cols,
            vals,
        }
    }

    /// Rows (= columns).
    pub fn nrows(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Entries held.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// Where each row starts in [`Csr::col_indices`] and [`Csr::values`], and the end.
    pub fn row_offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// Every entry's column, row after row.
    pub fn col_indices(&self) -> &[u32] {
        &self.cols
    }

    /// Every entry's value, row after row.
    pub fn values(&self) -> &[f32] {
        &self.vals
    }

    /// Row i's columns and values.
    pub fn row(&self, i: usize) -> (&[u32], &[f32]) {
        let r = self.offsets[i]..self.offsets[i + 1];
        (&self.cols[r.clone()], &self.vals[r])
    }

    /// Every row's columns and values, in order.
    pub fn rows(&self) -> impl Iterator<Item = (&[u32], &[f32])> + '_ {
        (0..self.nrows()).map(|i| self.row(i))
    }

    /// The transpose (a counting sort by column: each of its rows keeps
    /// the rising order of the rows it came from).
    pub fn transpose(&self) -> Csr {
        let n = self.nrows();
        let mut offsets = vec![0usize; n + 1];
        for &c in &self.cols {
            offsets[c as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut next = offsets.clone();
        let mut cols = vec![0u32; self.nnz()];
        let mut vals = vec![0f32; self.nnz()];
        for (i, (row_cols, row_vals)) in self.rows().enumerate() {
            for (&c, &v) in row_cols.iter().zip(row_vals) {
                let k = &mut next[c as usize];
                cols[*k] = i as u32;
                vals[*k] = v;
                *k += 1;
            }
        }
        Csr {
            offsets,
            cols,
            vals,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Csr;

    /// The transpose moves every entry (i, j, v) to (j, i, v), and twice is
    /// the matrix itself.
    #[test]
    fn transpose_swaps_rows_and_columns() {
        // [[0, 1, 2], [3, 0, 0], [0, 4, 5]]
        let m = Csr::from_parts(
            3,
            vec![0, 2, 3, 5],
            vec![1, 2, 0, 1, 2],
            vec![1.0, 2.0, 3.0, 4.0, 5.0],
        );
        let t = m.transpose();
        assert_eq!(t.row(0), (&[1u32][..], &[3.0f32][..]));
        assert_eq!(t.row(1), (&[0u32, 2][..], &[1.0f32, 4.0][..]));
        assert_eq!(t.row(2), (&[0u32, 2][..], &[2.0f32, 5.0][..]));
        assert_eq!(t.transpose(), m);
    }

    #[test]
    #[should_panic(expected = "columns rise")]
    fn unsorted_rows_are_refused() {
        Csr::from_parts(2, vec![0, 2, 2], vec![1, 0], vec![1.0, 1.0]);
    }
}
