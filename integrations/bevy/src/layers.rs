//! Light layers at run time: a bake whose lights are grouped into layers
//! (radbake's `docs/layers.md`) shows, in Bevy, the bake at any RGB weight
//! per layer: put a [`RadbakeLayers`] on the [`RadbakeBake`] entity and
//! change its weights.
//!
//! Each layer's lightmap pages and irradiance volumes are its lights'
//! share of the bake, so the bake at weights w is Σₖ wₖ × layer k, per
//! texel and per voxel (bounces included). When the weights change:
//! - the pages and volumes are recombined on Bevy's
//!   [`AsyncComputeTaskPool`] from the layers' RGB9E5 images (loaded once,
//!   kept on the CPU only); the frame that changes a weight only starts
//!   the task, and the frame that finishes it only swaps the new images
//!   into the bake's page and volume assets (Bevy then uploads them);
//! - on that same frame each layer's lights (its `lights`, by glTF node
//!   name) get their intensity × max(w) and colour × w / max(w), and its
//!   emissive materials their emission × w, so a light's specular, its
//!   light on dynamic objects and a lamp's glowing surface follow the
//!   layer with its baked light.
//!
//! A weight for a layer the bake does not have, or one that is negative
//! or not finite, is refused: nothing changes, the bake entity gets a
//! [`RadbakeLayersError`] with a one-line reason, and it is logged.

use crate::live::{moved, LiveJob, Solved};
use crate::{RadbakeApplied, RadbakeBake, RadbakeLiveApplied, RadbakeManifest};
use bevy::gltf::GltfMaterialName;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::tasks::{block_on, poll_once, AsyncComputeTaskPool, Task};
use radbake_live::Sun;
use std::sync::Arc;

/// One light layer of a bake (`manifest.json`'s `layers`).
#[derive(Debug, Clone)]
pub struct Layer {
    /// The layer's name.
    pub name: String,
    /// Its lights: the glTF node names of their `KHR_lights_punctual` nodes.
    pub lights: Vec<String>,
    /// Its emissive materials: glTF material names.
    pub materials: Vec<String>,
    /// Per lightmap page, the layer's share (`lightmap_<page>_<layer>.ktx2`,
    /// RGB9E5, loaded for the main world only).
    pub pages: Vec<Handle<Image>>,
    /// Per probe grid, the layer's share (`probes_<k>_<layer>.ktx2`).
    pub volumes: Vec<Handle<Image>>,
}

/// The RGB weight of each light layer of the bake on this entity; a layer
/// not named keeps weight 1 (the bake as baked).
#[derive(Component, Clone, Debug, Default, PartialEq)]
pub struct RadbakeLayers {
    /// Layer name → RGB weight.
    pub weights: HashMap<String, Vec3>,
}

impl RadbakeLayers {
    /// These weights with layer `name` at `rgb`.
    pub fn with(mut self, name: &str, rgb: Vec3) -> Self {
        self.set(name, rgb);
        self
    }

    /// Sets layer `name`'s weight to `rgb`.
    pub fn set(&mut self, name: &str, rgb: Vec3) {
        self.weights.insert(name.to_owned(), rgb);
    }

    /// Layer `name`'s weight (1 where not set).
    pub fn weight(&self, name: &str) -> Vec3 {
        self.weights.get(name).copied().unwrap_or(Vec3::ONE)
    }
}

/// Why the last [`RadbakeLayers`] change was refused (one line); removed
/// when weights are applied.
#[derive(Component, Clone, Debug)]
pub struct RadbakeLayersError(pub String);

/// The weights now shown, on the bake entity once they are applied.
#[derive(Component, Clone, Debug, Default)]
pub struct RadbakeLayersApplied {
    /// The weights applied.
    pub weights: RadbakeLayers,
    /// How many times weights were applied.
    pub generation: u64,
    /// Milliseconds the last recombination took on its task.
    pub task_ms: f32,
}

/// The layers' texels, decoded once: per page (then per volume), per
/// layer, RGB per texel; and each target image without its data.
struct Sources {
    pages: Vec<(Image, Vec<Vec<Vec3>>)>,
    volumes: Vec<(Image, Vec<Vec<Vec3>>)>,
}

