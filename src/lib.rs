//! # radbake — a radiosity lightmap baker for glTF 2.0 scenes
//!
//! The bake is a pipeline of plain data, one module per stage:
//!
//! ```text
//! Scene ─► Atlas ─► Geometry ─► Texels ─► Patches ─► FormFactors ─► Solution ─► Lightmaps ─► files
//! scene    atlas    geometry    texels    patches    form_factors   solve        lightmap     output
//! ```
//!
//! It solves the discrete radiosity equation (Goral, Torrance, Greenberg &
//! Battaile 1984) for Lambertian surfaces, in radiance form:
//! Lᵢ = Eᵢ + ρᵢ Σⱼ Fᵢⱼ Lⱼ.
//!
//! **Units and the lightmap convention.** glTF emissive (`emissiveFactor` ×
//! `KHR_materials_emissive_strength`) is emitted radiance. A lightmap texel
//! holds *incident irradiance / π* (linear RGB), so a Lambertian surface's
//! outgoing radiance is `albedo × lightmap + emission`.
//!
//! ```no_run
//! let scene = radbake::scene::load("scene.gltf".as_ref(), &Default::default())?;
//! let bake = radbake::bake(&scene, &radbake::BakeConfig::default(), &radbake::Silent)?;
//! radbake::output::write_lightmaps("out".as_ref(), &bake.lightmaps)?;
//! radbake::output::write_report("out".as_ref(), &bake.report("scene.gltf"))?;
//! # Ok::<(), radbake::Error>(())
//! ```

pub mod atlas;
pub mod config;
pub mod denoise;
pub mod direct;
pub mod error;
pub mod form_factors;
pub mod gather;
pub mod geometry;
#[cfg(feature = "preview")]
pub mod gpu;
pub mod incremental;
pub mod lightmap;
pub mod output;
pub mod patches;
pub mod photon;
#[cfg(feature = "preview")]
pub mod preview;
pub mod progress;
pub mod raycast;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod seams;
pub mod solve;
pub mod texels;
pub mod trace;

pub use config::BakeConfig;
pub use error::{Error, Result};
pub use progress::{Progress, Silent};

use atlas::Atlas;
use form_factors::{raycast::Surfaces, FormFactors};
use geometry::Geometry;
use glam::Vec3;
use lightmap::Lightmaps;
use patches::Patches;
use rayon::prelude::*;
use report::{Counts, Energy, InstanceReport, Report, StageTime};
use scene::Scene;
use solve::Solution;
use std::time::Instant;
use texels::Texels;

/// Everything a bake produced, stage by stage.
pub struct Bake<'s> {
    /// The input scene.
    pub scene: &'s Scene,
    /// Effective settings.
    pub config: BakeConfig,
    /// Lightmap atlas.
    pub atlas: Atlas,
    /// World triangles.
    pub geometry: Geometry,
    /// Lightmap texels.
    pub texels: Texels,
    /// Patches.
    pub patches: Patches,
    /// Form factors (None for progressive refinement, which stores none).
    pub form_factors: Option<FormFactors>,
    /// Σⱼ Fᵢⱼ per patch (NaN for patches that progressive refinement never shot).
    pub row_sums: Vec<f32>,
    /// Form-factor counters.
    pub ff_stats: form_factors::FormFactorStats,
    /// Direct light (irradiance / π) per texel.
    pub direct: Vec<Vec3>,
    /// Direct light per patch (area-weighted mean of its texels').
    pub patch_direct: Vec<Vec3>,
    /// Radiosity solution (H per patch includes the direct light).
    pub solution: Solution,
    /// Rays cast for direct light.
    pub direct_rays: u64,
    /// Rays cast by the final gather.
    pub gather_rays: u64,
    /// Rays cast by the validity estimate before the gather.
    pub validity_rays: u64,
    /// Texels found inside or under geometry (filled from their neighbours).
    pub invalid_texels: u64,
    /// Validity per texel (false: inside or under geometry, filled).
    pub texel_valid: Vec<bool>,
    /// Seam sample pairs stitched.
    pub seam_samples: u64,
    /// Mean |difference| across seams (RGB sum) before and after stitching.
    pub seam_mismatch: [f64; 2],
    /// Lightmap pages.
    pub lightmaps: Lightmaps,
    /// Directional lightmaps (`--directional sh`): a, b_x, b_y, b_z pages,
    /// irradiance / π for a normal n being a + n_x b_x + n_y b_y + n_z b_z.
    pub sh: Option<[Lightmaps; 4]>,
    /// Ambient-occlusion pages (grey), with `--ao DISTANCE`.
    pub ao: Option<Lightmaps>,
    /// Wall time per stage.
    pub stages: Vec<StageTime>,
    /// Non-fatal problems.
    pub warnings: Vec<String>,
}

