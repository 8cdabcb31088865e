//! Light layers in the radiosity bake ([`crate::scene::layers`]): each
//! layer's light, computed within the whole bake so that the layers sum
//! to it and any weighted sum of them is the bake at those weights.
//!
//! Light transport is linear in the emitters, so a layer is the whole bake
//! with every other layer's emitters scaled to 0 ([`Mask`]) — provided
//! every decision that depends on light is taken once, from the whole:
//!
//! - the lights are sampled as in the whole bake (a [`Mask`] scales what a
//!   light brings, not how it is sampled), with the same random streams, so
//!   every layer's direct light has the whole bake's sample points and rays
//!   (its share routed from the whole's pass);
//! - the solve runs the whole solve's iteration count (Jacobi and
//!   Gauss–Seidel are linear for a fixed count);
//! - where the whole first pass is clamped at 0, every layer's is 0
//!   ([`lightmap::first_pass_layer`]);
//! - each texel's gather reads the hits of the rays the whole bake's
//!   adaptive gather read, in the same pass
//!   ([`crate::radiosity::gather::gather_layers`]), and the denoiser's and the seams'
//!   weights are the whole bake's ([`crate::radiosity::denoise::atrous_layers`],
//!   [`crate::maps::seams::stitch_layers`]).
//!
//! The form factors, the burial, the validity, the direct light's rays
//! (each layer's direct light is routed from the whole's pass,
//! [`first_pass::direct_light_layers`]) and the gather's rays are the
//! whole bake's; a layer casts only its near-field shadow rays.

use super::log::Log;
use super::first_pass::{self, DirectLight};
use super::texel_light::{LayerTexels, PatchLight};
use crate::config::BakeConfig;
use crate::error::{Error, Result};
use crate::light::lights::Mask;
use crate::maps::lightmap;
use crate::pipeline::shard::Sharding;
use crate::radiosity::solve::System;
use crate::scene::layers::Layers;
use crate::surface::Surfaces;
use glam::Vec3;

/// Settings and scene checked for a layered bake: radiosity over a stored
/// matrix, in one job. `live`: the layers come from live lights
/// ([`super::live`]), and the messages say so.
///
/// # Errors
/// [`Error::Config`] naming the setting that layers do not support yet.
pub fn check(config: &BakeConfig, shard: &Sharding, live: bool) -> Result<()> {
    let (what, instead) = if live {
        ("live lights", "or bake the light in mode `indirect`")
    } else {
        ("light layers", "or set layers = \"off\"")
    };
    let refuse = |key: &str, message: &str| {
        Err(Error::Config {
            key: key.into(),
            message: format!("{what} {message} ({instead})"),
        })
    };
    if config.method != crate::config::Method::Radiosity {
        return refuse("method", "are baked by the radiosity method");
    }
    if config.solver == crate::config::Solver::Progressive {
        return refuse(
            "solver",
            "need a stored form-factor matrix: use jacobi, gauss-seidel or direct",
        );
    }
    if config.gather_nee {
        return refuse("gather_nee", "are not baked with gather_nee yet");
    }
    if !shard.is_whole() {
        return refuse("layers", "are not baked in shards yet");
    }
    Ok(())
}

/// A layer's patch indirect light over its direct light `direct` (from
/// the whole bake's pass, [`first_pass::direct_light_layers`]): the whole
/// solve, as many iterations.
fn indirect(
    s: &Surfaces,
    config: &BakeConfig,
    direct: &DirectLight,
    patch_light: &PatchLight,
) -> Result<Vec<Vec3>> {
    let mask = direct.lights.mask.clone().unwrap_or_default();
    let Some(ff) = &patch_light.form_factors else {
        return Err(Error::Config {
            key: "solver".into(),
            message: "light layers need a stored form-factor matrix".into(),
        });
    };
    // E′ as in the whole solve, the layer's share of it.
    let emission: Vec<Vec3> = (0..s.patches.len())
        .map(|i| {
            let t = s.patches.texels_of(i)[0] as usize;
            let m = s.geometry.material[s.texels.triangle[t] as usize] as usize;
            if direct.sampled[m] {
                Vec3::ZERO
            } else {
                s.patches.emission[i] * mask.material[m]
            }
        })
        .collect();
    let system = System {
        emission: &emission,
        albedo: &s.patches.albedo,
        direct: &direct.patch,
        area: &s.patches.area,
    };
    let fixed = BakeConfig {
        tolerance: 0.0,
        max_iterations: patch_light.solution.iterations,
        ..config.clone()
    };
    let solution = first_pass::solve_matrix(&ff.matrix, &system, &fixed, &|_| {})?;
    Ok((solution.irradiance.iter().zip(&direct.patch))
        .map(|(h, d)| *h - *d)
        .collect())
}

/// The whole bake's first pass before its clamp ([`lightmap::interpolate_unclamped`]).
fn whole_unclamped(s: &Surfaces, patch_light: &PatchLight) -> Vec<Vec3> {
    let indirect: Vec<Vec3> = (patch_light.solution.irradiance.iter())
        .zip(&patch_light.direct)
        .map(|(h, d)| *h - *d)
        .collect();
    lightmap::interpolate_unclamped(s.texels, s.patches, &indirect)
}

/// Without a final gather: each layer's first pass (its baked direct light
/// and its interpolated patch light).
///
/// # Errors
/// As [`check`]'s.
pub(super) fn first_passes(
    s: &Surfaces,
    config: &BakeConfig,
    (layers, directs): (&Layers, Vec<DirectLight>),
    patch_light: &PatchLight,
    log: &mut Log,
) -> Result<Vec<LayerTexels>> {
    log.begin("layers", layers.len() as u64);
    let whole = whole_unclamped(s, patch_light);
    let mut out = Vec::with_capacity(layers.len());
    for direct in directs {
        let indirect = indirect(s, config, &direct, patch_light)?;
        let baked = direct.parts.baked();
        out.push(LayerTexels {
            values: lightmap::first_pass_layer(s.texels, s.patches, &baked, &indirect, &whole),
            mixed: direct.mixed(),
        });
        log.progress().advance(1);
    }
    log.end("layers");
    Ok(out)
}

/// A light layer's inputs to the final gather: its direct light, its
/// first pass (filled as the whole's) and its share of the lights.
pub(super) struct LayerInput {
    pub(super) direct: DirectLight,
    pub(super) first: Vec<Vec3>,
    pub(super) mask: Mask,
}

/// Each layer's direct light and first pass, over the whole bake's patch
/// solution and pre-gather validity `pre`; their gathers then read the
/// whole gather's hits ([`crate::radiosity::gather::gather_layers`]).
///
/// # Errors
/// As [`check`]'s.
pub(super) fn inputs(
    s: &Surfaces,
    config: &BakeConfig,
    (layers, directs): (&Layers, Vec<DirectLight>),
    patch_light: &PatchLight,
    pre: &[bool],
    log: &mut Log,
) -> Result<Vec<LayerInput>> {
    log.begin("layers", layers.len() as u64);
    let unclamped = whole_unclamped(s, patch_light);
    let mut out = Vec::with_capacity(layers.len());
    for direct in directs {
        let indirect = indirect(s, config, &direct, patch_light)?;
        let mask = direct.lights.mask.clone().unwrap_or_default();
        let mut first =
            lightmap::first_pass_layer(s.texels, s.patches, &direct.texel, &indirect, &unclamped);
        lightmap::fill_invalid(s.texels, &mut first, pre, lightmap::fill_rings(config.patch_texels));
        out.push(LayerInput { direct, first, mask });
        log.progress().advance(1);
    }
    log.end("layers");
    Ok(out)
}
