//! Light transport by radiosity (Goral et al. 1984) with a final gather,
//! one function per sub-stage:
//!
//! ```text
//! form factors ─► direct light D ─► solve L = E′ + ρ (D + F L) ─► first pass H₁ ─► validity ─► final gather (+ denoise)
//! form_factors    direct              solve                        lightmap           gather       gather, denoise
//! ```
//!
//! Progressive refinement (Cohen et al. 1988) stores no matrix: its rows
//! come on demand ([`OnDemand`]) and its solution is completed by
//! gathering sweeps ([`progressive::gather_sweeps`]).

use super::first_pass::{direct_light_layers, solve_matrix, DirectLight};
use super::log::Log;
use super::snapshot::Snapshots;
use super::texel_light::{LayerTexels, PatchLight, Rays, TexelLight};
use crate::config::{self, BakeConfig, FormFactorMethod, Solver};
use crate::error::{Error, Result};
use crate::layout::atlas::Atlas;
use crate::light::lights::{Directional, Mask};
use crate::scene::layers::Layers;
use crate::maps::lightmap;
use crate::pipeline::shard::Sharding;
use crate::radiosity::denoise;
use crate::radiosity::form_factors::rows::OnDemand;
use crate::radiosity::form_factors::{self, hemicube, FormFactors};
use crate::radiosity::gather::{self, Extras, Gathered, Gatherer};
use crate::radiosity::patch_lights::PatchLights;
use crate::radiosity::solve::{self, progressive, System};
use crate::raycast::batch::BatchCaster;
use crate::raycast::device;
use crate::surface::Surfaces;
use glam::Vec3;