struct Timer<'a> {
    stages: Vec<StageTime>,
    start: Instant,
    progress: &'a dyn Progress,
}

impl<'a> Timer<'a> {
    fn begin(&mut self, stage: &str, total: u64) {
        self.start = Instant::now();
        self.progress.begin(stage, total);
    }
    fn end(&mut self, stage: &str) {
        self.progress.end();
        self.stages.push(StageTime {
            stage: stage.into(),
            seconds: self.start.elapsed().as_secs_f64(),
        });
    }
}

/// Bakes `scene` with `config`, reporting to `progress`.
///
/// # Errors
/// [`Error::Config`] for settings out of range, [`Error::Unwrap`] when the
/// atlas can't be built.
pub fn bake<'s>(
    scene: &'s Scene,
    config: &BakeConfig,
    progress: &dyn Progress,
) -> Result<Bake<'s>> {
    config.validate()?;
    let mut warnings = scene.warnings.clone();
    if !scene.has_emitters() {
        warnings
            .push("the scene has no emissive surface and no light: the lightmaps are black".into());
    }
    let mut timer = Timer {
        stages: Vec::new(),
        start: Instant::now(),
        progress,
    };

    timer.begin("unwrap", 0);
    let atlas = atlas::unwrap(scene, config)?;
    warnings.extend(atlas.warnings.iter().cloned());
    timer.end("unwrap");

    timer.begin("texels", 0);
    let geometry = Geometry::new(scene, &atlas);
    let texels = texels::rasterize(scene, &atlas, &geometry);
    timer.end("texels");

    timer.begin("patches", 0);
    let patches = patches::build(
        &texels,
        config.patch_texels,
        1.0 / (atlas.texels_per_meter * atlas.texels_per_meter),
    );
    timer.end("patches");

    timer.begin("bvh", 0);
    let rays = raycast::RayCaster::new(scene, &geometry);
    timer.end("bvh");

    let surfaces = Surfaces {
        scene,
        geometry: &geometry,
        texels: &texels,
        patches: &patches,
        rays: &rays,
    };
    // `device = "gpu"`: one GPU ray caster for the form factors and the final gather.
    let gpu = gpu_caster(&surfaces, config, &mut warnings);
    let advance = |n| progress.advance(n);
    let solved = match config.method {
        config::Method::Radiosity => {
            let progressive = config.solver == config::Solver::Progressive;
            if config.solver == config::Solver::Direct
                && patches.len() > config.direct_max_patches as usize
            {
                return Err(Error::Config {
                    key: "direct_max_patches".into(),
                    message: format!(
                        "the direct solver is O(n³) and refuses {} patches (limit {}); use jacobi, gauss-seidel or progressive, or coarser patches",
                        patches.len(),
                        config.direct_max_patches
                    ),
                });
            }
            // Progressive refinement computes rows on demand: no matrix is stored.
            timer.begin(
                "form_factors",
                if progressive { 0 } else { patches.len() as u64 },
            );
            let form_factors = (!progressive).then(|| match config.form_factors {
                config::FormFactorMethod::Raycast if gpu.is_some() => {
                    gpu_form_factors(gpu.as_ref(), &surfaces, config, &advance, &mut warnings)
                }
                config::FormFactorMethod::Raycast => form_factors::raycast::compute(
                    &surfaces,
                    config.rays_per_patch,
                    config.seed,
                    &advance,
                ),
                config::FormFactorMethod::Hemicube => {
                    form_factors::hemicube::compute(&surfaces, config.hemicube_resolution, &advance)
                }
            });
            timer.end("form_factors");

            timer.begin("direct", texels.len() as u64);
            let sampled = direct_sampled_materials(scene, &geometry, config.emitters);
            let lights = direct::Lights::new(scene, &geometry, &sampled, Vec3::from(config.sky));
            // With the final gather on (and casting at least as many rays as
            // the direct light's samples, as every preset does), its rays
            // estimate the hemisphere part of the direct light (sky, emitters
            // by MIS) for the lightmap, so the direct pass casts only a
            // quarter as many hemisphere rays, for the first pass H₁ that the
            // solve and the gather's hits read (Sponza: 30 % fewer rays).
            let gathering = config.final_gather > 0 && config.final_gather >= config.direct_samples;
            let mis = direct::Mis {
                light: config.direct_samples,
                hemisphere: if gathering {
                    config.final_gather
                } else {
                    config.direct_samples
                },
            };
            let first_direct = direct::texels(
                &surfaces,
                &lights,
                config.direct_samples,
                if gathering {
                    (config.direct_samples / 4).max(4)
                } else {
                    config.direct_samples
                },
                mis,
                config.supersample,
                config.seed,
                &advance,
            );
            let mut texel_direct = first_direct.total();
            let direct_dir = first_direct.directional;
            let direct_rays = first_direct.rays;
            let patch_direct: Vec<Vec3> = (0..patches.len())
                .map(|i| {
                    let sum: Vec3 = patches
                        .texels_of(i)
                        .iter()
                        .map(|&t| texel_direct[t as usize] * texels.area[t as usize])
                        .sum();
                    sum / patches.area[i]
                })
                .collect();
            timer.end("direct");

            // Emission sampled as direct light is in D already; only the other
            // emitters' emission enters the solve: L = E' + ρ H, H = D + F L.
            let solve_emission: Vec<Vec3> = (0..patches.len())
                .map(|i| {
                    let t = patches.texels_of(i)[0] as usize;
                    let m = geometry.material[texels.triangle[t] as usize] as usize;
                    if sampled[m] {
                        Vec3::ZERO
                    } else {
                        patches.emission[i]
                    }
                })
                .collect();
            let system = solve::System {
                emission: &solve_emission,
                albedo: &patches.albedo,
                direct: &patch_direct,
                area: &patches.area,
            };
            let max_shots = config.max_iterations as u64 * patches.len() as u64;
            timer.begin(
                "solve",
                if progressive {
                    max_shots
                } else {
                    config.max_iterations as u64
                },
            );
            let (solution, row_sums, ff_stats) = match &form_factors {
                Some(ff) => {
                    let f = &ff.matrix;
                    let solution = match config.solver {
                        config::Solver::GaussSeidel => solve::gauss_seidel::solve(
                            f,
                            &system,
                            config.tolerance,
                            config.max_iterations,
                            &advance,
                        ),
                        config::Solver::Direct => solve::dense::solve(f, &system).ok_or_else(|| {
                            Error::Limit(
                                "the radiosity matrix is singular (an albedo of 1 in a closed scene?)"
                                    .into(),
                            )
                        })?,
                        _ => solve::jacobi::solve(
                            f,
                            &system,
                            config.tolerance,
                            config.max_iterations,
                            &advance,
                        ),
                    };
                    (solution, ff.row_sums(), ff.stats.clone())
                }
                None => {
                    let rows = form_factors::OnDemand::new(&surfaces, config);
                    let p = solve::progressive::solve(
                        &rows,
                        &system,
                        config.tolerance,
                        max_shots,
                        &advance,
                    );
                    // Shooting scales a shooter's row by Aᵢ/Aⱼ (reciprocity), which
                    // is noisy for small receivers (and biased for the hemicube's
                    // point-sampled rows). Two gathering sweeps from each patch's own
                    // row, L ← E + ρ (D + F L), put the accuracy back on the
                    // receiving side (each divides the shooting error by ~1/ρ);
                    // rows are made and dropped, so memory stays O(n).
                    let mut solution = p.solution;
                    let mut gathered: Vec<(Vec3, f32)> = Vec::new();
                    for _ in 0..2 {
                        gathered = (0..patches.len())
                            .into_par_iter()
                            .map(|j| {
                                let row = rows.row(j);
                                let h = row
                                    .iter()
                                    .map(|&(k, f)| solution.radiance[k as usize] * f)
                                    .sum::<Vec3>();
                                (system.direct[j] + h, row.iter().map(|e| e.1).sum())
                            })
                            .collect();
                        solution.irradiance = gathered.iter().map(|g| g.0).collect();
                        solution.radiance = (0..patches.len())
                            .map(|j| system.emission[j] + system.albedo[j] * solution.irradiance[j])
                            .collect();
                    }
                    (
                        solution,
                        gathered.iter().map(|g| g.1).collect(),
                        rows.stats(),
                    )
                }
            };
            if solution.residual >= config.tolerance && config.solver != config::Solver::Direct {
                warnings.push(format!(
                    "the solver stopped at its limit (max_iterations = {}) with residual {:.2e} above tolerance {:.2e}",
                    config.max_iterations, solution.residual, config.tolerance
                ));
            }
            timer.end("solve");

            let indirect: Vec<Vec3> = solution
                .irradiance
                .iter()
                .zip(&patch_direct)
                .map(|(h, d)| *h - *d)
                .collect();
            let mut first = lightmap::first_pass(&texels, &patches, &texel_direct, &indirect);
            let mut validity_rays = 0u64;
            if config.final_gather > 0 {
                // The gather reads H₁ wherever its rays land, and a texel
                // buried in a wall holds the dark value of its buried centre
                // (Sponza's ceiling gathered 8 % too little). A first, cheap
                // validity estimate lets buried texels take their
                // neighbours' H₁ before anything reads them.
                timer.begin("validity", texels.len() as u64);
                let (pre, rays) = gather::validity(&surfaces, gather::VALIDITY_RAYS, config.seed);
                lightmap::fill_invalid(&texels, &mut first, &pre, fill_rings(config));
                validity_rays = rays;
                timer.end("validity");
            }
            let extras = gather::Extras {
                directional: config.directional == config::DirectionalMode::Sh,
                sky: Vec3::from(config.sky),
                ao_distance: config.ao_distance,
            };
            let mut gathered_dir: Vec<direct::Directional> = Vec::new();
            let mut ao: Vec<f32> = Vec::new();
            let (texel_values, valid, gather_rays) = if config.final_gather > 0 {
                timer.begin("final_gather", texels.len() as u64);
                let gatherer = gather::Gatherer::new(
                    &surfaces,
                    &first,
                    &sampled,
                    config.final_gather,
                    config.seed,
                    extras,
                    gathering.then_some((&lights, mis)),
                );
                let g = final_gather(gpu.as_ref(), &gatherer, &advance, &mut warnings);
                if gathering {
                    texel_direct = first_direct
                        .light
                        .iter()
                        .zip(&g.direct)
                        .map(|(l, h)| *l + *h)
                        .collect();
                }
                gathered_dir = g.directional;
                ao = g.ao;
                timer.end("final_gather");
                let mut indirect = g.indirect;
                if config.denoise {
                    timer.begin("denoise", 0);
                    denoise::atrous(
                        &texels,
                        &mut indirect,
                        &g.valid,
                        &g.variance,
                        1.0 / atlas.texels_per_meter,
                    );
                    timer.end("denoise");
                }
                let values = texel_direct
                    .iter()
                    .zip(&indirect)
                    .map(|(d, i)| *d + *i)
                    .collect();
                (values, g.valid, g.rays)
            } else {
                (first, vec![true; texels.len()], 0)
            };
            Solved {
                form_factors,
                row_sums,
                ff_stats,
                texel_direct,
                direct_dir,
                patch_direct,
                solution,
                direct_rays,
                texel_values,
                valid,
                gather_rays,
                validity_rays,
                gathered_dir,
                ao,
            }
        }
        config::Method::Pathtrace | config::Method::Photon => {
            let sky = Vec3::from(config.sky);
            let tracer = trace::Tracer::new(scene, &geometry, &rays, sky);
            let (texel_values, valid, paths) = if config.method == config::Method::Pathtrace {
                timer.begin("path_trace", texels.len() as u64);
                let (v, ok) = trace::reference_texels(
                    &tracer,
                    &texels,
                    &|t, j, rng| surfaces.sample_texel_area(t, j, rng),
                    config.path_samples,
                    config.seed,
                    &advance,
                );
                timer.end("path_trace");
                (v, ok, texels.len() as u64 * config.path_samples as u64)
            } else {
                timer.begin("photons", texels.len() as u64);
                let out = photon::bake_texels(&surfaces, &tracer, config, &advance);
                timer.end("photons");
                out
            };
            Solved {
                form_factors: None,
                row_sums: Vec::new(),
                ff_stats: Default::default(),
                texel_direct: vec![Vec3::ZERO; texels.len()],
                direct_dir: vec![[Vec3::ZERO; 3]; texels.len()],
                patch_direct: Vec::new(),
                solution: Solution::default(),
                direct_rays: 0,
                texel_values,
                valid,
                gather_rays: paths,
                validity_rays: 0,
                gathered_dir: Vec::new(),
                ao: Vec::new(),
            }
        }
    };
    let Solved {
        form_factors,
        row_sums,
        ff_stats,
        texel_direct,
        direct_dir,
        patch_direct,
        solution,
        direct_rays,
        mut texel_values,
        valid,
        gather_rays,
        validity_rays,
        gathered_dir,
        ao,
    } = solved;
    timer.begin("lightmaps", 0);
    lightmap::fill_invalid(&texels, &mut texel_values, &valid, fill_rings(config));
    let invalid_texels = valid.iter().filter(|v| !**v).count() as u64;
    let mut lightmaps =
        lightmap::build(&texels, texel_values, atlas.page_count, 2 * config.padding);
    let seam_samples = if config.stitch_seams {
        seams::find(&geometry)
    } else {
        Vec::new()
    };
    let seam_mismatch = [seams::mismatch(&lightmaps, &seam_samples), 0.0];
    seams::stitch(&mut lightmaps, &seam_samples, 16);
    let seam_mismatch = [seam_mismatch[0], seams::mismatch(&lightmaps, &seam_samples)];
    for t in 0..texels.len() {
        let [x, y] = texels.xy[t];
        lightmaps.texel_values[t] =
            lightmaps.pages[texels.page[t] as usize][(y * texels.width + x) as usize];
    }
    // Directional maps: b from the gather (indirect, sky, emitters) plus the
    // punctual lights' exact part; a = value − n · b, so a + n · b
    // reproduces the lightmap at the surface normal.
    let sh = (!gathered_dir.is_empty()).then(|| {
        let b: Vec<direct::Directional> = (0..texels.len())
            .map(|t| std::array::from_fn(|axis| gathered_dir[t][axis] + direct_dir[t][axis]))
            .collect();
        let a: Vec<Vec3> = (0..texels.len())
            .map(|t| {
                let n = texels.n_ws[t];
                lightmaps.texel_values[t] - b[t][0] * n.x - b[t][1] * n.y - b[t][2] * n.z
            })
            .collect();
        let page = |v: Vec<Vec3>| lightmap::build(&texels, v, atlas.page_count, 2 * config.padding);
        [
            page(a),
            page(b.iter().map(|d| d[0]).collect()),
            page(b.iter().map(|d| d[1]).collect()),
            page(b.iter().map(|d| d[2]).collect()),
        ]
    });
    let ao = (!ao.is_empty()).then(|| {
        lightmap::build(
            &texels,
            ao.iter().map(|&v| Vec3::splat(v)).collect(),
            atlas.page_count,
            2 * config.padding,
        )
    });
    timer.end("lightmaps");

    Ok(Bake {
        scene,
        config: config.clone(),
        atlas,
        geometry,
        texels,
        patches,
        form_factors,
        row_sums,
        ff_stats,
        direct: texel_direct,
        patch_direct,
        solution,
        direct_rays,
        gather_rays,
        validity_rays,
        invalid_texels,
        texel_valid: valid,
        seam_samples: seam_samples.len() as u64,
        seam_mismatch,
        lightmaps,
        sh,
        ao,
        stages: timer.stages,
        warnings,
    })
}

