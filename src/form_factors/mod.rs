//! Stage 5 — form factors Fᵢⱼ: the fraction of the energy leaving patch i
//! (diffusely) that arrives at patch j (Goral et al. 1984):
//!
//! Fᵢⱼ = 1/Aᵢ ∫_Aᵢ ∫_Aⱼ cos θᵢ cos θⱼ / (π r²) V(x, y) dAⱼ dAᵢ
//!
//! Stored as a sparse CSR matrix (`nalgebra-sparse`); row i sums to the
//! fraction of i's hemisphere covered by other (front-facing) patches, 1 in a
//! closed room. [`raycast`] and [`hemicube`] compute rows, [`rows`] serves
//! them one at a time to progressive refinement; `analytic` holds Howell's
//! closed forms used by the tests.

pub mod analytic;
#[cfg(feature = "gpu")]
pub mod gpu_hemicube;
pub mod hemicube;
pub mod raycast;
pub mod rows;

use nalgebra_sparse::CsrMatrix;

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
    pub matrix: CsrMatrix<f32>,
    /// Counters.
    pub stats: FormFactorStats,
}

impl FormFactors {
    /// Builds F from sorted per-row `(column, value)` lists.
    pub fn from_rows(n: usize, rows: Vec<Vec<(u32, f32)>>, stats: FormFactorStats) -> FormFactors {
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0usize);
        let nnz: usize = rows.iter().map(Vec::len).sum();
        let mut cols = Vec::with_capacity(nnz);
        let mut vals = Vec::with_capacity(nnz);
        for row in rows {
            for (j, f) in row {
                cols.push(j as usize);
                vals.push(f);
            }
            offsets.push(cols.len());
        }
        let matrix = CsrMatrix::try_from_csr_data(n, n, offsets, cols, vals)
            .expect("rows are built sorted and in range");
        FormFactors { matrix, stats }
    }

    /// Builds F from `row(i)` for every patch, in parallel (rows are
    /// independent and collected in order, so the result does not depend on
    /// the thread count); `advance` is called once per row.
    pub fn from_row_fn(
        n: usize,
        row: impl Fn(usize) -> (Vec<(u32, f32)>, FormFactorStats) + Sync,
        advance: &(dyn Fn(u64) + Sync),
    ) -> FormFactors {
        use rayon::prelude::*;
        let results: Vec<(Vec<(u32, f32)>, FormFactorStats)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let r = row(i);
                advance(1);
                r
            })
            .collect();
        FormFactors::from_results(n, results)
    }

    /// Builds F from every patch's row and counters, in patch order.
    pub fn from_results(
        n: usize,
        results: impl IntoIterator<Item = (Vec<(u32, f32)>, FormFactorStats)>,
    ) -> FormFactors {
        let mut stats = FormFactorStats::default();
        let mut rows = Vec::with_capacity(n);
        for (r, st) in results {
            stats.add(&st);
            rows.push(r);
        }
        FormFactors::from_rows(n, rows, stats)
    }

    /// Σⱼ Fᵢⱼ for every row.
    pub fn row_sums(&self) -> Vec<f32> {
        self.matrix
            .row_iter()
            .map(|r| r.values().iter().sum())
            .collect()
    }

    /// Non-zeros of F.
    pub fn nnz(&self) -> usize {
        self.matrix.nnz()
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
