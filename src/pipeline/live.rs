//! A live bake's extra stage: what the run time needs to re-solve the live
//! lights' bounced light for any direction ([`radbake_live`]), gathered
//! from the bake's products into one [`LiveData`] (`live.bin`):
//!
//! - the patches' form factors F (as f16) and albedo ρ, as solved here;
//! - each live light's sun table ([`sun_table`]);
//! - how texels are made from patches: the first pass's interpolation
//!   ([`lightmap::bilinear_weights`], the per-patch shift by area share) and
//!   each texel's pixel, with the padding's copies
//!   ([`lightmap::padding_sources`]);
//! - with probes, the patch each probe ray meets ([`probe_hits`]), for the
//!   live layer's probes to follow the sun ([`radbake_live::probes`]).
//!
//! The live lights are baked in mode `indirect`, their bounced light in
//! the layer [`LIVE_LAYER`], which the run time's solution replaces.

use super::log::Log;
use super::texel_light::TexelLight;
use crate::config::{BakeConfig, LightMode, Solver, LIVE_LAYER};
use crate::error::{Error, Result};
use crate::light::sky::Sky;
use crate::light::sun_table::{patch_direct, sun_table, sun_table_along};
use crate::maps::lightmap;
use crate::scene::layers::Layers;
use crate::scene::Scene;
use crate::surface::Surfaces;
use crate::probes::Probes;
use crate::surface::Landing;
use radbake_live::format::{Matrix, ProbeGrid, ProbeHeader, ProbeHits, TexelMap};
use rayon::prelude::*;
use radbake_live::{Header, LiveData, LiveLight, PageSize, SkyLayer};

/// The scene's live lights (indices into [`Scene::lights`]).
pub fn live_lights(scene: &Scene) -> Vec<usize> {
    (0..scene.lights.len())
        .filter(|&i| scene.lights[i].mode == LightMode::Live)
        .collect()
}

/// `config` for a scene with live lights: a uniform sky that names no
/// layer is put in its own layer `sky`, so that its colour can change at
/// run time. Unchanged otherwise.
pub fn effective_config(scene: &Scene, config: &BakeConfig, sky: &Sky) -> BakeConfig {
    let mut c = config.clone();
    let uniform = matches!(sky, Sky::Uniform(_)) && !sky.is_black();
    if !live_lights(scene).is_empty() && c.sky_layer.is_none() && uniform {
        c.sky_layer = Some("sky".into());
    }
    c
}

/// Refuses settings under which the live stage cannot run: layers off
/// (the live lights' bounce is a layer), and the light layers' own
/// ([`super::layered::check`], said for live lights).
///
/// # Errors
/// [`Error::Config`] naming the setting.
pub fn check(scene: &Scene, config: &BakeConfig, shard: &super::shard::Sharding) -> Result<()> {
    if live_lights(scene).is_empty() {
        return Ok(());
    }
    if config.layers == crate::config::LayerMode::Off {
        return Err(Error::Config {
            key: "layers".into(),
            message: "live lights are baked into the light layer `live`: set layers = \"auto\" (or bake the light in mode `indirect`)".into(),
        });
    }
    super::layered::check(config, shard, true)
}