/// The GPU ray caster of `device = "gpu"` (wgpu, feature `preview`).
#[cfg(feature = "preview")]
type GpuCaster = gpu::GpuRayCaster;
/// Without the `preview` feature there is none.
#[cfg(not(feature = "preview"))]
type GpuCaster = std::convert::Infallible;

/// The GPU ray caster where `device = "gpu"` and a ray-casting stage will
/// use it (ray-cast form factors, the final gather); `None`, with a warning
/// saying why, where there is no adapter or the shader fails (the bake then
/// casts every ray on the CPU).
fn gpu_caster(
    surfaces: &Surfaces,
    config: &BakeConfig,
    warnings: &mut Vec<String>,
) -> Option<GpuCaster> {
    let uses = config.method == config::Method::Radiosity
        && ((config.form_factors == config::FormFactorMethod::Raycast
            && config.solver != config::Solver::Progressive)
            || config.final_gather > 0);
    if config.device != config::Device::Gpu || !uses {
        return None;
    }
    #[cfg(feature = "preview")]
    {
        match gpu::GpuRayCaster::new(surfaces.geometry) {
            Ok(g) => {
                warnings.push(format!(
                    "form-factor and final-gather rays cast on the GPU: {}",
                    g.adapter
                ));
                Some(g)
            }
            Err(e) => {
                warnings.push(format!("device = \"gpu\": {e:#}; all rays cast on the CPU"));
                None
            }
        }
    }
    #[cfg(not(feature = "preview"))]
    {
        let _ = surfaces;
        warnings.push(
            "device = \"gpu\" needs the `preview` feature (wgpu); all rays cast on the CPU".into(),
        );
        None
    }
}