/// Radiosity with a final gather: texels' direct light sampled, indirect
/// light from the patch solution read back through per-texel rays.
///
/// # Errors
/// The direct solver refused (too many patches) or singular.
pub fn run(
    s: &Surfaces,
    atlas: &Atlas,
    config: &BakeConfig,
    (sky, layers): (&crate::light::sky::Sky, Option<&Layers>),
    log: &mut Log,
    shard: &Sharding,
) -> Result<TexelLight> {
    check_direct_solver(config, s.patches.len())?;
    let progress = log.progress();
    let advance = |n| progress.advance(n);
    // `device = "gpu"`: one batch caster for the form factors and the gather.
    let gpu = gpu_caster(s, config, &mut log.warnings);

    let progressive = config.solver == Solver::Progressive;
    let total = if progressive {
        0
    } else {
        s.patches.len() as u64
    };
    log.begin("form_factors", total);
    let form_factors = match (progressive, shard.is_whole()) {
        (true, _) => None,
        (false, true) => Some(compute_form_factors(
            s,
            config,
            gpu.as_deref(),
            &advance,
            &mut log.warnings,
        )),
        (false, false) => Some(sharded_form_factors(s, config, shard, &advance)?),
    };
    log.end("form_factors");

    log.begin("direct", s.texels.len() as u64);
    // The light layers' direct light in the same pass.
    let masks: Vec<Mask> = layers.map_or(Vec::new(), |l| {
        (0..l.len()).map(|k| Mask::of_layer(l, s.scene, k)).collect()
    });
    let (mut direct, layer_directs) = direct_light_layers(s, config, sky, &masks, &advance, shard)?;
    log.end("direct");
    shard.checkpoint(1, false)?;

    let max_shots = config.max_iterations as u64 * s.patches.len() as u64;
    let total = if progressive {
        max_shots
    } else {
        config.max_iterations as u64
    };
    log.begin("solve", total);
    let patch_direct = std::mem::take(&mut direct.patch);
    let dilate = 2 * config.padding;
    let mut watch = Snapshots::new(progress, s, atlas, || direct.parts.baked(), dilate);
    let patch_light = solved(shard, form_factors, patch_direct, |ff, patch_direct| {
        solve_patches(
            s,
            config,
            ff,
            &direct.sampled,
            patch_direct,
            (&advance, &mut watch),
            &mut log.warnings,
        )
    })?;
    if patch_light.solution.residual >= config.tolerance && config.solver != Solver::Direct {
        log.warnings.push(format!(
            "the solver stopped at its limit (max_iterations = {}) with residual {:.2e} above tolerance {:.2e}",
            config.max_iterations, patch_light.solution.residual, config.tolerance
        ));
    }
    log.end("solve");
    shard.checkpoint(1, true)?;

    let indirect: Vec<Vec3> = patch_light
        .solution
        .irradiance
        .iter()
        .zip(&patch_light.direct)
        .map(|(h, d)| *h - *d)
        .collect();
    let mut first = lightmap::first_pass(s.texels, s.patches, &direct.texel, &indirect);
    let mut rays = Rays {
        form_factors: patch_light.stats.rays,
        direct: direct.parts.rays,
        ..Rays::default()
    };
    let mixed = direct.mixed();
    if config.final_gather == 0 {
        // The lightmap leaves the mixed lights' direct light out.
        let baked = direct.parts.baked();
        let layers = match layers {
            Some(l) => super::layered::first_passes(s, config, (l, layer_directs), &patch_light, log)?,
            None => Vec::new(),
        };
        return Ok(TexelLight {
            valid: vec![true; first.len()],
            layers,
            values: lightmap::first_pass(s.texels, s.patches, &baked, &indirect),
            direct: baked,
            mixed,
            directional: None,
            ao: None,
            variance: Vec::new(),
            rays,
            patch_light: Some(patch_light),
        });
    }
    let (pre, validity_rays) = pre_validity(s, config, &mut first, log);
    rays.validity = validity_rays;
    // Each light layer's direct light and first pass, for the gather's
    // hits to read beside the whole's.
    let layer_inputs = match layers {
        Some(l) => super::layered::inputs(s, config, (l, layer_directs), &patch_light, &pre, log)?,
        None => Vec::new(),
    };
    let inputs = GatherInputs {
        sky,
        first: &first,
        pre: &pre,
        direct: &direct,
        patch_light: &patch_light,
        layers: &layer_inputs,
    };
    let (g, layer_gathers) = gather_stage(s, atlas, config, inputs, gpu.as_deref(), shard, log)?;
    rays.gather = g.rays;
    let parts = (layer_inputs.into_iter().map(|l| l.direct))
        .zip(layer_gathers)
        .collect();
    let light = gathered_light(s, atlas, config, (direct, g), parts, log);
    Ok(TexelLight {
        rays,
        mixed,
        patch_light: Some(patch_light),
        ..light
    })
}

/// Texel validity before the gather: the gather reads H₁ wherever its
/// rays land, and a texel buried in a wall holds the dark value of its
/// buried centre (Sponza's ceiling gathered 8 % too little). A first,
/// cheap estimate (or the burial stage's, from folded points) lets buried
/// texels take their neighbours' H₁ in `first` before anything reads
/// them. Returns each texel's validity and the rays cast.
fn pre_validity(
    s: &Surfaces,
    config: &BakeConfig,
    first: &mut [Vec3],
    log: &mut Log,
) -> (Vec<bool>, u64) {
    log.begin("validity", s.texels.len() as u64);
    let (pre, validity_rays) = if s.burial.valid.is_empty() {
        let v = crate::surface::validity::validity(
            s,
            crate::surface::validity::VALIDITY_RAYS,
            config.seed,
            config.backface_tolerance,
        );
        (v.valid, v.rays)
    } else {
        // Judged already by the burial stage, from folded points.
        (s.burial.valid.clone(), s.burial.stats.validity_rays)
    };
    lightmap::fill_invalid(
        s.texels,
        first,
        &pre,
        lightmap::fill_rings(config.patch_texels),
    );
    log.end("validity");
    (pre, validity_rays)
}

