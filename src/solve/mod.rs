//! Stage 6 — solving the radiosity equation. With every surface Lambertian,
//! we solve for outgoing radiance Lᵢ (= Bᵢ/π) rather than radiosity:
//!
//! Lᵢ = Eᵢ + ρᵢ Hᵢ,   Hᵢ = Σⱼ Fᵢⱼ Lⱼ + Dᵢ
//!
//! per RGB channel, where Hᵢ is the incident irradiance / π — exactly what a
//! lightmap texel stores — and Dᵢ the direct irradiance / π from punctual
//! lights and sky (zero when there are none).

pub mod jacobi;

use glam::Vec3;

/// The solved radiosity system.
#[derive(Clone, Debug, Default)]
pub struct Solution {
    /// Outgoing radiance Lᵢ per patch (W·sr⁻¹·m⁻²).
    pub radiance: Vec<Vec3>,
    /// Incident irradiance / π, Hᵢ, per patch: the lightmap value.
    pub irradiance: Vec<Vec3>,
    /// Iterations run.
    pub iterations: u32,
    /// Relative change of L in the last iteration (Σ|ΔL| / Σ|L|).
    pub residual: f32,
}