/// Ray-cast form factors with the rays cast on the GPU ([`gpu`]); on the
/// CPU, with a warning, where the GPU fails.
fn gpu_form_factors(
    gpu: Option<&GpuCaster>,
    surfaces: &Surfaces,
    config: &BakeConfig,
    advance: &(dyn Fn(u64) + Sync),
    warnings: &mut Vec<String>,
) -> FormFactors {
    #[cfg(feature = "preview")]
    if let Some(g) = gpu {
        match gpu::form_factors(surfaces, g, config.rays_per_patch, config.seed, advance) {
            Ok(ff) => return ff,
            Err(e) => warnings.push(format!(
                "device = \"gpu\": {e:#}; form factors computed on the CPU"
            )),
        }
    }
    #[cfg(not(feature = "preview"))]
    if let Some(g) = gpu {
        match *g {}
    }
    let _ = &warnings;
    form_factors::raycast::compute(surfaces, config.rays_per_patch, config.seed, advance)
}

/// The final gather, its rays cast on the GPU where there is one ([`gpu`]);
/// on the CPU, with a warning, where the GPU fails.
fn final_gather(
    gpu: Option<&GpuCaster>,
    gatherer: &gather::Gatherer,
    advance: &(dyn Fn(u64) + Sync),
    warnings: &mut Vec<String>,
) -> gather::Gathered {
    #[cfg(feature = "preview")]
    if let Some(g) = gpu {
        match gpu::gather(gatherer, g, advance) {
            Ok(gathered) => return gathered,
            Err(e) => warnings.push(format!("device = \"gpu\": {e:#}; final gather on the CPU")),
        }
    }
    #[cfg(not(feature = "preview"))]
    if let Some(g) = gpu {
        match *g {}
    }
    let _ = &warnings;
    gatherer.gather_cpu(advance)
}

