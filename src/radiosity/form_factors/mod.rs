//! Form factors Fᵢⱼ: the fraction of the energy leaving patch i
//! (diffusely) that arrives at patch j (Goral et al. 1984):
//!
//! Fᵢⱼ = 1/Aᵢ ∫_Aᵢ ∫_Aⱼ cos θᵢ cos θⱼ / (π r²) V(x, y) dAⱼ dAᵢ
//!
//! Stored as a sparse CSR matrix ([`Csr`], columns in runs); row i sums to the
//! fraction of i's hemisphere covered by other (front-facing) patches, 1 in a
//! closed room. [`raycast`] and [`hemicube`] compute rows, [`rows`] serves
//! them one at a time to progressive refinement; `analytic` holds Howell's
//! closed forms used by the tests.

pub mod analytic;
mod csr;
#[cfg(feature = "gpu")]
pub mod gpu_hemicube;
pub mod hemicube;
pub mod raycast;
pub mod rows;

pub use csr::{Csr, Row, Run};

/// Counters of a form-factor computation.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FormFactorStats {
    /// Rays cast.
    pub rays: u64,
    /// Rays that left the scene.
    pub escaped: u64,
    /// Rays that hit the back of a one-sided surface (energy into a wall).
    pub back_faces: u64,
    /// Rays that hit a surface with no lightmap texel there.
    pub unmapped: u64,
}

/// The form-factor matrix F (rows: shooting patch i, columns: receiving patch j).
#[derive(Clone, Debug)]
pub struct FormFactors {
    /// F in CSR form, f32 values.
    pub matrix: Csr,
    /// Counters.
    pub stats: FormFactorStats,
}

impl FormFactors {
    /// Builds F from sorted per-row `(column, value)` lists.
    pub fn from_rows(n: usize, rows: Vec<Vec<(u32, f32)>>, stats: FormFactorStats) -> FormFactors {
        let mut b = CsrBuilder::new(n);
        b.stats = stats;
        b.extend(rows.into_iter().map(|r| (r, FormFactorStats::default())));
        b.finish()
    }

    /// Builds F from `row(i)` for every patch, in parallel (rows are
    /// independent and collected in order, so the result does not depend on
    /// the thread count); `advance` is called once per row. The rows are
    /// made [`ROW_CHUNK`] at a time and moved into the matrix, so they are
    /// never all held beside it: the furnace's nearly dense F (290 M
    /// entries) peaked at 4.7–5.7 GB with every row held beside the matrix
    /// (rows 2.3 GB, CSR 3.5 GB), 3.7 GB then, 2.6 GB with 32-bit columns.
    /// A chunk is moved in while the next is made, so the copy (and the
    /// kernel's zeroing of the matrix's new pages) no longer leaves the
    /// other threads idle: the furnace's form factors 10.1–10.9 → 9.0–9.4 s
    /// on 2 threads.
    pub fn from_row_fn(
        n: usize,
        row: impl Fn(usize) -> (Vec<(u32, f32)>, FormFactorStats) + Sync,
        advance: &(dyn Fn(u64) + Sync),
    ) -> FormFactors {
        use rayon::prelude::*;
        type Part = Vec<(Vec<(u32, f32)>, FormFactorStats)>;
        let make = |lo: usize| -> Part {
            (lo..(lo + ROW_CHUNK).min(n))
                .into_par_iter()
                .map(|i| {
                    let r = row(i);
                    advance(1);
                    r
                })
                .collect()
        };
        let mut b = CsrBuilder::new(n);
        let mut made: Part = Vec::new();
        for lo in (0..n).step_by(ROW_CHUNK) {
            let ready = std::mem::take(&mut made);
            made = rayon::join(|| b.extend(ready), || make(lo)).1;
        }
        b.extend(made);
        b.finish()
    }

    /// Builds F from every patch's row and counters, in patch order.
    pub fn from_results(
        n: usize,
        results: impl IntoIterator<Item = (Vec<(u32, f32)>, FormFactorStats)>,
    ) -> FormFactors {
        let mut b = CsrBuilder::new(n);
        b.extend(results);
        b.finish()
    }

    /// Σⱼ Fᵢⱼ for every row.
    pub fn row_sums(&self) -> Vec<f32> {
        self.matrix.rows().map(|r| r.vals.iter().sum()).collect()
    }

    /// Non-zeros of F.
    pub fn nnz(&self) -> usize {
        self.matrix.nnz()
    }
}

/// Rows made at a time by [`FormFactors::from_row_fn`]: two chunks are
/// held at once (4,096 held 200 MB more of the furnace's rows, for the
/// same time).
const ROW_CHUNK: usize = 2048;

/// F, filled row by row in patch order.
struct CsrBuilder {
    n: usize,
    matrix: Csr,
    stats: FormFactorStats,
}

impl CsrBuilder {
    fn new(n: usize) -> CsrBuilder {
        CsrBuilder {
            n,
            matrix: Csr::new(),
            stats: FormFactorStats::default(),
        }
    }

    /// Appends the next rows (each sorted by column) and adds their counters.
    fn extend(&mut self, rows: impl IntoIterator<Item = (Vec<(u32, f32)>, FormFactorStats)>) {
        for (row, st) in rows {
            self.stats.add(&st);
            self.matrix.push_sorted(&row);
        }
    }

    fn finish(self) -> FormFactors {
        FormFactors {
            matrix: self.matrix.square(self.n),
            stats: self.stats,
        }
    }
}

impl FormFactorStats {
    /// Adds `o`'s counts.
    pub fn add(&mut self, o: &FormFactorStats) {
        self.rays += o.rays;
        self.escaped += o.escaped;
        self.back_faces += o.back_faces;
        self.unmapped += o.unmapped;
    }
}