/// What a recombination task returns.
struct Recombined {
    weights: RadbakeLayers,
    pages: Vec<Image>,
    volumes: Vec<Image>,
    task_ms: f32,
    /// A live bake's solve (its live layer's pages replaced).
    live: Option<Solved>,
}

/// A bake's recombination state.
#[derive(Component, Default)]
pub(crate) struct LayerJob {
    sources: Option<Arc<Sources>>,
    task: Option<Task<Recombined>>,
    /// Weights changed while a task ran: start again when it is done.
    stale: bool,
    /// Base emission of each layered material (by asset), and its layer.
    emission: HashMap<AssetId<StandardMaterial>, (usize, LinearRgba)>,
    /// Base intensity and colour of each layered light entity, and its layer.
    lights: HashMap<Entity, (usize, f32, LinearRgba)>,
    /// A live bake's run time ([`crate::live`]).
    live: Option<LiveJob>,
}

/// Checks `weights` against the bake's layers: every name is a layer, every
/// weight finite and ≥ 0.
fn check(weights: &RadbakeLayers, layers: &[Layer], live: Option<&str>) -> Result<(), String> {
    for (name, w) in &weights.weights {
        if Some(name.as_str()) == live {
            return Err(format!(
                "radbake: layer `{name}` is the live sun's, re-solved as its light turns: change the light's colour or illuminance instead"
            ));
        }
        if !layers.iter().any(|l| &l.name == name) {
            let names: Vec<&str> = layers.iter().map(|l| l.name.as_str()).collect();
            return Err(format!(
                "radbake: the bake has no layer `{name}` (its layers: {})",
                names.join(", ")
            ));
        }
        if !w.is_finite() || w.min_element() < 0.0 {
            return Err(format!(
                "radbake: layer `{name}`: weight {w} must be finite and ≥ 0"
            ));
        }
    }
    Ok(())
}

/// The layers' images decoded ([`Sources`]); `None` until all are loaded.
fn sources(manifest: &RadbakeManifest, images: &Assets<Image>) -> Option<Result<Sources, String>> {
    let decode = |h: &Handle<Image>| -> Option<Result<(Image, Vec<Vec3>), String>> {
        let img = images.get(h)?;
        let data = img.data.as_ref()?;
        if img.texture_descriptor.format
            != bevy::render::render_resource::TextureFormat::Rgb9e5Ufloat
        {
            return Some(Err(format!(
                "radbake: a layer image is {:?}, not RGB9E5",
                img.texture_descriptor.format
            )));
        }
        let texels = data
            .chunks_exact(4)
            .map(|c| rgb9e5_to_rgb(u32::from_le_bytes([c[0], c[1], c[2], c[3]])))
            .collect();
        let mut template = img.clone();
        template.data = None;
        template.asset_usage = bevy::asset::RenderAssetUsages::default();
        Some(Ok((template, texels)))
    };
    let group = |count: usize, of: &dyn Fn(&Layer) -> &[Handle<Image>]| {
        let mut out = Vec::with_capacity(count);
        for k in 0..count {
            let mut template = None;
            let mut per_layer = Vec::with_capacity(manifest.layers.len());
            for l in &manifest.layers {
                let h = of(l).get(k)?;
                let (t, texels) = match decode(h)? {
                    Ok(d) => d,
                    Err(e) => return Some(Err(e)),
                };
                template.get_or_insert(t);
                per_layer.push(texels);
            }
            out.push((template?, per_layer));
        }
        Some(Ok(out))
    };
    let pages = match group(manifest.pages.len(), &|l| &l.pages)? {
        Ok(p) => p,
        Err(e) => return Some(Err(e)),
    };
    let volumes = match group(manifest.volumes.len(), &|l| &l.volumes)? {
        Ok(v) => v,
        Err(e) => return Some(Err(e)),
    };
    for (_, per_layer) in pages.iter().chain(&volumes) {
        if per_layer.windows(2).any(|w| w[0].len() != w[1].len()) {
            return Some(Err("radbake: the layers' images differ in size".into()));
        }
    }
    Some(Ok(Sources { pages, volumes }))
}