/// What the light-transport stage hands to the lightmap stage.
struct Solved {
    form_factors: Option<FormFactors>,
    row_sums: Vec<f32>,
    ff_stats: form_factors::FormFactorStats,
    texel_direct: Vec<Vec3>,
    direct_dir: Vec<direct::Directional>,
    patch_direct: Vec<Vec3>,
    solution: Solution,
    direct_rays: u64,
    texel_values: Vec<Vec3>,
    valid: Vec<bool>,
    gather_rays: u64,
    validity_rays: u64,
    gathered_dir: Vec<direct::Directional>,
    ao: Vec<f32>,
}

/// Rings of neighbours an invalid texel is filled from
/// ([`lightmap::fill_invalid`]): four patches' width, at least 16 texels.
fn fill_rings(config: &BakeConfig) -> u32 {
    4 * config.patch_texels.max(4)
}

/// Which materials' emission is sampled as direct light (per
/// [`config::EmitterSampling`]); the rest enters the radiosity solve.
/// Public for the benchmarks, which run single stages.
pub fn direct_sampled_materials(
    scene: &Scene,
    geometry: &Geometry,
    mode: config::EmitterSampling,
) -> Vec<bool> {
    use config::EmitterSampling::*;
    let mut area = vec![0.0f64; scene.materials.len()];
    let mut total = 0.0f64;
    for (t, &m) in geometry.material.iter().enumerate() {
        area[m as usize] += geometry.area[t] as f64;
        total += geometry.area[t] as f64;
    }
    scene
        .materials
        .iter()
        .enumerate()
        .map(|(m, mat)| {
            mat.is_emissive()
                && match mode {
                    Direct => true,
                    Radiosity => false,
                    Auto => area[m] <= 0.02 * total,
                }
        })
        .collect()
}

