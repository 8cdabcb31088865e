//! Light transport: surfaces → [`TexelLight`], one function per
//! [`Method`]. Radiosity ([`super::radiosity`]) is the bake; path tracing
//! ([`crate::trace`], Kajiya 1986) and photon mapping ([`crate::trace::photon`],
//! Jensen 1996) are the references it is checked against, and return the
//! same product.

use super::log::Log;
use super::radiosity;
use super::texel_light::{Rays, TexelLight};
use crate::config::{BakeConfig, Method};
use crate::error::{Error, Result};
use crate::layout::atlas::Atlas;
use crate::light::direct;
use crate::light::lights::{Lights, Mis};
use crate::light::sky::Sky;
use crate::scene::layers::Layers;
use crate::surface::Surfaces;
use crate::trace::{self, Tracer};
use glam::Vec3;

/// Light transport by `config.method`, with its light `layers` apart
/// where there are any (radiosity only; [`super::layered`]).
///
/// # Errors
/// Radiosity's: a direct solve refused or singular.
pub fn run(
    s: &Surfaces,
    atlas: &Atlas,
    config: &BakeConfig,
    (sky, layers): (&Sky, Option<&Layers>),
    log: &mut Log,
    shard: &crate::pipeline::shard::Sharding,
) -> Result<TexelLight> {
    match config.method {
        Method::Radiosity => radiosity::run(s, atlas, config, (sky, layers), log, shard),
        Method::Pathtrace => Ok(pathtrace(s, config, sky, log)),
        Method::Photon => photon(s, config, log),
    }
}

/// The mixed lights' direct light per texel, for a reference method's
/// probes: the bake's direct pass over those lights alone (shadow rays
/// only). Empty where the scene has no mixed light.
fn mixed_direct(s: &Surfaces, config: &BakeConfig) -> Vec<Vec3> {
    let none = vec![false; s.scene.materials.len()];
    let mut lights = Lights::new(s.scene, s.geometry, &none, Vec3::ZERO);
    lights.punctual.retain(|l| l.mode.is_mixed());
    if lights.punctual.is_empty() {
        return Vec::new();
    }
    let mis = Mis {
        light: 1,
        hemisphere: 1,
    };
    direct::texels(
        s,
        &lights,
        0,
        0,
        mis,
        config.supersample,
        config.seed,
        &|_| {},
    )
    .mixed
}

/// The path-traced reference: `path_samples` paths from points spread over
/// each whole texel (every piece, by area).
fn pathtrace(s: &Surfaces, config: &BakeConfig, sky: &Sky, log: &mut Log) -> TexelLight {
    let mut tracer = Tracer::new(s.scene, s.geometry, s.rays, sky.clone());
    tracer.skip_mixed_direct = true;
    let progress = log.progress();
    log.begin("path_trace", s.texels.len() as u64);
    let (values, valid) = trace::reference::reference_texels(
        &tracer,
        s.texels,
        &|t, j, rng| s.sample_texel_area(t, j, rng),
        config.path_samples,
        config.seed,
        &|n| progress.advance(n),
    );
    log.end("path_trace");
    let paths = s.texels.len() as u64 * config.path_samples as u64;
    TexelLight {
        mixed: mixed_direct(s, config),
        ..reference(values, valid, paths)
    }
}

/// Photon mapping with Christensen's precomputed irradiance read by the
/// final gather.
///
/// # Errors
/// Mixed lights without the final gather: the photons' density estimate
/// at a texel cannot tell their direct light from the rest.
fn photon(s: &Surfaces, config: &BakeConfig, log: &mut Log) -> Result<TexelLight> {
    if config.final_gather == 0 && s.scene.lights.iter().any(|l| l.mode.is_mixed()) {
        return Err(Error::Config {
            key: "light_modes".into(),
            message: "method = \"photon\" leaves an indirect or shadowmask light's direct light out only through the final gather (final_gather > 0)".into(),
        });
    }
    let tracer = Tracer::new(s.scene, s.geometry, s.rays, Vec3::from(config.sky));
    let progress = log.progress();
    log.begin("photons", s.texels.len() as u64);
    let (values, valid, rays) =
        crate::trace::photon::bake_texels(s, &tracer, config, &|n| progress.advance(n));
    log.end("photons");
    Ok(TexelLight {
        mixed: mixed_direct(s, config),
        ..reference(values, valid, rays)
    })
}

/// A reference method's product: values and validity, its rays counted as
/// the gather's.
fn reference(values: Vec<Vec3>, valid: Vec<bool>, rays: u64) -> TexelLight {
    TexelLight {
        direct: vec![Vec3::ZERO; values.len()],
        values,
        valid,
        mixed: Vec::new(),
        directional: None,
        ao: None,
        variance: Vec::new(),
        layers: Vec::new(),
        rays: Rays {
            gather: rays,
            ..Rays::default()
        },
        patch_light: None,
    }
}
