//! The product of light transport, the same for every method:
//! [`TexelLight`] (the light per texel, its validity, the rays cast), with
//! radiosity's patch-level solution ([`PatchLight`]) where radiosity ran.

use crate::light::lights::Directional;
use crate::radiosity::form_factors::{FormFactorStats, FormFactors};
use crate::radiosity::solve::Solution;
use glam::Vec3;

/// The light per texel, as every method of light transport returns it.
#[derive(Clone, Debug, Default)]
pub struct TexelLight {
    /// Incident irradiance / π per texel (linear RGB), as it arrived: the
    /// invalid texels' values are not yet filled.
    pub values: Vec<Vec3>,
    /// Validity per texel (false: inside or under geometry; the lightmap
    /// stage fills it from its neighbours).
    pub valid: Vec<bool>,
    /// The direct part of `values` per texel (zero for the references).
    pub direct: Vec<Vec3>,
    /// The mixed lights' direct light per texel (irradiance / π; empty
    /// where the scene has none): not in `values` (the engine draws it),
    /// but on the surfaces all the same, so the probes' rays add it where
    /// they land.
    pub mixed: Vec<Vec3>,
    /// The directional part b per texel (`--directional sh` with the final
    /// gather): irradiance / π for a normal n is a + n · b.
    pub directional: Option<Vec<Directional>>,
    /// Ambient occlusion per texel (`--ao DISTANCE` with the final gather).
    pub ao: Option<Vec<f32>>,
    /// The final gather's estimate of each texel's variance (luminance,
    /// of the texel's mean before denoising; [`crate::radiosity::gather::Gathered`]);
    /// empty without a final gather. Σ a² var / (Σ a)² over an instance's
    /// texels is the variance of its mean, which the denoiser does not
    /// change (it conserves each chart's power).
    pub variance: Vec<f32>,
    /// Per light layer ([`crate::scene::layers`]; empty without layers),
    /// its share of `values` and `mixed`: the same rays, validity and
    /// filter weights, so the layers sum to the whole.
    pub layers: Vec<LayerTexels>,
    /// Rays cast, per purpose.
    pub rays: Rays,
    /// Radiosity's patch-level products (`None` for the references).
    pub patch_light: Option<PatchLight>,
}

/// One light layer's share of a [`TexelLight`].
#[derive(Clone, Debug, Default)]
pub struct LayerTexels {
    /// Its share of [`TexelLight::values`].
    pub values: Vec<Vec3>,
    /// Its share of [`TexelLight::mixed`] (empty where the scene has no
    /// mixed light).
    pub mixed: Vec<Vec3>,
}

/// Rays cast by light transport, per purpose.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rays {
    /// Form factors.
    pub form_factors: u64,
    /// Direct light (shadow and hemisphere rays).
    pub direct: u64,
    /// The validity estimate before the final gather.
    pub validity: u64,
    /// The final gather (the references: paths traced, or photons emitted
    /// plus gather rays).
    pub gather: u64,
}

impl Rays {
    /// Every ray.
    pub fn total(&self) -> u64 {
        self.form_factors + self.direct + self.validity + self.gather
    }
}

/// Radiosity's patch-level products.
#[derive(Clone, Debug, Default)]
pub struct PatchLight {
    /// Form factors (`None` for progressive refinement, which stores none).
    pub form_factors: Option<FormFactors>,
    /// Form-factor counters.
    pub stats: FormFactorStats,
    /// Σⱼ Fᵢⱼ per patch.
    pub row_sums: Vec<f32>,
    /// Direct light per patch (area-weighted mean of its texels').
    pub direct: Vec<Vec3>,
    /// The solution (H per patch includes the direct light).
    pub solution: Solution,
}