/// What the final gather reads: the sky, the first pass H₁ (`first`,
/// invalid texels filled), the validity estimate before it (`pre`), the
/// direct light and the patch solution.
struct GatherInputs<'a> {
    sky: &'a crate::light::sky::Sky,
    first: &'a [Vec3],
    pre: &'a [bool],
    /// The light layers' direct light and first passes (empty without
    /// layers): their gathers read the whole gather's hits.
    layers: &'a [super::layered::LayerInput],
    direct: &'a DirectLight,
    patch_light: &'a PatchLight,
}

/// The final gather ([`Gatherer`]) with its near field and, with
/// `gather_nee`, its light samples, on `gpu` where there is one, or the
/// slices of `shard`.
fn gather_stage<'a>(
    s: &'a Surfaces<'a>,
    atlas: &Atlas,
    config: &BakeConfig,
    inputs: GatherInputs<'a>,
    gpu: Option<&dyn BatchCaster>,
    shard: &Sharding,
    log: &mut Log,
) -> Result<(Gathered, Vec<Gathered>)> {
    let GatherInputs {
        sky,
        first,
        pre,
        direct,
        patch_light,
        layers,
    } = inputs;
    let progress = log.progress();
    let advance = |n| progress.advance(n);
    log.begin("final_gather", s.texels.len() as u64);
    let sizes = texel_sizes(s, atlas);
    let near = |g: Gatherer<'a>, direct: &'a DirectLight| near_field(g, config, &sizes, direct, pre);
    let gatherer = near(gatherer(s, first, direct, config, sky), direct);
    if !layers.is_empty() {
        // One pass: the layers read the whole gather's hits.
        let layer_gatherers: Vec<Gatherer> = (layers.iter())
            .map(|l| near(self::gatherer(s, &l.first, &l.direct, config, sky), &l.direct).for_layer(&l.mask))
            .collect();
        let both = match gpu.map(|g| gather::gather_layers(&gatherer, &layer_gatherers, Some(g), &advance)) {
            Some(Ok(both)) => both,
            other => {
                if let Some(Err(e)) = other {
                    log.warnings.push(format!("device = \"gpu\": {e:#}; final gather on the CPU"));
                }
                gather::gather_layers(&gatherer, &layer_gatherers, None, &advance)?
            }
        };
        log.end("final_gather");
        return Ok(both);
    }
    // Light samples towards the solved bright patches, picked by the rows
    // of F (so only with a stored matrix).
    let lights = match &patch_light.form_factors {
        Some(ff) if config.gather_nee => Some(PatchLights::build(
            s,
            &ff.matrix,
            &gatherer.texel_radiance(),
        )),
        _ => None,
    };
    let gatherer = match &lights {
        Some(l) => gatherer.with_lights(l),
        None => gatherer,
    };
    let g = if shard.is_whole() {
        final_gather(&gatherer, gpu, &advance, &mut log.warnings)
    } else {
        // Slices of equal cost: a valid texel casts its rays, an invalid
        // one stops after a few.
        let cost: Vec<f64> = (pre.iter())
            .map(|&v| if v { config.final_gather as f64 } else { 1.0 })
            .collect();
        let texels = shard.items(
            "gather",
            s.texels.len(),
            |count| crate::pipeline::shard::balanced(&cost, count),
            |range| gatherer.gather_range(range, &advance),
        )?;
        gatherer.assemble(texels)
    };
    drop(gatherer);
    shard.checkpoint(2, false)?;
    drop(lights);
    log.end("final_gather");
    Ok((g, Vec::new()))
}

/// `g` with its near field where there are local lights (see
/// [`gather::NearField`]): close hits, within `gather_near_field` texels of
/// the atlas's density (lowered to fit `max_texels`) and the hit
/// instance's texel scale (`sizes`), read the local lights at the point.
fn near_field<'a>(
    g: Gatherer<'a>,
    config: &BakeConfig,
    sizes: &[f32],
    direct: &'a DirectLight,
    pre: &'a [bool],
) -> Gatherer<'a> {
    if config.gather_near_field > 0.0 && direct.lights.has_local() {
        g.with_near(gather::NearField::new(
            config.gather_near_field,
            sizes,
            &direct.parts.local,
            pre,
            &direct.lights,
        ))
    } else {
        g
    }
}