/// Σₖ wₖ × layer k into a copy of `template`, RGB9E5; with `live`, layer
/// `live.0`'s texels are `live.1` (weight 1: its pages, or its volumes
/// moved by the probes' change).
fn weighted(
    template: &Image,
    per_layer: &[Vec<Vec3>],
    w: &[Vec3],
    live: Option<(usize, &[[f32; 3]])>,
) -> Image {
    let n = per_layer.first().map_or(0, Vec::len);
    let mut data = Vec::with_capacity(4 * n);
    for i in 0..n {
        let mut v = Vec3::ZERO;
        for (k, (l, w)) in per_layer.iter().zip(w).enumerate() {
            v += match live {
                Some((lk, page)) if lk == k => Vec3::from(page[i]),
                _ => l[i] * *w,
            };
        }
        data.extend_from_slice(&rgb_to_rgb9e5(v).to_le_bytes());
    }
    let mut image = template.clone();
    image.data = Some(data);
    image
}

/// Starts a recombination for every applied bake whose [`RadbakeLayers`]
/// changed (or changed while one ran), or whose live sun moved
/// ([`crate::live`]), and applies those that finished.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub(crate) fn recombine_layers(
    mut commands: Commands,
    mut bakes: Query<
        (
            Entity,
            &RadbakeBake,
            Option<Ref<RadbakeLayers>>,
            Option<&mut LayerJob>,
        ),
        With<RadbakeApplied>,
    >,
    manifests: Res<Assets<RadbakeManifest>>,
    mut images: ResMut<Assets<Image>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut lights: ParamSet<(
        Query<&mut PointLight>,
        Query<&mut SpotLight>,
        Query<&mut DirectionalLight>,
        Query<(&DirectionalLight, &GlobalTransform)>,
    )>,
    tagged: (
        Query<&Children>,
        Query<(&GltfMaterialName, &MeshMaterial3d<StandardMaterial>)>,
    ),
    names: (Query<&ChildOf>, Query<&Name>),
    applied: (Query<&RadbakeLayersApplied>, Query<&RadbakeLiveApplied>),
) {
    let as_baked = RadbakeLayers::default();
    for (root, bake, weights, job) in &mut bakes {
        let Some(manifest) = manifests.get(&bake.manifest) else {
            continue;
        };
        // Weights to apply, or a live sun to follow (its other layers as
        // baked where no weights are given).
        if weights.is_none() && manifest.live.is_none() {
            continue;
        }
        let changed = weights.as_ref().is_some_and(|w| w.is_changed());
        let weights: &RadbakeLayers = weights.as_deref().unwrap_or(&as_baked);
        let Some(mut job) = job else {
            commands.entity(root).insert(LayerJob {
                stale: true,
                live: manifest.live.as_ref().map(|d| {
                    let k = manifest
                        .layers
                        .iter()
                        .position(|l| l.name == d.header.layer);
                    LiveJob::new(d, k.unwrap_or(usize::MAX))
                }),
                ..default()
            });
            continue;
        };
        if changed {
            job.stale = true;
        }
        let sun = job.live.as_mut().and_then(|live| {
            let layer = manifest.layers.get(live.layer)?;
            let sun = live.sun_now(
                root,
                &layer.lights,
                (&tagged.0, &names.0, &names.1),
                &lights.p3(),
            )?;
            Some((sun, live.solved.is_none_or(|s| moved(&sun, &s))))
        });
        if sun.is_some_and(|(_, m)| m) {
            job.stale = true;
        }
        if let Some(task) = job.task.as_mut() {
            let Some(done) = block_on(poll_once(task)) else {
                continue;
            };
            job.task = None;
            let w = done.weights.clone();
            let ctx = (&mut commands, root, &applied);
            if !finish(&mut job, done, manifest, ctx, &mut images) {
                continue;
            }
            weigh_lights(
                &mut job,
                manifest,
                &w,
                root,
                &mut lights,
                &tagged,
                &names,
                &mut materials,
            );
        }
        if !job.stale || job.task.is_some() {
            continue;
        }
        let live_layer = manifest.live.as_ref().map(|d| d.header.layer.as_str());
        if let Err(e) = check(weights, &manifest.layers, live_layer) {
            error!("{e}");
            commands.entity(root).insert(RadbakeLayersError(e));
            job.stale = false;
            continue;
        }
        if job.sources.is_none() {
            match sources(manifest, &images) {
                None => continue, // the layers' images are still loading
                Some(Ok(s)) => job.sources = Some(Arc::new(s)),
                Some(Err(e)) => {
                    error!("{e}");
                    commands.entity(root).insert(RadbakeLayersError(e));
                    job.stale = false;
                    continue;
                }
            }
        }
        start(&mut job, manifest, weights, sun.map(|(s, _)| s));
    }
}

