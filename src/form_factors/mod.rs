//! Stage 5 — form factors Fᵢⱼ: the fraction of the energy leaving patch i
//! (diffusely) that arrives at patch j (Goral et al. 1984):
//!
//! Fᵢⱼ = 1/Aᵢ ∫_Aᵢ ∫_Aⱼ cos θᵢ cos θⱼ / (π r²) V(x, y) dAⱼ dAᵢ
//!
//! Stored as a sparse CSR matrix (`nalgebra-sparse`); row i sums to the
//! fraction of i's hemisphere covered by other (front-facing) patches, 1 in a
//! closed room. `analytic` holds Howell's closed forms used by the tests.

pub mod analytic;
pub mod hemicube;
pub mod raycast;

use crate::config::{BakeConfig, FormFactorMethod};
use crate::solve::{GatheringRows, ShootingRows};
use nalgebra_sparse::CsrMatrix;
use raycast::Surfaces;
use std::sync::Mutex;

/// Counters of a form-factor computation.
#[derive(Clone, Debug, Default, serde::Serialize)]
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

/// Rows of F computed from the shooter when asked, for progressive
/// refinement: the same rows as the stored matrix would hold (same seeds),
/// turned into shooting coefficients by reciprocity, Sᵢⱼ = Fᵢⱼ Aᵢ / Aⱼ.
pub struct OnDemand<'a> {
    surfaces: &'a Surfaces<'a>,
    method: FormFactorMethod,
    rays_per_patch: u32,
    seed: u64,
    cube: Option<hemicube::Hemicube>,
    stats: Mutex<FormFactorStats>,
}

impl<'a> OnDemand<'a> {
    /// A row source with `config`'s method and settings.
    pub fn new(surfaces: &'a Surfaces<'a>, config: &BakeConfig) -> Self {
        OnDemand {
            surfaces,
            method: config.form_factors,
            rays_per_patch: config.rays_per_patch,
            seed: config.seed,
            cube: (config.form_factors == FormFactorMethod::Hemicube)
                .then(|| hemicube::Hemicube::new(config.hemicube_resolution)),
            stats: Mutex::new(FormFactorStats::default()),
        }
    }

    /// Counters of every row computed so far.
    pub fn stats(&self) -> FormFactorStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }
}

impl OnDemand<'_> {
    /// Row i of F (as the stored matrix would hold it).
    pub fn row(&self, i: usize) -> Vec<(u32, f32)> {
        let (row, st) = match (&self.cube, self.method) {
            (Some(cube), FormFactorMethod::Hemicube) => hemicube::row(self.surfaces, cube, i),
            _ => raycast::row(self.surfaces, i, self.rays_per_patch, self.seed),
        };
        if let Ok(mut s) = self.stats.lock() {
            s.add(&st);
        }
        row
    }
}

impl GatheringRows for OnDemand<'_> {
    fn gathering_row(&self, i: usize) -> Vec<(u32, f32)> {
        self.row(i)
    }
}

impl ShootingRows for OnDemand<'_> {
    fn shooting_row(&self, i: usize) -> (Vec<(u32, f32)>, f32) {
        let row = self.row(i);
        let area = &self.surfaces.patches.area;
        let sum = row.iter().map(|e| e.1).sum();
        let ai = area[i];
        (
            row.into_iter()
                .map(|(j, f)| (j, f * ai / area[j as usize]))
                .collect(),
            sum,
        )
    }
}

/// Columns of a stored F (ΔHⱼ = Fⱼᵢ ΔLᵢ), for progressive refinement on
/// exactly the matrix the other solvers use.
pub struct StoredColumns {
    transposed: CsrMatrix<f32>,
    row_sums: Vec<f32>,
}

impl StoredColumns {
    /// Transposes `f` once.
    pub fn new(f: &FormFactors) -> Self {
        StoredColumns {
            transposed: f.matrix.transpose(),
            row_sums: f.row_sums(),
        }
    }
}

impl ShootingRows for StoredColumns {
    fn shooting_row(&self, i: usize) -> (Vec<(u32, f32)>, f32) {
        let r = self.transposed.row(i);
        (
            r.col_indices()
                .iter()
                .zip(r.values())
                .map(|(&j, &v)| (j as u32, v))
                .collect(),
            self.row_sums[i],
        )
    }
}