/// The final gather's settings over first pass `first`: its extras, the
/// direct light it estimates with its own rays, and the direct light it
/// does not (the adaptive gather's yardstick: with `gathering`, the
/// punctual lights and light samples; else the whole direct pass).
pub(super) fn gatherer<'a>(
    s: &'a Surfaces<'a>,
    first: &'a [Vec3],
    direct: &'a DirectLight,
    config: &BakeConfig,
    sky: &crate::light::sky::Sky,
) -> Gatherer<'a> {
    let extras = Extras {
        directional: config.directional == config::DirectionalMode::Sh,
        sky: sky.clone(),
        ao_distance: config.ao_distance,
        backface_tolerance: config.backface_tolerance,
        threshold: config.gather_threshold,
    };
    let known = if direct.gathering {
        &direct.parts.light
    } else {
        &direct.texel
    };
    Gatherer::new(
        s,
        first,
        &direct.sampled,
        config.final_gather,
        config.seed,
        extras,
        direct.gathering.then_some((&direct.lights, direct.mis)),
    )
    .with_known(known)
}

/// The direct solver is O(n³): refuse more than `direct_max_patches`.
fn check_direct_solver(config: &BakeConfig, patches: usize) -> Result<()> {
    if config.solver == Solver::Direct && patches > config.direct_max_patches as usize {
        return Err(Error::Config {
            key: "direct_max_patches".into(),
            message: format!(
                "the direct solver is O(n³) and refuses {} patches (limit {}); use jacobi, gauss-seidel or progressive, or coarser patches",
                patches, config.direct_max_patches
            ),
        });
    }
    Ok(())
}

/// The batch caster of `device = "gpu"`, where a ray-casting stage will
/// use it (ray-cast form factors, the final gather); `None`, with a warning
/// saying why, where there is no adapter or the shader fails (every ray is
/// then cast on the CPU).
fn gpu_caster<'a>(
    s: &Surfaces<'a>,
    config: &BakeConfig,
    warnings: &mut Vec<String>,
) -> Option<Box<dyn BatchCaster + 'a>> {
    let uses = (config.form_factors == FormFactorMethod::Raycast
        && config.solver != Solver::Progressive)
        || config.final_gather > 0;
    if config.device != config::Device::Gpu || !uses {
        return None;
    }
    match device::gpu_batches(s.scene, s.geometry, s.rays) {
        Ok(g) => {
            warnings.push(format!(
                "form-factor and final-gather rays cast on the GPU: {}",
                g.describe()
            ));
            Some(g)
        }
        Err(e) => {
            warnings.push(format!("device = \"gpu\": {e:#}; all rays cast on the CPU"));
            None
        }
    }
}

/// Every row of F, by ray casting (on `gpu` where there is one; on the CPU,
/// with a warning, where it fails) or by hemicubes.
fn compute_form_factors(
    s: &Surfaces,
    config: &BakeConfig,
    gpu: Option<&dyn BatchCaster>,
    advance: &(dyn Fn(u64) + Sync),
    warnings: &mut Vec<String>,
) -> FormFactors {
    let (rays, seed) = (config.rays_per_patch, config.seed);
    match (config.form_factors, gpu) {
        (FormFactorMethod::Hemicube, _) => gpu_hemicubes(s, config, advance, warnings)
            .unwrap_or_else(|| hemicube::compute(s, config.hemicube_resolution, advance)),
        (FormFactorMethod::Raycast, Some(g)) => {
            match form_factors::raycast::compute_batched(s, g, rays, seed, advance) {
                Ok(ff) => ff,
                Err(e) => {
                    warnings.push(format!(
                        "device = \"gpu\": {e:#}; form factors computed on the CPU"
                    ));
                    form_factors::raycast::compute(s, rays, seed, advance)
                }
            }
        }
        (FormFactorMethod::Raycast, None) => form_factors::raycast::compute(s, rays, seed, advance),
    }
}