/// Applies a finished recombination: the new pages and volumes into the
/// bake's image assets, [`RadbakeLayersApplied`] (and
/// [`RadbakeLiveApplied`]) on the bake entity. False where the live solve
/// failed (nothing applied; [`RadbakeLayersError`] says why).
fn finish(
    job: &mut LayerJob,
    done: Recombined,
    manifest: &RadbakeManifest,
    (commands, root, applied): (
        &mut Commands,
        Entity,
        &(Query<&RadbakeLayersApplied>, Query<&RadbakeLiveApplied>),
    ),
    images: &mut Assets<Image>,
) -> bool {
    if let Some(solved) = done.live {
        let live = job
            .live
            .as_mut()
            .expect("a live solve comes from a live job");
        live.solver = Some(solved.solver);
        live.pages = solved.pages;
        match solved.result {
            Ok(solve) => {
                live.solved = Some(solved.sun);
                let generation = applied.1.get(root).map_or(0, |a| a.generation) + 1;
                commands.entity(root).insert(RadbakeLiveApplied {
                    direction: Vec3::from(solved.sun.direction).normalize(),
                    irradiance: Vec3::from(solved.sun.irradiance),
                    iterations: solve.iterations,
                    residual: solve.residual,
                    solve_ms: solved.ms,
                    generation,
                });
            }
            Err(e) => {
                // Solved as far as it goes: not again until the sun moves.
                live.solved = Some(solved.sun);
                error!("{e}");
                commands.entity(root).insert(RadbakeLayersError(e));
                return false;
            }
        }
    }
    for (h, image) in manifest.pages.iter().zip(done.pages) {
        let _ = images.insert(h.id(), image);
    }
    for (v, image) in manifest.volumes.iter().zip(done.volumes) {
        let _ = images.insert(v.voxels.id(), image);
    }
    let generation = applied.0.get(root).map_or(0, |a| a.generation) + 1;
    commands.entity(root).insert(RadbakeLayersApplied {
        weights: done.weights,
        generation,
        task_ms: done.task_ms,
    });
    commands.entity(root).remove::<RadbakeLayersError>();
    true
}

/// Starts the recombination task at `weights` (and, for a live bake, the
/// solve for `sun`).
fn start(
    job: &mut LayerJob,
    manifest: &RadbakeManifest,
    weights: &RadbakeLayers,
    sun: Option<Sun>,
) {
    let sources = job.sources.clone().expect("sources are decoded first");
    let w: Vec<Vec3> = manifest
        .layers
        .iter()
        .map(|l| weights.weight(&l.name))
        .collect();
    let weights = RadbakeLayers::clone(weights);
    job.stale = false;
    // A live bake: its solver and sun go to the task (the first
    // recombination waits for the light to be found).
    let live = match (job.live.as_mut(), sun) {
        (Some(live), Some(sun)) => match live.solver.take() {
            Some(solver) => {
                live.solved = Some(sun);
                Some((solver, sun, std::mem::take(&mut live.pages), live.layer))
            }
            None => return,
        },
        (Some(_), None) => {
            job.stale = true;
            return;
        }
        (None, _) => None,
    };
    job.task = Some(AsyncComputeTaskPool::get().spawn(async move {
        let t = std::time::Instant::now();
        let solved =
            live.map(|(solver, sun, pages, k)| (crate::live::solve(solver, sun, pages), k));
        let replaced = |page: usize| match &solved {
            Some((s, k)) if s.result.is_ok() => s.pages.get(page).map(|p| (*k, &p[..])),
            _ => None,
        };
        let pages = (sources.pages.iter().enumerate())
            .map(|(i, (t, l))| weighted(t, l, &w, replaced(i)))
            .collect();
        // The live layer's volumes: as baked + the probes' change.
        let moved_volume = |i: usize| -> Option<(usize, Vec<[f32; 3]>)> {
            let (s, k) = solved.as_ref().filter(|(s, _)| s.result.is_ok())?;
            let delta = s.volumes.as_ref()?.get(i)?;
            let baked = sources.volumes.get(i)?.1.get(*k)?;
            // The grids match the volumes (checked at load).
            let sum = baked.iter().zip(delta);
            Some((
                *k,
                sum.map(|(b, d)| (*b + Vec3::from(*d)).max(Vec3::ZERO).to_array())
                    .collect(),
            ))
        };
        let volumes = (sources.volumes.iter().enumerate())
            .map(|(i, (t, l))| {
                let moved = moved_volume(i);
                weighted(t, l, &w, moved.as_ref().map(|(k, v)| (*k, &v[..])))
            })
            .collect();
        Recombined {
            weights,
            pages,
            volumes,
            task_ms: t.elapsed().as_secs_f32() * 1e3,
            live: solved.map(|(s, _)| s),
        }
    }));
}

