//! F as a square sparse matrix in compressed sparse row form whose columns
//! are held as runs of consecutive columns.
//!
//! A hemicube's rows are nearly dense: the furnace's F at the defaults has
//! 290 M entries in 14.2 M runs (20 entries a run on average). A `u32`
//! column per entry was 1.16 GB of its 2.6 GB bake, and Jacobi's product
//! read 8 bytes per entry; as runs, the columns are 114 MB and the product
//! reads 4.4 bytes per entry, walking `x` in order within a run. (A `usize`
//! column per entry, nalgebra-sparse's CSR, was 3.5 of a 3.7 GB bake.)

/// A run of a row's consecutive columns: its first column and where it
/// starts among the row's entries (it ends where the next run starts, or
/// at the row's end).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Run {
    /// First column of the run.
    pub col: u32,
    /// Index of the run's first entry within its row.
    pub at: u32,
}

/// A square CSR matrix of `f32` whose rows' columns strictly rise and are
/// held as [`Run`]s.
#[derive(Clone, Debug, PartialEq)]
pub struct Csr {
    /// Where each row starts in `vals`, and the end.
    offsets: Vec<usize>,
    /// Where each row starts in `runs`, and the end.
    run_offsets: Vec<usize>,
    runs: Vec<Run>,
    vals: Vec<f32>,
}

impl Default for Csr {
    fn default() -> Self {
        Csr::new()
    }
}

/// One row of a [`Csr`]: its runs and values.
#[derive(Clone, Copy, Debug)]
pub struct Row<'a> {
    /// The row's runs of columns.
    pub runs: &'a [Run],
    /// The row's values, in column order.
    pub vals: &'a [f32],
}

impl<'a> Row<'a> {
    /// Entries held.
    pub fn len(&self) -> usize {
        self.vals.len()
    }

    /// True when the row holds nothing.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }

    /// Each run as (first column, its values).
    #[inline]
    pub fn segments(&self) -> impl Iterator<Item = (u32, &'a [f32])> + 'a {
        let (runs, vals) = (self.runs, self.vals);
        runs.iter().enumerate().map(move |(r, run)| {
            let end = runs.get(r + 1).map_or(vals.len(), |n| n.at as usize);
            (run.col, &vals[run.at as usize..end])
        })
    }

    /// Every entry as (column, value), in column order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, f32)> + 'a {
        self.segments()
            .flat_map(|(c, v)| v.iter().enumerate().map(move |(k, &x)| (c + k as u32, x)))
    }

    /// The index among the row's entries of column `j`, if held.
    pub fn find(&self, j: u32) -> Option<usize> {
        let r = self
            .runs
            .partition_point(|run| run.col <= j)
            .checked_sub(1)?;
        let run = self.runs[r];
        let k = run.at as usize + (j - run.col) as usize;
        let end = self
            .runs
            .get(r + 1)
            .map_or(self.vals.len(), |n| n.at as usize);
        (k < end).then_some(k)
    }

    /// The column of the row's entry `k` (< [`Row::len`]).
    pub fn col(&self, k: usize) -> u32 {
        let r = self.runs.partition_point(|run| run.at as usize <= k) - 1;
        self.runs[r].col + (k - self.runs[r].at as usize) as u32
    }
}

impl Csr {
    /// The matrix of no rows, to which [`Csr::push_row`] appends.
    pub fn new() -> Csr {
        Csr {
            offsets: vec![0],
            run_offsets: vec![0],
            runs: Vec::new(),
            vals: Vec::new(),
        }
    }

    /// Appends a row from its entries (column, value), columns strictly
    /// rising.
    ///
    /// # Panics
    /// Where they do not rise (a caller's bug, not bad input).
    pub fn push_row(&mut self, row: impl IntoIterator<Item = (u32, f32)>) {
        let row: Vec<(u32, f32)> = row.into_iter().collect();
        self.push_sorted(&row);
    }

    /// [`Csr::push_row`] of a row held as a slice: its values copied in
    /// one pass and its runs found in another (F's rows are appended this
    /// way while the other thread makes the next ones; pushing entry by
    /// entry held that thread back from its share of the furnace's 290 M
    /// entries).
    ///
    /// # Panics
    /// Where the columns do not rise (a caller's bug).
    pub fn push_sorted(&mut self, row: &[(u32, f32)]) {
        assert!(
            u32::try_from(row.len()).is_ok(),
            "a row of under 2³² entries"
        );
        self.vals.extend(row.iter().map(|e| e.1));
        let mut prev: Option<u32> = None;
        for (k, &(c, _)) in row.iter().enumerate() {
            if prev.is_none_or(|p| p == u32::MAX || c != p + 1) {
                assert!(prev.is_none_or(|p| c > p), "columns rise within a row");
                self.runs.push(Run {
                    col: c,
                    at: k as u32,
                });
            }
            prev = Some(c);
        }
        self.offsets.push(self.vals.len());
        self.run_offsets.push(self.runs.len());
    }