/// `device = "gpu"` with hemicubes: every row rendered on the GPU; `None`
/// (with a warning) where there is no adapter or it fails, and the CPU
/// renders them.
fn gpu_hemicubes(
    s: &Surfaces,
    config: &BakeConfig,
    advance: &(dyn Fn(u64) + Sync),
    warnings: &mut Vec<String>,
) -> Option<FormFactors> {
    let gpu = gpu_device(s, config, warnings)?;
    match hemicube::compute_on(s, gpu.as_ref(), config.hemicube_resolution, advance) {
        Ok(ff) => Some(ff),
        Err(e) => {
            warnings.push(format!(
                "device = \"gpu\": {e:#}; hemicubes rendered on the CPU"
            ));
            None
        }
    }
}

/// The GPU's hemicubes for `device = "gpu"` (a warning names the adapter,
/// or why there is none, and then the CPU renders them).
fn gpu_device(
    s: &Surfaces,
    config: &BakeConfig,
    warnings: &mut Vec<String>,
) -> Option<Box<dyn hemicube::RowBatches>> {
    if config.device != config::Device::Gpu {
        return None;
    }
    match open_gpu_hemicubes(s.geometry, config.hemicube_resolution) {
        Ok(g) => {
            warnings.push(format!("hemicubes rendered on the GPU: {}", g.describe()));
            Some(g)
        }
        Err(e) => {
            warnings.push(format!(
                "device = \"gpu\": {e:#}; hemicubes rendered on the CPU"
            ));
            None
        }
    }
}