/// The lights and emissive materials of each layer at `weights` (see the
/// module documentation); their baked values recorded the first time.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn weigh_lights(
    job: &mut LayerJob,
    manifest: &RadbakeManifest,
    weights: &RadbakeLayers,
    root: Entity,
    lights: &mut ParamSet<(
        Query<&mut PointLight>,
        Query<&mut SpotLight>,
        Query<&mut DirectionalLight>,
        Query<(&DirectionalLight, &GlobalTransform)>,
    )>,
    (children, tagged): &(
        Query<&Children>,
        Query<(&GltfMaterialName, &MeshMaterial3d<StandardMaterial>)>,
    ),
    (parents, names): &(Query<&ChildOf>, Query<&Name>),
    materials: &mut Assets<StandardMaterial>,
) {
    // The live layer's light is the user's to turn and dim: not weighed.
    let live = manifest.live.as_ref().map(|d| d.header.layer.as_str());
    let layer_of_light = |name: &str| {
        manifest
            .layers
            .iter()
            .position(|l| Some(l.name.as_str()) != live && l.lights.iter().any(|n| n == name))
    };
    let layer_of_material = |name: &str| {
        manifest
            .layers
            .iter()
            .position(|l| l.materials.iter().any(|n| n == name))
    };
    let w: Vec<Vec3> = manifest
        .layers
        .iter()
        .map(|l| weights.weight(&l.name))
        .collect();
    for e in children.iter_descendants(root) {
        if let Ok((name, mat)) = tagged.get(e) {
            if let Some(k) = layer_of_material(&name.0) {
                if !job.emission.contains_key(&mat.id()) {
                    if let Some(m) = materials.get(&mat.0) {
                        job.emission.insert(mat.id(), (k, m.emissive));
                    }
                }
            }
        }
        if job.lights.contains_key(&e) {
            continue;
        }
        let node = parents.get(e).ok().and_then(|p| names.get(p.parent()).ok());
        let Some(k) = node.and_then(|n| layer_of_light(n.as_str())) else {
            continue;
        };
        let base = if let Ok(l) = lights.p0().get(e) {
            Some((l.intensity, l.color.to_linear()))
        } else if let Ok(l) = lights.p1().get(e) {
            Some((l.intensity, l.color.to_linear()))
        } else if let Ok(l) = lights.p2().get(e) {
            Some((l.illuminance, l.color.to_linear()))
        } else {
            None
        };
        if let Some((i, c)) = base {
            job.lights.insert(e, (k, i, c));
        }
    }
    for (&id, &(k, base)) in &job.emission {
        if let Some(mut m) = materials.get_mut(id) {
            m.emissive =
                LinearRgba::rgb(base.red * w[k].x, base.green * w[k].y, base.blue * w[k].z);
        }
    }
    for (&e, &(k, intensity, colour)) in &job.lights {
        let peak = w[k].max_element();
        let tint = if peak > 0.0 { w[k] / peak } else { Vec3::ONE };
        let colour = Color::LinearRgba(LinearRgba::rgb(
            colour.red * tint.x,
            colour.green * tint.y,
            colour.blue * tint.z,
        ));
        if let Ok(mut l) = lights.p0().get_mut(e) {
            (l.intensity, l.color) = (intensity * peak, colour);
        }
        if let Ok(mut l) = lights.p1().get_mut(e) {
            (l.intensity, l.color) = (intensity * peak, colour);
        }
        if let Ok(mut l) = lights.p2().get_mut(e) {
            (l.illuminance, l.color) = (intensity * peak, colour);
        }
    }
}

