//! The radiosity bake's first pass, shared by the whole bake
//! ([`super::radiosity`]) and its light layers ([`super::layered`]):
//! direct light per texel and per patch ([`direct_light`]), and the patch
//! system solved over a stored form-factor matrix ([`solve_matrix`]).

use crate::config::{BakeConfig, Solver};
use crate::error::{Error, Result};
use crate::light::direct;
use crate::light::lights::{self, Lights, Mask, Mis};
use crate::pipeline::shard::Sharding;
use crate::radiosity::solve::{self, System};
use crate::surface::Surfaces;
use glam::Vec3;

/// The direct-light stage's product.
pub struct DirectLight {
    /// Per material: emission sampled as direct light (else it enters the solve).
    pub sampled: Vec<bool>,
    pub lights: Lights,
    pub mis: Mis,
    /// The final gather's rays are the hemisphere samples of the lightmap's
    /// direct light (the direct pass then casts a quarter as many).
    pub gathering: bool,
    /// The pass's two parts.
    pub parts: direct::Direct,
    /// Per texel, `parts.total()`.
    pub texel: Vec<Vec3>,
    /// Per patch (moved into [`PatchLight`] by the solve).
    pub patch: Vec<Vec3>,
}

impl DirectLight {
    /// The mixed lights' direct light per texel; empty where the scene has
    /// no mixed light.
    pub fn mixed(&self) -> Vec<Vec3> {
        if self.lights.punctual.iter().any(|l| l.mode.is_mixed()) {
            self.parts.mixed.clone()
        } else {
            Vec::new()
        }
    }
}

/// Direct light per texel and per patch. With the final gather on (and
/// casting at least as many rays as the direct light's samples, as every
/// preset does), its rays estimate the hemisphere part of the direct light
/// (sky, emitters by MIS) for the lightmap, so this pass casts only a
/// quarter as many hemisphere rays, for the first pass H₁ that the solve
/// and the gather's hits read (Sponza: 30 % fewer rays).
pub fn direct_light(
    s: &Surfaces,
    config: &BakeConfig,
    sky: &crate::light::sky::Sky,
    advance: &(dyn Fn(u64) + Sync),
    shard: &Sharding,
) -> Result<DirectLight> {
    Ok(direct_light_layers(s, config, sky, &[], advance, shard)?.0)
}

/// [`direct_light`], and in the same pass (same rays, same draws) each
/// light layer's share of it, one per mask of `layers` (each what a pass
/// over the layer's masked lights gives; see
/// [`direct::direct_routed`]). With layers the pass is not sharded (a
/// layered bake is one job).
pub fn direct_light_layers(
    s: &Surfaces,
    config: &BakeConfig,
    sky: &crate::light::sky::Sky,
    layers: &[Mask],
    advance: &(dyn Fn(u64) + Sync),
    shard: &Sharding,
) -> Result<(DirectLight, Vec<DirectLight>)> {
    let sampled = lights::sampled_materials(s.scene, s.geometry, config.emitters);
    let mut lights = Lights::new(s.scene, s.geometry, &sampled, sky.clone());
    lights.sky_samples = config.sky_samples;
    let gathering = config.final_gather > 0 && config.final_gather >= config.direct_samples;
    let mis = Mis {
        light: config.direct_samples,
        hemisphere: if gathering {
            config.final_gather
        } else {
            config.direct_samples
        },
    };
    let hemisphere = if gathering {
        (config.direct_samples / 4).max(4)
    } else {
        config.direct_samples
    };
    let settings = direct::TexelSettings {
        samples: config.direct_samples,
        hemisphere,
        mis,
        supersample: config.supersample,
        seed: config.seed,
    };
    let n = s.texels.len();
    // Slices of equal cost (in a sharded bake): a texel enclosed in a
    // solid casts nothing.
    let cost = || -> Vec<f64> {
        (0..n)
            .map(|t| if s.burial.enclosed(t) { 0.01 } else { 1.0 })
            .collect()
    };
    let layer_lights: Vec<Lights> = layers.iter().map(|m| lights.masked(m.clone())).collect();
    let (texels, layer_texels) = if layers.is_empty() {
        let texels = shard.items(
            "direct",
            n,
            |count| crate::pipeline::shard::balanced(&cost(), count),
            |range| direct::texel_range(s, &lights, &settings, range, advance),
        )?;
        (texels, Vec::new())
    } else {
        direct::texel_range_layers(s, &lights, &layer_lights, &settings, advance)
    };
    let build = |texels: Vec<direct::TexelDirect>, lights: Lights| {
        let parts = direct::assemble(texels);
        let texel = parts.total();
        let patch = (0..s.patches.len())
            .map(|i| {
                let sum: Vec3 = s
                    .patches
                    .texels_of(i)
                    .iter()
                    .map(|&t| texel[t as usize] * s.texels.area[t as usize])
                    .sum();
                sum / s.patches.area[i]
            })
            .collect();
        DirectLight {
            sampled: sampled.clone(),
            lights,
            mis,
            gathering,
            parts,
            texel,
            patch,
        }
    };
    let layer_directs = (layer_texels.into_iter().zip(layer_lights))
        .map(|(t, l)| build(t, l))
        .collect();
    Ok((build(texels, lights), layer_directs))
}

/// The system solved over the stored matrix `f` by `config.solver`.
///
/// # Errors
/// The direct solver's matrix is singular.
pub fn solve_matrix(
    f: &crate::radiosity::form_factors::Csr,
    system: &System,
    config: &BakeConfig,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<solve::Solution> {
    let (tolerance, iterations) = (config.tolerance, config.max_iterations);
    Ok(match config.solver {
        Solver::GaussSeidel => solve::gauss_seidel::solve(f, system, tolerance, iterations, advance),
        Solver::Direct => solve::dense::solve(f, system).ok_or_else(|| {
            Error::Limit("the radiosity matrix is singular (an albedo of 1 in a closed scene?)".into())
        })?,
        _ => solve::jacobi::solve(f, system, tolerance, iterations, advance),
    })
}