/// The live data of a bake whose scene has live lights (None without).
///
/// # Errors
/// [`Error::Limit`] where F has more entries than the file holds.
pub fn build(
    s: &Surfaces,
    (config, sky, layers): (&BakeConfig, &Sky, &Layers),
    (light, probes): (&TexelLight, Option<&Probes>),
    page_count: u32,
    log: &mut Log,
) -> Result<Option<LiveData>> {
    let live = live_lights(s.scene);
    if live.is_empty() {
        return Ok(None);
    }
    let Some(f) = (light.patch_light.as_ref()).and_then(|p| p.form_factors.as_ref()) else {
        // `layered::check` refused progressive refinement already.
        return Err(Error::Config {
            key: "solver".into(),
            message: "live lights need a stored form-factor matrix".into(),
        });
    };
    let matrix = matrix(&f.matrix)?;
    log.begin("live", (s.texels.len() * live.len()) as u64);
    let progress = log.progress();
    let advance = |n| progress.advance(n);
    let paths: Vec<Option<Vec<glam::Vec3>>> = (live.iter())
        .map(|&i| sun_path(&s.scene.lights[i], config))
        .collect::<Result<_>>()?;
    let suns = (live.iter().zip(&paths))
        .map(|(&i, path)| {
            let light = &s.scene.lights[i];
            match path {
                Some(p) => sun_table_along(s, light, p, config.seed, &advance),
                None => sun_table(s, light, config.live_grid, config.seed, &advance),
            }
        })
        .collect();
    let texels = texel_map(s, page_count, 2 * config.padding);
    let probes = probes
        .filter(|p| config.live_probe_rays > 0 && !p.is_empty())
        .map(|p| probe_hits(s, p, config.live_probe_rays));
    log.end("live");
    let p = s.patches.len() as u64;
    let header = Header {
        version: radbake_live::format::VERSION,
        patches: p,
        texels: s.texels.len() as u64,
        entries: matrix.vals.len() as u64,
        block: s.patches.block,
        grid: config.live_grid,
        padding: texels.padding.iter().map(|p| p.len() as u64).collect(),
        pages: vec![
            PageSize {
                width: s.texels.width,
                height: s.texels.height,
            };
            page_count.max(1) as usize
        ],
        tolerance: config.tolerance,
        max_iterations: if config.solver == Solver::Direct {
            200
        } else {
            config.max_iterations
        },
        layer: LIVE_LAYER.into(),
        lights: (live.iter().zip(paths))
            .map(|(&i, path)| {
                let l = &s.scene.lights[i];
                LiveLight {
                    name: l.name.clone(),
                    direction: (-l.direction).to_array(),
                    irradiance: l.intensity.to_array(),
                    path: path.map(|p| p.iter().map(|d| d.to_array()).collect()),
                }
            })
            .collect(),
        sky: sky_layer(s.scene, sky, layers),
        probes: probes.as_ref().map(|p| p.0.clone()),
    };
    let data = LiveData {
        header,
        albedo: s.patches.albedo.iter().map(|a| a.to_array()).collect(),
        matrix,
        suns,
        texels,
        probes: None,
    };
    Ok(Some(match probes {
        Some((_, hits)) => with_baked_radiance(s, &live, config, data, hits)?,
        None => data,
    }))
}

/// `data` with the probes' `hits` and the patches' outgoing radiance at
/// the baked suns, which the probes were baked with: D from each live
/// light's exact visibility at its direction ([`patch_direct`], not the
/// table's interpolation: a sun off its path is the bake's own), solved
/// by the run time's Jacobi iterations. So the probes' change at run time
/// is measured from the light they hold.
///
/// # Errors
/// [`Error::Config`] should the direct light not be finite.
fn with_baked_radiance(
    s: &Surfaces,
    live: &[usize],
    config: &BakeConfig,
    data: LiveData,
    mut hits: ProbeHits,
) -> Result<LiveData> {
    let mut direct = vec![[0.0f32; 3]; s.patches.len()];
    for &i in live {
        let light = &s.scene.lights[i];
        let d = patch_direct(s, light, &[-light.direction], config.seed, &|_| {});
        for (acc, row) in direct.iter_mut().zip(&d) {
            for (c, e) in acc.iter_mut().zip(light.intensity.to_array()) {
                *c += e * row[0];
            }
        }
    }
    let max = data.header.max_iterations;
    let mut solver = radbake_live::Live::new(data);
    solver.set_direct(&direct).map_err(|e| Error::Config {
        key: "live".into(),
        message: e.to_string(),
    })?;
    solver.solve(max);
    hits.baked = solver.patch_radiance().to_vec();
    let mut data = solver.into_data();
    data.probes = Some(hits);
    Ok(data)
}