/// An RGB9E5 texel (the `VK_FORMAT_E5B9G9R9_UFLOAT_PACK32` layout: 9-bit
/// mantissas R, G, B from the low bits, a shared 5-bit exponent, bias 15)
/// as RGB.
pub fn rgb9e5_to_rgb(v: u32) -> Vec3 {
    let scale = 2f32.powi((v >> 27) as i32 - 15 - 9);
    Vec3::new(
        (v & 0x1ff) as f32,
        ((v >> 9) & 0x1ff) as f32,
        ((v >> 18) & 0x1ff) as f32,
    ) * scale
}

/// RGB as an RGB9E5 texel (the OpenGL `EXT_texture_shared_exponent`
/// encoding: the exponent from the largest channel, rounded, negative
/// values and NaN as 0).
pub fn rgb_to_rgb9e5(c: Vec3) -> u32 {
    const N: i32 = 9;
    const B: i32 = 15;
    let max = ((1 << N) - 1) as f32 / (1 << N) as f32 * 2f32.powi(31 - B);
    let clamp = |v: f32| if v > 0.0 { v.min(max) } else { 0.0 };
    let (r, g, b) = (clamp(c.x), clamp(c.y), clamp(c.z));
    let maxc = r.max(g).max(b);
    if maxc == 0.0 {
        return 0;
    }
    let mut exp = (-B - 1).max(maxc.log2().floor() as i32) + 1 + B;
    let scale = |e: i32| 2f32.powi(e - B - N);
    if (maxc / scale(exp) + 0.5).floor() as i32 == 1 << N {
        exp += 1;
    }
    let q = |v: f32| ((v / scale(exp) + 0.5).floor() as u32).min((1 << N) - 1);
    q(r) | q(g) << 9 | q(b) << 18 | (exp as u32) << 27
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The codec round-trips within RGB9E5's precision (2⁻⁹ of the largest
    /// channel).
    #[test]
    fn rgb9e5_round_trips() {
        for c in [
            Vec3::new(0.25, 0.5, 1.0),
            Vec3::new(1e-4, 3.0, 0.0),
            Vec3::new(123.0, 0.01, 7.5),
            Vec3::ZERO,
        ] {
            let back = rgb9e5_to_rgb(rgb_to_rgb9e5(c));
            assert!(
                (back - c).abs().max_element() <= c.max_element() / 512.0,
                "{c} → {back}"
            );
        }
        // White: exponent 16 (2⁻⁸ per mantissa step), mantissas 256.
        assert_eq!(
            rgb_to_rgb9e5(Vec3::ONE),
            256 | 256 << 9 | 256 << 18 | 16 << 27
        );
    }

    /// Unknown layers and bad weights are refused, with the reason.
    #[test]
    fn bad_weights_are_refused() {
        let layers = vec![Layer {
            name: "lamp".into(),
            lights: vec![],
            materials: vec![],
            pages: vec![],
            volumes: vec![],
        }];
        let ok = RadbakeLayers::default().with("lamp", Vec3::splat(2.0));
        assert!(check(&ok, &layers, None).is_ok());
        let unknown = RadbakeLayers::default().with("lantern", Vec3::ONE);
        assert!(check(&unknown, &layers, None)
            .unwrap_err()
            .contains("no layer `lantern`"));
        for bad in [
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::splat(f32::NAN),
            Vec3::splat(f32::INFINITY),
        ] {
            let w = RadbakeLayers::default().with("lamp", bad);
            assert!(check(&w, &layers, None)
                .unwrap_err()
                .contains("finite and ≥ 0"));
        }
        // The live layer is re-solved, not weighed.
        let live = RadbakeLayers::default().with("lamp", Vec3::ONE);
        assert!(check(&live, &layers, Some("lamp"))
            .unwrap_err()
            .contains("live sun's"));
    }
}
