//! Solving the radiosity equation. With every surface Lambertian,
//! we solve for outgoing radiance Lᵢ (= Bᵢ/π) rather than radiosity:
//!
//! Lᵢ = Eᵢ + ρᵢ Hᵢ,   Hᵢ = Σⱼ Fᵢⱼ Lⱼ + Dᵢ
//!
//! per RGB channel, where Hᵢ is the incident irradiance / π — exactly what a
//! lightmap texel stores — and Dᵢ the direct irradiance / π from punctual
//! lights and sky (zero when there are none).

pub mod dense;
pub mod gauss_seidel;
pub mod jacobi;
pub mod progressive;

use glam::Vec3;

/// The system's data per patch: L = E + ρ H, H = D + F L.
#[derive(Clone, Copy, Debug)]
pub struct System<'a> {
    /// Emitted radiance E entering the solve.
    pub emission: &'a [Vec3],
    /// Albedo ρ.
    pub albedo: &'a [Vec3],
    /// Direct light D (irradiance / π).
    pub direct: &'a [Vec3],
    /// Patch areas (progressive refinement's reciprocity and power).
    pub area: &'a [f32],
}

impl System<'_> {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.emission.len()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.emission.is_empty()
    }

    /// L⁽⁰⁾ = E + ρ D: emission and the first bounce of direct light.
    pub fn initial_radiance(&self) -> Vec<Vec3> {
        (0..self.len())
            .map(|i| self.emission[i] + self.albedo[i] * self.direct[i])
            .collect()
    }
}

/// Shooting coefficients for progressive refinement: `row(i)` lists
/// (j, Sᵢⱼ) with ΔHⱼ = Sᵢⱼ ΔLᵢ, i.e. column i of F (Sᵢⱼ = Fⱼᵢ), or by
/// reciprocity Fᵢⱼ Aᵢ / Aⱼ when F is computed from the shooter on demand.
pub trait ShootingRows: Sync {
    /// Coefficients of shooter `i`, and Σⱼ Fᵢⱼ (the fraction of i's light that lands).
    fn shooting_row(&self, i: usize) -> (Vec<(u32, f32)>, f32);
    /// Several shooters' rows, in their order: one row per thread, unless
    /// the source does better (a GPU pass of hemicubes).
    fn shooting_rows(&self, batch: &[usize]) -> Vec<(Vec<(u32, f32)>, f32)> {
        use rayon::prelude::*;
        batch.par_iter().map(|&i| self.shooting_row(i)).collect()
    }
    /// Where the source's shooting rows are the patches' own rows scaled
    /// by reciprocity (Sᵢⱼ = Fᵢⱼ Aᵢ / Aⱼ): those rows Fᵢ· and their sums, in
    /// the batch's order, so that a solve may hold the exact rows, scale
    /// them as it shoots and gather from them afterwards
    /// ([`progressive::gather_sweeps`]). None (the default) where they are
    /// not (a stored F's columns).
    fn reciprocal_rows(&self, _batch: &[usize]) -> Option<SummedRows> {
        None
    }
}

/// Rows of coefficients with their sums: (row, Σ of its values).
pub type SummedRows = Vec<(Vec<(u32, f32)>, f32)>;

/// Shooting coefficient Sᵢⱼ = Fᵢⱼ Aᵢ / Aⱼ from form factor `f` = Fᵢⱼ by
/// reciprocity (Aᵢ Fᵢⱼ = Aⱼ Fⱼᵢ): one expression wherever a shooting row
/// is made from a gathering row, so that rows held and rows made afresh
/// shoot the same bits.
#[inline]
pub fn reciprocal(f: f32, i: usize, j: usize, area: &[f32]) -> f32 {
    f * area[i] / area[j]
}

/// Rows of F for gathering: `gathering_row(i)` lists (j, Fᵢⱼ), the row
/// itself (progressive refinement's closing sweeps,
/// [`progressive::gather_sweeps`]).
pub trait GatheringRows: Sync {
    /// Row i of F.
    fn gathering_row(&self, i: usize) -> Vec<(u32, f32)>;
    /// Several rows, in their order (as [`ShootingRows::shooting_rows`]).
    fn gathering_rows(&self, batch: &[usize]) -> Vec<Vec<(u32, f32)>> {
        use rayon::prelude::*;
        batch.par_iter().map(|&i| self.gathering_row(i)).collect()
    }
}

/// The solved radiosity system.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Solution {
    /// Outgoing radiance Lᵢ per patch (W·sr⁻¹·m⁻²).
    pub radiance: Vec<Vec3>,
    /// Incident irradiance / π, Hᵢ, per patch: the lightmap value.
    pub irradiance: Vec<Vec3>,
    /// Iterations run.
    pub iterations: u32,
    /// Relative change of L in the last iteration (Σ|ΔL| / Σ|L|); for
    /// progressive refinement, the unshot fraction of the power.
    pub residual: f32,
    /// Progressive refinement: shots fired.
    pub shots: u64,
}