    /// Checks that the matrix is square: `n` rows, every column below `n`.
    ///
    /// # Panics
    /// Where it is not (a caller's bug).
    pub fn square(self, n: usize) -> Csr {
        assert_eq!(self.nrows(), n, "one row per patch");
        assert!(
            self.rows().all(|r| r
                .segments()
                .last()
                .is_none_or(|(c, v)| c as usize + v.len() <= n)),
            "columns below n"
        );
        self
    }

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
        let mut m = Csr::new();
        for w in offsets.windows(2) {
            let r = w[0]..w[1];
            m.push_row(cols[r.clone()].iter().copied().zip(vals[r].iter().copied()));
        }
        m.square(n)
    }

    /// Rows (= columns).
    pub fn nrows(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Entries held.
    pub fn nnz(&self) -> usize {
        self.vals.len()
    }

    /// Runs of columns held.
    pub fn nruns(&self) -> usize {
        self.runs.len()
    }

    /// Where each row starts in [`Csr::values`], and the end.
    pub fn row_offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// Every entry's value, row after row.
    pub fn values(&self) -> &[f32] {
        &self.vals
    }

    /// Row i.
    #[inline]
    pub fn row(&self, i: usize) -> Row<'_> {
        Row {
            runs: &self.runs[self.run_offsets[i]..self.run_offsets[i + 1]],
            vals: &self.vals[self.offsets[i]..self.offsets[i + 1]],
        }
    }

    /// Every row, in order.
    pub fn rows(&self) -> impl Iterator<Item = Row<'_>> + '_ {
        (0..self.nrows()).map(|i| self.row(i))
    }

    /// The transpose (a counting sort by column: each of its rows keeps
    /// the rising order of the rows it came from). Two passes over the
    /// entries: the first counts each column's entries and runs (an entry
    /// continues its column's run where that column's last entry came from
    /// the row before), the second places them.
    pub fn transpose(&self) -> Csr {
        let n = self.nrows();
        let mut offsets = vec![0usize; n + 1];
        let mut run_offsets = vec![0usize; n + 1];
        let mut last = vec![u32::MAX; n];
        for (i, row) in self.rows().enumerate() {
            for (c, v) in row.segments() {
                for j in c as usize..c as usize + v.len() {
                    offsets[j + 1] += 1;
                    if i == 0 || last[j] != i as u32 - 1 {
                        run_offsets[j + 1] += 1;
                    }
                    last[j] = i as u32;
                }
            }
        }
        for j in 0..n {
            offsets[j + 1] += offsets[j];
            run_offsets[j + 1] += run_offsets[j];
        }
        let mut next = offsets.clone();
        let mut next_run = run_offsets.clone();
        let mut vals = vec![0f32; self.nnz()];
        let mut runs = vec![Run { col: 0, at: 0 }; run_offsets[n]];
        last.fill(u32::MAX);
        for (i, row) in self.rows().enumerate() {
            for (c, v) in row.segments() {
                for (j, &x) in (c as usize..).zip(v) {
                    if i == 0 || last[j] != i as u32 - 1 {
                        runs[next_run[j]] = Run {
                            col: i as u32,
                            at: (next[j] - offsets[j]) as u32,
                        };
                        next_run[j] += 1;
                    }
                    last[j] = i as u32;
                    vals[next[j]] = x;
                    next[j] += 1;
                }
            }
        }
        Csr {
            offsets,
            run_offsets,
            runs,
            vals,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Csr;

    fn entries(m: &Csr, i: usize) -> Vec<(u32, f32)> {
        m.row(i).iter().collect()
    }

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
        assert_eq!(entries(&t, 0), [(1, 3.0)]);
        assert_eq!(entries(&t, 1), [(0, 1.0), (2, 4.0)]);
        assert_eq!(entries(&t, 2), [(0, 2.0), (2, 5.0)]);
        assert_eq!(t.transpose(), m);
    }

    /// Runs split where a column is skipped, and every entry is found by
    /// column and by index.
    #[test]
    fn runs_hold_every_entry() {
        let cols = [0u32, 1, 2, 5, 7, 8, 11];
        let vals: Vec<f32> = (0..cols.len()).map(|k| k as f32 + 0.5).collect();
        let offsets = vec![0; 12].into_iter().chain([7]).collect();
        let m = Csr::from_parts(12, offsets, cols.to_vec(), vals);
        let row = m.row(11);
        assert_eq!(row.runs.len(), 4);
        assert_eq!(m.nruns(), 4);
        assert_eq!(row.iter().map(|e| e.0).collect::<Vec<_>>(), cols);
        for (k, &c) in cols.iter().enumerate() {
            assert_eq!(row.find(c), Some(k));
            assert_eq!(row.col(k), c);
        }
        for j in [3u32, 4, 6, 9, 10] {
            assert_eq!(row.find(j), None);
        }
        assert!(m.row(0).is_empty() && m.row(0).find(0).is_none());
        assert_eq!(m.transpose().transpose(), m);
    }

    #[test]
    fn a_slice_row_is_the_row_pushed_entry_by_entry() {
        let rows: [&[(u32, f32)]; 5] = [
            &[],
            &[(3, 1.0), (4, 2.0), (5, 3.0), (9, 4.0), (11, 5.0), (12, 6.0)],
            &[(0, 0.5)],
            &[(7, 1.5), (u32::MAX - 1, 2.5), (u32::MAX, 3.5)],
            &[(1, 1.0), (3, 1.0), (5, 1.0), (6, 1.0)],
        ];
        let (mut a, mut b) = (Csr::new(), Csr::new());
        for r in rows {
            a.push_row(r.iter().copied());
            b.push_sorted(r);
        }
        assert_eq!(a, b);
        assert_eq!(b.nruns(), 3 + 1 + 2 + 3);
    }

    #[test]
    #[should_panic(expected = "columns rise")]
    fn unsorted_slice_rows_are_refused() {
        Csr::new().push_sorted(&[(2, 1.0), (2, 1.0)]);
    }

    #[test]
    #[should_panic(expected = "columns rise")]
    fn unsorted_rows_are_refused() {
        Csr::from_parts(2, vec![0, 2, 2], vec![1, 0], vec![1.0, 1.0]);
    }

    #[test]
    #[should_panic(expected = "columns below n")]
    fn columns_past_the_square_are_refused() {
        Csr::from_parts(2, vec![0, 2, 2], vec![1, 2], vec![1.0, 1.0]);
    }
}
