//! Light transport: surfaces → [`TexelLight`], one function per
//! [`Method`]. Radiosity ([`super::radiosity`]) is the bake; path tracing
//! ([`crate::trace`], Kajiya 1986) and photon mapping ([`crate::photon`],
//! Jensen 1996) are the references it is checked against, and return the
//! same product.

use super::radiosity::{self, PatchLight};
use super::Log;
use crate::atlas::Atlas;
use crate::config::{BakeConfig, Method};
use crate::direct::Directional;
use crate::error::Result;
use crate::form_factors::raycast::Surfaces;
use crate::trace::{self, Tracer};
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
    /// The directional part b per texel (`--directional sh` with the final
    /// gather): irradiance / π for a normal n is a + n · b.
    pub directional: Option<Vec<Directional>>,
    /// Ambient occlusion per texel (`--ao DISTANCE` with the final gather).
    pub ao: Option<Vec<f32>>,
    /// Rays cast, per purpose.
    pub rays: Rays,
    /// Radiosity's patch-level products (`None` for the references).
    pub patch_light: Option<PatchLight>,
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

/// Light transport by `config.method`.
///
/// # Errors
/// Radiosity's: a direct solve refused or singular.
pub fn run(s: &Surfaces, atlas: &Atlas, config: &BakeConfig, log: &mut Log) -> Result<TexelLight> {
    match config.method {
        Method::Radiosity => radiosity::run(s, atlas, config, log),
        Method::Pathtrace => Ok(pathtrace(s, config, log)),
        Method::Photon => Ok(photon(s, config, log)),
    }
}

/// The path-traced reference: `path_samples` paths from points spread over
/// each whole texel (every piece, by area).
fn pathtrace(s: &Surfaces, config: &BakeConfig, log: &mut Log) -> TexelLight {
    let tracer = Tracer::new(s.scene, s.geometry, s.rays, Vec3::from(config.sky));
    let progress = log.progress();
    log.begin("path_trace", s.texels.len() as u64);
    let (values, valid) = trace::reference_texels(
        &tracer,
        s.texels,
        &|t, j, rng| s.sample_texel_area(t, j, rng),
        config.path_samples,
        config.seed,
        &|n| progress.advance(n),
    );
    log.end("path_trace");
    let paths = s.texels.len() as u64 * config.path_samples as u64;
    reference(values, valid, paths)
}

/// Photon mapping with Christensen's precomputed irradiance read by the
/// final gather.
fn photon(s: &Surfaces, config: &BakeConfig, log: &mut Log) -> TexelLight {
    let tracer = Tracer::new(s.scene, s.geometry, s.rays, Vec3::from(config.sky));
    let progress = log.progress();
    log.begin("photons", s.texels.len() as u64);
    let (values, valid, rays) =
        crate::photon::bake_texels(s, &tracer, config, &|n| progress.advance(n));
    log.end("photons");
    reference(values, valid, rays)
}

/// A reference method's product: values and validity, its rays counted as
/// the gather's.
fn reference(values: Vec<Vec3>, valid: Vec<bool>, rays: u64) -> TexelLight {
    TexelLight {
        direct: vec![Vec3::ZERO; values.len()],
        values,
        valid,
        directional: None,
        ao: None,
        rays: Rays {
            gather: rays,
            ..Rays::default()
        },
        patch_light: None,
    }
}