/// The form-factor rows of a sharded bake ([`crate::pipeline::shard`]): a phase-1
/// job casts its slice of patches' rows on the CPU; later jobs read them.
fn sharded_form_factors(
    s: &Surfaces,
    config: &BakeConfig,
    shard: &Sharding,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<FormFactors> {
    use rayon::prelude::*;
    let n = s.patches.len();
    let on_demand = OnDemand::new(s, config);
    // Slices of equal cost: a buried patch casts nothing.
    let cost = || -> Vec<f64> {
        (0..n)
            .map(|i| if s.patch_buried(i) { 0.01 } else { 1.0 })
            .collect()
    };
    let rows = shard.items(
        "rows",
        n,
        |count| crate::pipeline::shard::balanced(&cost(), count),
        |range| {
            (range.into_par_iter())
                .map(|i| {
                    let r = on_demand.counted(i);
                    advance(1);
                    r
                })
                .collect()
        },
    )?;
    Ok(FormFactors::from_results(n, rows))
}

/// What the solve leaves for later shards: the solution, Σⱼ Fᵢⱼ and the
/// counters (the matrix itself is read again from the rows' slices).
#[derive(serde::Serialize, serde::Deserialize)]
struct Solved {
    solution: solve::Solution,
    row_sums: Vec<f32>,
    stats: form_factors::FormFactorStats,
}

/// The solve, or in a sharded bake its product: computed by merge 1 (and
/// written), read by later jobs ([`Sharding::once`]).
fn solved(
    shard: &Sharding,
    form_factors: Option<FormFactors>,
    patch_direct: Vec<Vec3>,
    solve: impl FnOnce(Option<FormFactors>, Vec<Vec3>) -> Result<PatchLight>,
) -> Result<PatchLight> {
    if shard.is_whole() {
        return solve(form_factors, patch_direct);
    }
    let mut inputs = Some((form_factors, patch_direct));
    let mut kept = None;
    let product = shard.once("solve", 1, || {
        let (ff, direct) = inputs.take().ok_or(Error::ShardDone)?;
        let p = solve(ff, direct)?;
        let out = Solved {
            solution: p.solution.clone(),
            row_sums: p.row_sums.clone(),
            stats: p.stats.clone(),
        };
        kept = Some(p);
        Ok(out)
    })?;
    if let Some(p) = kept {
        return Ok(p);
    }
    let (form_factors, patch_direct) = inputs.ok_or(Error::ShardDone)?;
    Ok(PatchLight {
        form_factors,
        stats: product.stats,
        row_sums: product.row_sums,
        direct: patch_direct,
        solution: product.solution,
    })
}

/// The patch system L = E′ + ρ H, H = D + F L, solved by `config.solver`.
/// Emission sampled as direct light is in D already; only the other
/// emitters' emission E′ enters the solve.
fn solve_patches(
    s: &Surfaces,
    config: &BakeConfig,
    form_factors: Option<FormFactors>,
    sampled: &[bool],
    patch_direct: Vec<Vec3>,
    (advance, watch): (&(dyn Fn(u64) + Sync), &mut Snapshots),
    warnings: &mut Vec<String>,
) -> Result<PatchLight> {
    let emission: Vec<Vec3> = (0..s.patches.len())
        .map(|i| {
            let t = s.patches.texels_of(i)[0] as usize;
            let m = s.geometry.material[s.texels.triangle[t] as usize] as usize;
            if sampled[m] {
                Vec3::ZERO
            } else {
                s.patches.emission[i]
            }
        })
        .collect();
    let system = System {
        emission: &emission,
        albedo: &s.patches.albedo,
        direct: &patch_direct,
        area: &s.patches.area,
    };
    let (tolerance, iterations) = (config.tolerance, config.max_iterations);
    let (solution, row_sums, stats) = match &form_factors {
        Some(ff) => {
            let solution = solve_matrix(&ff.matrix, &system, config, advance)?;
            (solution, ff.row_sums(), ff.stats.clone())
        }
        None => {
            let mut rows = OnDemand::new(s, config);
            if config.form_factors == FormFactorMethod::Hemicube {
                if let Some(gpu) = gpu_device(s, config, warnings) {
                    rows = rows.with_gpu(gpu);
                }
            }
            let max_shots = iterations as u64 * s.patches.len() as u64;
            let mut observe = |p: &progressive::Partial| watch.observe(&system, p);
            let shot =
                progressive::solve(&rows, &system, tolerance, max_shots, advance, &mut observe);
            let mut solution = shot.solution;
            let row_sums =
                progressive::gather_sweeps(&rows, &system, &mut solution, 2, Some(&shot.rows));
            if let Some(e) = rows.gpu_failed() {
                warnings.push(format!(
                    "device = \"gpu\": {e}; the other hemicubes rendered on the CPU"
                ));
            }
            (solution, row_sums, rows.stats())
        }
    };
    Ok(PatchLight {
        form_factors,
        stats,
        row_sums,
        direct: patch_direct,
        solution,
    })
}

/// The final gather, its rays cast on `gpu` where there is one; on the
/// CPU, with a warning, where it fails.
pub(super) fn final_gather(
    gatherer: &Gatherer,
    gpu: Option<&dyn BatchCaster>,
    advance: &(dyn Fn(u64) + Sync),
    warnings: &mut Vec<String>,
) -> Gathered {
    if let Some(g) = gpu {
        match gatherer.gather_batched(g, advance) {
            Ok(gathered) => return gathered,
            Err(e) => warnings.push(format!("device = \"gpu\": {e:#}; final gather on the CPU")),
        }
    }
    gatherer.gather_cpu(advance)
}

/// Texel light from the gather: the direct light, its hemisphere part
/// replaced by the gather's where the gather estimates it, plus the
/// gathered indirect light. The denoiser filters everything the gather's
/// rays estimated: the indirect light and that hemisphere part of the
/// direct light (the sky's and area lights' cosine-sampled, MIS-weighted
/// share, as noisy as the indirect in shade); the light-sampled direct
/// light (punctual lights, light samples of area lights and the sky)
/// keeps its sharp shadows. `direct` (the report's direct figures) is
/// unfiltered. The directional part is the gather's plus the punctual
/// lights' exact part.
fn gathered_light(
    s: &Surfaces,
    atlas: &Atlas,
    config: &BakeConfig,
    (mut direct, mut g): (DirectLight, Gathered),
    parts: Vec<(DirectLight, Gathered)>,
    log: &mut Log,
) -> TexelLight {
    // `texel_direct` (reported) keeps the gather's direct part; `sharp`
    // is the rest, which the filter leaves alone.
    let split = |direct: DirectLight, g: &mut Gathered| -> [Vec<Vec3>; 3] {
        if direct.gathering {
            let sum = |a: &[Vec3]| a.iter().zip(&g.direct).map(|(x, h)| *x + *h).collect();
            let (gathered, texel_direct) = (sum(&g.indirect), sum(&direct.parts.light));
            [direct.parts.light, gathered, texel_direct]
        } else {
            let baked = direct.parts.baked();
            [baked.clone(), std::mem::take(&mut g.indirect), baked]
        }
    };
    let punctual = std::mem::take(&mut direct.parts.directional);
    let [sharp, mut gathered, texel_direct] = split(direct, &mut g);
    // The light layers': each its sharp part, its gathered part and its
    // mixed lights' direct light.
    let mut layers: Vec<([Vec<Vec3>; 2], Vec<Vec3>)> = Vec::with_capacity(parts.len());
    for (d, mut lg) in parts {
        let mixed = d.mixed();
        let [sharp, gathered, _] = split(d, &mut lg);
        layers.push(([sharp, gathered], mixed));
    }
    if config.denoise {
        log.begin("denoise", 0);
        let texel_size = texel_sizes(s, atlas);
        let region = |t: usize| s.burial.region(s.texels, t);
        let mut layer_gathered: Vec<Vec<Vec3>> = (layers.iter_mut())
            .map(|(p, _)| std::mem::take(&mut p[1]))
            .collect();
        denoise::atrous_layers(
            s.texels,
            &region,
            (&mut gathered, &mut layer_gathered),
            &g.valid,
            &g.variance,
            &texel_size,
        );
        for ((p, _), lg) in layers.iter_mut().zip(layer_gathered) {
            p[1] = lg;
        }
        log.end("denoise");
    }
    let add = |a: &[Vec3], b: &[Vec3]| -> Vec<Vec3> { a.iter().zip(b).map(|(d, i)| *d + *i).collect() };
    let values = add(&sharp, &gathered);
    let layers = (layers.into_iter())
        .map(|([sharp, gathered], mixed)| LayerTexels {
            values: add(&sharp, &gathered),
            mixed,
        })
        .collect();
    let directional = (!g.directional.is_empty()).then(|| {
        (0..g.directional.len())
            .map(|t| std::array::from_fn(|axis| g.directional[t][axis] + punctual[t][axis]))
            .collect::<Vec<Directional>>()
    });
    TexelLight {
        values,
        valid: g.valid,
        direct: texel_direct,
        directional,
        ao: (!g.ao.is_empty()).then_some(g.ao),
        variance: g.variance,
        layers,
        rays: Rays::default(),
        mixed: Vec::new(),
        patch_light: None,
    }
}

/// Per instance, the side of one of its texels in metres: the atlas's
/// density (lowered to fit `max_texels`) times the instance's texel scale.
pub(super) fn texel_sizes(s: &Surfaces, atlas: &Atlas) -> Vec<f32> {
    s.scene
        .instances
        .iter()
        .map(|i| 1.0 / (atlas.texels_per_meter * i.texel_scale))
        .collect()
}

/// Hemicubes of resolution `n` on the GPU (`device = "gpu"`).
///
/// # Errors
/// No adapter, a driver that refuses the pipeline, or a build without the
/// `gpu` feature: the caller renders hemicubes on the CPU.
fn open_gpu_hemicubes(
    geometry: &crate::layout::geometry::Geometry,
    n: u32,
) -> crate::Result<Box<dyn hemicube::RowBatches>> {
    #[cfg(feature = "gpu")]
    return Ok(Box::new(
        crate::radiosity::form_factors::gpu_hemicube::GpuHemicubes::new(geometry, n)?,
    ));
    #[cfg(not(feature = "gpu"))]
    {
        let _ = (geometry, n);
        crate::error::device_bail!("radbake was built without the `gpu` feature")
    }
}