impl Bake<'_> {
    /// Per-instance area-weighted means of the texel values.
    pub fn instance_reports(&self) -> Vec<InstanceReport> {
        let n = self.scene.instances.len();
        let mut area = vec![0.0f64; n];
        let mut sum = vec![[0.0f64; 3]; n];
        let mut count = vec![0u64; n];
        for t in 0..self.texels.len() {
            let i = self.texels.instance[t] as usize;
            let a = self.texels.area[t] as f64;
            let v = self.lightmaps.texel_values[t];
            area[i] += a;
            count[i] += 1;
            for c in 0..3 {
                sum[i][c] += a * v[c] as f64;
            }
        }
        self.scene
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| {
                let r = self.atlas.instances[i];
                InstanceReport {
                    node: inst.node.clone(),
                    mesh: self.scene.meshes[inst.mesh as usize].name.clone(),
                    area: area[i],
                    texels: count[i],
                    mean: std::array::from_fn(|c| {
                        if area[i] > 0.0 {
                            (sum[i][c] / area[i]) as f32
                        } else {
                            0.0
                        }
                    }),
                    page: r.page,
                    uv_rect: [r.min[0], r.min[1], r.max[0], r.max[1]],
                }
            })
            .collect()
    }

    /// The power balance of the solution (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        let p = &self.patches;
        let s = &self.solution;
        let rows = &self.row_sums;
        let pi = std::f64::consts::PI;
        let mut e = Energy::default();
        for (i, row_sum) in rows.iter().enumerate() {
            let a = p.area[i] as f64;
            for c in 0..3 {
                let emitted = pi * a * p.emission[i][c] as f64;
                e.emitted[c] += emitted;
                e.emitted_landing[c] += emitted * *row_sum as f64;
                e.direct_received[c] += pi * a * self.patch_direct[i][c] as f64;
                e.absorbed[c] += pi * a * (1.0 - p.albedo[i][c] as f64) * s.irradiance[i][c] as f64;
                e.reflected_escaped[c] +=
                    pi * a * s.radiance[i][c] as f64 * (1.0 - *row_sum as f64);
            }
        }
        for c in 0..3 {
            e.relative_imbalance[c] = if e.direct_received[c] > 0.0 {
                (e.direct_received[c] - e.absorbed[c] - e.reflected_escaped[c])
                    / e.direct_received[c]
            } else {
                0.0
            };
        }
        e
    }

    /// The report for this bake of `scene_path`.
    pub fn report(&self, scene_path: &str) -> Report {
        let st = &self.scene.stats;
        let ff = &self.ff_stats;
        Report {
            radbake_version: env!("CARGO_PKG_VERSION").into(),
            scene: scene_path.into(),
            settings: self.config.clone(),
            stages: self.stages.clone(),
            counts: Counts {
                triangles: self.geometry.len() as u64,
                instances: self.scene.instances.len() as u64,
                meshes: self.scene.meshes.len() as u64,
                lights: self.scene.lights.len() as u64,
                degenerate_triangles: st.degenerate_triangles,
                skipped_primitives: st.skipped_primitives,
                unmapped_triangles: self.texels.unmapped_triangles,
                chart_overlaps: self.texels.chart_overlaps,
                pages: self.atlas.page_count as u64,
                page_size: [self.atlas.width, self.atlas.height],
                charts: self.atlas.chart_count as u64,
                utilization: self.atlas.utilization,
                texels_per_meter: self.atlas.texels_per_meter,
                texels: self.texels.len() as u64,
                patches: self.patches.len() as u64,
                nonzeros: self.form_factors.as_ref().map_or(0, |f| f.nnz() as u64),
                rays: ff.rays + self.direct_rays + self.validity_rays + self.gather_rays,
                rays_form_factors: ff.rays,
                rays_direct: self.direct_rays,
                rays_validity: self.validity_rays,
                rays_gather: self.gather_rays,
                invalid_texels: self.invalid_texels,
                seam_samples: self.seam_samples,
                seam_mismatch: self.seam_mismatch,
                rays_escaped: ff.escaped,
                rays_back_faces: ff.back_faces,
                rays_unmapped: ff.unmapped,
                iterations: self.solution.iterations as u64,
                shots: self.solution.shots,
                residual: self.solution.residual,
            },
            energy: self.energy(),
            instances: self.instance_reports(),
            warnings: self.warnings.clone(),
        }
    }
}