/// The patch that each probe's rays meet: ray i along the Fibonacci
/// direction i of `rays` (the same set for every probe, so the run time
/// keeps one basis per ray), u32::MAX where it meets nothing, a back face
/// or a surface without texels; none traced for an invalid probe (its
/// light is filled from its neighbours').
fn probe_hits(s: &Surfaces, probes: &Probes, rays: u32) -> (ProbeHeader, ProbeHits) {
    let dirs: Vec<glam::Vec3> = (0..rays).map(|i| crate::probes::light::fibonacci(i, rays)).collect();
    let hits: Vec<u32> = (0..probes.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let p = probes.position(i);
            let valid = probes.valid[i];
            dirs.iter().map(move |&d| {
                if !valid {
                    return u32::MAX;
                }
                match s.trace(p, d).0 {
                    Landing::Texel(t) => s.patches.of_texel[t as usize].0,
                    _ => u32::MAX,
                }
            })
        })
        .collect();
    let header = ProbeHeader {
        count: probes.len() as u64,
        rays,
        grids: (probes.volumes.iter())
            .map(|v| ProbeGrid {
                first: v.first as u64,
                resolution: v.resolution.to_array(),
            })
            .collect(),
    };
    let valid = probes.valid.clone();
    let baked = Vec::new();
    (header, ProbeHits { valid, hits, baked })
}

/// A live light's path directions: its node's, else the settings' (None:
/// the hemisphere's grid).
///
/// # Errors
/// [`Error::Config`] for a path on which the sun never rises.
fn sun_path(light: &crate::scene::Light, config: &BakeConfig) -> Result<Option<Vec<glam::Vec3>>> {
    let path = light.sun_path.clone().or(config.sun_path.map(Into::into));
    path.map(|p| {
        p.directions().map_err(|message| Error::Config {
            key: format!("sun_path of light `{}`", light.name),
            message,
        })
    })
    .transpose()
}

/// The sky's layer where its colour may change live: a uniform sky alone
/// in its layer.
fn sky_layer(scene: &Scene, sky: &Sky, layers: &Layers) -> Option<SkyLayer> {
    let Sky::Uniform(c) = sky else { return None };
    let k = layers.sky?;
    let (lights, materials, _) = layers.members(scene, k);
    (lights.is_empty() && materials.is_empty()).then(|| SkyLayer {
        layer: layers.names[k].clone(),
        radiance: c.to_array(),
    })
}

/// F in the file's form: entries as f16 (rounded to nearest; the error
/// is measured in `docs/live.md`).
fn matrix(f: &crate::radiosity::form_factors::Csr) -> Result<Matrix> {
    if f.nnz() > u32::MAX as usize {
        return Err(Error::Limit(format!(
            "F has {} entries; live.bin holds at most {}",
            f.nnz(),
            u32::MAX
        )));
    }
    let mut m = Matrix {
        rows: vec![0],
        cols: Vec::with_capacity(f.nnz()),
        vals: Vec::with_capacity(f.nnz()),
    };
    for i in 0..f.nrows() {
        for (j, v) in f.row(i).iter() {
            m.cols.push(j);
            m.vals.push(half::f16::from_f32(v).to_bits());
        }
        m.rows.push(m.vals.len() as u32);
    }
    Ok(m)
}

/// Each texel's patch, area share, corner patches and pixel; the
/// padding's copies.
fn texel_map(s: &Surfaces, page_count: u32, rings: u32) -> TexelMap {
    let (t, p) = (s.texels, s.patches);
    TexelMap {
        patch: p.of_texel.iter().map(|q| q.0).collect(),
        share: (0..t.len())
            .map(|i| t.area[i] / p.area[p.of_texel[i].0 as usize])
            .collect(),
        corners: (0..t.len())
            .map(|i| lightmap::bilinear_weights(t, p, i).0.map(|c| c.map_or(u32::MAX, |(q, _)| q)))
            .collect(),
        pixel: (0..t.len()).map(|i| t.xy[i][1] * t.width + t.xy[i][0]).collect(),
        page: t.page.iter().map(|&pg| pg as u16).collect(),
        padding: lightmap::padding_sources(t, page_count, rings),
    }
}
