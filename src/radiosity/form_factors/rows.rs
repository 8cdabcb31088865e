//! Rows of F one at a time, for progressive refinement (Cohen et al. 1988),
//! which shoots from one patch at a time and stores no matrix: computed
//! from the shooter on demand ([`OnDemand`], memory O(n)), or the columns
//! of a stored matrix ([`StoredColumns`], for tests on exactly the matrix
//! the other solvers use).

use super::raycast;
use super::{hemicube, FormFactorStats, FormFactors};
use crate::config::{BakeConfig, FormFactorMethod};
use crate::radiosity::solve::{GatheringRows, ShootingRows};
use crate::surface::Surfaces;
use std::sync::Mutex;

/// Rows of F computed from the shooter when asked, for progressive
/// refinement: the same rows as the stored matrix would hold (same seeds),
/// turned into shooting coefficients by reciprocity, Sᵢⱼ = Fᵢⱼ Aᵢ / Aⱼ.
pub struct OnDemand<'a> {
    surfaces: &'a Surfaces<'a>,
    method: FormFactorMethod,
    rays_per_patch: u32,
    seed: u64,
    /// The hemicube's delta form factors and cell map (hemicube rows only).
    hemicubes: Option<hemicube::Setup>,
    stats: Mutex<FormFactorStats>,
    /// Hemicubes rendered on the GPU, a batch of rows per pass; dropped
    /// (and the error kept for the bake's warnings) if it fails.
    gpu: Option<Box<dyn hemicube::RowBatches>>,
    gpu_failed: Mutex<Option<String>>,
}

impl<'a> OnDemand<'a> {
    /// A row source with `config`'s method and settings.
    pub fn new(surfaces: &'a Surfaces<'a>, config: &BakeConfig) -> Self {
        OnDemand {
            surfaces,
            method: config.form_factors,
            rays_per_patch: config.rays_per_patch,
            seed: config.seed,
            hemicubes: (config.form_factors == FormFactorMethod::Hemicube)
                .then(|| hemicube::Setup::new(surfaces, config.hemicube_resolution)),
            stats: Mutex::new(FormFactorStats::default()),
            gpu: None,
            gpu_failed: Mutex::new(None),
        }
    }

    /// Hemicube rows from `gpu` (the method must be the hemicube).
    pub fn with_gpu(mut self, gpu: Box<dyn hemicube::RowBatches>) -> Self {
        self.gpu = Some(gpu);
        self
    }

    /// Why the GPU stopped rendering rows, if it did.
    pub fn gpu_failed(&self) -> Option<String> {
        self.gpu_failed.lock().ok().and_then(|e| e.clone())
    }

    /// Rows of `batch` in one GPU pass where there is a GPU (and it has not
    /// failed), else one per thread on the CPU.
    fn rows(&self, batch: &[usize]) -> Vec<Vec<(u32, f32)>> {
        use rayon::prelude::*;
        let working = self.gpu_failed.lock().is_ok_and(|e| e.is_none());
        if let (Some(gpu), Some(setup), true) = (&self.gpu, &self.hemicubes, working) {
            match gpu.rows(self.surfaces, setup, batch) {
                Ok(rows) => {
                    if let Ok(mut s) = self.stats.lock() {
                        rows.iter().for_each(|r| s.add(&r.1));
                    }
                    return rows.into_iter().map(|r| r.0).collect();
                }
                Err(e) => {
                    if let Ok(mut f) = self.gpu_failed.lock() {
                        *f = Some(format!("{e:#}"));
                    }
                }
            }
        }
        batch.par_iter().map(|&i| self.row(i)).collect()
    }

    /// Rows of F for `batch` ([`OnDemand::rows`]), each with Σⱼ Fᵢⱼ.
    fn summed_rows(&self, batch: &[usize]) -> crate::radiosity::solve::SummedRows {
        self.rows(batch).into_iter().map(summed).collect()
    }

    /// Sᵢⱼ = Fᵢⱼ Aᵢ / Aⱼ from row i of F and its sum, which is kept.
    fn shooting(&self, i: usize, (row, sum): (Vec<(u32, f32)>, f32)) -> (Vec<(u32, f32)>, f32) {
        let area = &self.surfaces.patches.area;
        let s = row.into_iter();
        let s = s.map(|(j, f)| {
            (
                j,
                crate::radiosity::solve::reciprocal(f, i, j as usize, area),
            )
        });
        (s.collect(), sum)
    }

    /// Counters of every row computed so far.
    pub fn stats(&self) -> FormFactorStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }
}

impl OnDemand<'_> {
    /// Row i of F (as the stored matrix would hold it).
    pub fn row(&self, i: usize) -> Vec<(u32, f32)> {
        let (row, st) = self.counted(i);
        if let Ok(mut s) = self.stats.lock() {
            s.add(&st);
        }
        row
    }

    /// Row i of F on the CPU by the configured method, with its counters
    /// (not added to [`OnDemand::stats`]).
    pub fn counted(&self, i: usize) -> (Vec<(u32, f32)>, FormFactorStats) {
        match (&self.hemicubes, self.method) {
            (Some(setup), FormFactorMethod::Hemicube) => hemicube::row(self.surfaces, setup, i),
            _ => raycast::row(self.surfaces, i, self.rays_per_patch, self.seed),
        }
    }
}

impl GatheringRows for OnDemand<'_> {
    fn gathering_row(&self, i: usize) -> Vec<(u32, f32)> {
        self.row(i)
    }
    fn gathering_rows(&self, batch: &[usize]) -> Vec<Vec<(u32, f32)>> {
        self.rows(batch)
    }
}

impl ShootingRows for OnDemand<'_> {
    fn shooting_row(&self, i: usize) -> (Vec<(u32, f32)>, f32) {
        self.shooting(i, summed(self.row(i)))
    }
    fn shooting_rows(&self, batch: &[usize]) -> Vec<(Vec<(u32, f32)>, f32)> {
        let rows = self.summed_rows(batch);
        batch
            .iter()
            .zip(rows)
            .map(|(&i, r)| self.shooting(i, r))
            .collect()
    }
    fn reciprocal_rows(&self, batch: &[usize]) -> Option<crate::radiosity::solve::SummedRows> {
        Some(self.summed_rows(batch))
    }
}

/// A row with the sum of its values.
fn summed(row: Vec<(u32, f32)>) -> (Vec<(u32, f32)>, f32) {
    let sum = row.iter().map(|e| e.1).sum();
    (row, sum)
}

/// Columns of a stored F (ΔHⱼ = Fⱼᵢ ΔLᵢ), for progressive refinement on
/// exactly the matrix the other solvers use.
pub struct StoredColumns {
    transposed: super::Csr,
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
        (self.transposed.row(i).iter().collect(), self.row_sums[i])
    }
}
