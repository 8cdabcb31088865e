//! Load a radbake bake into Bevy 0.19: lightmaps, irradiance volumes and the
//! lights the bake contains, from the bake folder's `manifest.json`.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_radbake::{RadbakeBake, RadbakePlugin};
//!
//! fn setup(mut commands: Commands, assets: Res<AssetServer>) {
//!     // `bakes/cornell` is a `radbake bake --out` folder under `assets/`.
//!     commands.spawn(RadbakeBake::load(&assets, "bakes/cornell"));
//! }
//! # fn main() { App::new().add_plugins((DefaultPlugins, RadbakePlugin::default())).add_systems(Startup, setup); }
//! ```
//!
//! What the plugin does, once the manifest and the baked glTF are loaded:
//! - spawns the glTF's default scene under the [`RadbakeBake`] entity (unless
//!   the entity already has a [`WorldAssetRoot`]);
//! - once the scene is spawned, gives every mesh entity of every baked node
//!   instance a [`Lightmap`] with that instance's `uv_rect` (instances of one
//!   mesh have their own rectangles: the baked `.glb` gives each instance its
//!   own mesh copy, so the instance is found by its node's mesh handles, not
//!   by name);
//! - sets `lightmap_exposure` on their materials to
//!   [`RadbakePlugin::exposure`];
//! - spawns each probe grid as a [`LightProbe`] + [`IrradianceVolume`] with
//!   the grid's transform, `intensity` = the same factor and
//!   `affects_lightmapped_meshes: false`;
//! - keeps Bevy's `GlobalAmbientLight` off lightmapped meshes (the bake
//!   holds the sky);
//! - sets every light's colour to the glTF's numbers as linear RGB, as
//!   `KHR_lights_punctual` defines it (Bevy's glTF loader reads them as
//!   sRGB);
//! - in a light-layered bake, recombines the pages at a [`RadbakeLayers`]'
//!   weights ([`layers`]), and in a live bake re-solves the live sun's
//!   bounce light when its light turns ([`live`]);
//! - switches `affects_lightmapped_mesh_diffuse` off on the scene's baked
//!   lights (their diffuse light on lightmapped meshes is in the lightmap)
//!   and keeps it on for the lights radbake left to the engine (their
//!   node's `extras.radbake.mode`, which radbake writes: `indirect`, whose
//!   bounces only are in the bake, and `realtime`); every light's intensity
//!   is scaled by the same factor, so its specular and its light on dynamic
//!   objects stay in proportion to the bake.
//!
//! **Units and exposure.** A radbake texel is incident irradiance / π
//! (`L_out = albedo × lightmap + emission`), in the glTF's own units. Bevy
//! adds `lightmap × lightmap_exposure × diffuse` to the indirect light and
//! multiplies all lighting but emission by the camera's exposure,
//! `2^−ev100 / 1.2` (`bevy_pbr` `pbr_functions.wgsl`, `bevy_camera`
//! `Exposure::exposure`). The default factor, [`DEFAULT_EXPOSURE`] =
//! 1.2 × 2^9.7 ≈ 998, cancels the exposure of Bevy's default camera
//! (`Exposure::BLENDER`, ev100 9.7): a default Bevy camera shows the bake at
//! the brightness `radbake preview --exposure 0` shows, and glTF emission
//! (which Bevy does not expose by default) agrees with it. Each stop of
//! `ev100` below 9.7 is one stop of `radbake preview --exposure` above 0 for
//! the lightmapped and probe-lit light.

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext, RecursiveDependencyLoadState};
use bevy::gltf::{Gltf, GltfExtras, GltfMesh, GltfNode};
use bevy::light::{IrradianceVolume, LightProbe};
use bevy::pbr::Lightmap;
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use serde::Deserialize;

pub mod layers;
pub mod live;
pub use layers::{Layer, RadbakeLayers, RadbakeLayersApplied, RadbakeLayersError};
pub use live::RadbakeLiveApplied;

/// The factor that makes a default Bevy camera (`Exposure::BLENDER`, ev100
/// 9.7) show a radbake bake at the preview's EV 0: 1.2 × 2^9.7.
pub const DEFAULT_EXPOSURE: f32 = 998.0957;

/// Loads radbake bakes: register it once; it is also the resource its
/// systems read their settings from.
#[derive(Resource, Clone, Debug)]
pub struct RadbakePlugin {
    /// `StandardMaterial::lightmap_exposure` of lightmapped materials, the
    /// irradiance volumes' `intensity` and the factor on the scene's lights.
    pub exposure: f32,
    /// Spawn the bake's irradiance volumes (when it has probes).
    pub probes: bool,
}

impl Default for RadbakePlugin {
    fn default() -> Self {
        Self {
            exposure: DEFAULT_EXPOSURE,
            probes: true,
        }
    }
}

impl Plugin for RadbakePlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<RadbakeManifest>()
            .register_asset_loader(ManifestLoader)
            .insert_resource(self.clone())
            .add_systems(PostStartup, ambient_off_lightmapped)
            .add_systems(
                Update,
                (spawn_baked_scenes, apply_bakes, layers::recombine_layers).chain(),
            );
    }
}

/// Put this on an entity to load a bake: the entity gets the baked scene as
/// its child and the bake's lightmaps, probes and light settings.
#[derive(Component, Clone, Debug)]
pub struct RadbakeBake {
    pub manifest: Handle<RadbakeManifest>,
}

impl RadbakeBake {
    /// `folder`: the bake folder's asset path (the `--out` of `radbake
    /// bake`; `""` for the asset root itself); its `manifest.json` is
    /// loaded.
    pub fn load(assets: &AssetServer, folder: &str) -> Self {
        let folder = folder.trim_end_matches('/');
        let path = if folder.is_empty() || folder == "." {
            "manifest.json".to_string()
        } else {
            format!("{folder}/manifest.json")
        };
        Self {
            manifest: assets.load(path),
        }
    }
}

/// What the plugin did for one bake, on the [`RadbakeBake`] entity once it is
/// applied.
#[derive(Component, Clone, Debug, Default)]
pub struct RadbakeApplied {
    /// Mesh entities given a `Lightmap`.
    pub lightmapped: usize,
    /// Manifest instances whose mesh entities were not found in the scene.
    pub missing: Vec<String>,
    /// Irradiance volumes spawned.
    pub volumes: usize,
    /// Baked lights, switched off for lightmapped diffuse.
    pub lights: usize,
    /// Lights radbake left to the engine (modes `indirect` and `realtime`,
    /// from their glTF nodes' `extras.radbake.mode`): they keep lighting
    /// lightmapped meshes in real time.
    pub realtime_lights: usize,
}

/// On a [`RadbakeBake`] entity whose manifest, glTF or one of their files
/// failed to load: the error, also logged once.
#[derive(Component, Clone, Debug)]
pub struct RadbakeFailed(pub String);

/// `manifest.json` of a bake, with its files' handles.
#[derive(Asset, TypePath, Debug)]
pub struct RadbakeManifest {
    /// The baked glTF (`<stem>.baked.glb`).
    pub gltf: Handle<Gltf>,
    /// One lightmap image per page (`lightmap_<page>.ktx2`).
    pub pages: Vec<Handle<Image>>,
    /// The node instances, in the manifest's order.
    pub instances: Vec<Instance>,
    /// The probe grids as Bevy irradiance volumes.
    pub volumes: Vec<Volume>,
    /// The bake's light layers (empty for a bake without layers): what a
    /// [`RadbakeLayers`] weighs.
    pub layers: Vec<Layer>,
    /// A live bake's run-time data (`live.bin`, read at load): the live
    /// sun's bounce light is re-solved when its light turns ([`live`]).
    pub live: Option<std::sync::Arc<radbake_live::LiveData>>,
}

/// One baked node instance.
#[derive(Debug, Clone, Deserialize)]
pub struct Instance {
    pub node: String,
    pub node_index: usize,
    pub page: usize,
    /// (min.x, min.y, max.x, max.y) in [0, 1], min = top-left: Bevy's
    /// `Lightmap::uv_rect`.
    pub uv_rect: [f32; 4],
    /// False for a node baked without a lightmap (`extras.radbake.lightmap:
    /// false`): it gets no `Lightmap`, and Bevy lights it by the
    /// irradiance volume.
    #[serde(default = "yes")]
    pub lightmap: bool,
}

fn yes() -> bool {
    true
}

/// One probe grid, as a Bevy irradiance volume.
#[derive(Debug, Clone)]
pub struct Volume {
    pub voxels: Handle<Image>,
    /// Maps Bevy's unit cube [−½, ½]³ onto the grid's box.
    pub transform: Transform,
}

#[derive(Deserialize)]
struct ManifestFile {
    baked_gltf: Option<String>,
    pages: Vec<PageFile>,
    instances: Vec<Instance>,
    probes: Option<ProbesFile>,
    #[serde(default)]
    layers: Vec<LayerFile>,
    live: Option<LiveFile>,
}

#[derive(Deserialize)]
struct LiveFile {
    file: String,
}

#[derive(Deserialize)]
struct LayerFile {
    name: String,
    #[serde(default)]
    lights: Vec<String>,
    #[serde(default)]
    materials: Vec<String>,
    pages: Vec<PageFile>,
    probes: Option<LayerProbesFile>,
}

#[derive(Deserialize)]
struct LayerProbesFile {
    bevy_irradiance_volumes: Vec<String>,
}

#[derive(Deserialize)]
struct PageFile {
    ktx2: Option<String>,
}

#[derive(Deserialize)]
struct ProbesFile {
    volumes: Vec<VolumeFile>,
}

#[derive(Deserialize)]
struct VolumeFile {
    #[serde(default)]
    resolution: Option<[u32; 3]>,
    translation: [f32; 3],
    rotation_xyzw: [f32; 4],
    scale: [f32; 3],
    bevy_irradiance_volume: String,
}

/// Why a manifest could not be loaded.
#[derive(Debug)]
pub struct ManifestError(String);

impl std::fmt::Display for ManifestError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ManifestError {}

/// Reads `manifest.json` and starts loading the files it names, relative to
/// the manifest's folder.
#[derive(Default, TypePath)]
pub struct ManifestLoader;

impl AssetLoader for ManifestLoader {
    type Asset = RadbakeManifest;
    type Settings = ();
    type Error = ManifestError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<RadbakeManifest, ManifestError> {
        let path = load_context.path().clone();
        let fail = |what: String| ManifestError(format!("{path}: {what}"));
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(|e| fail(e.to_string()))?;
        let file: ManifestFile = serde_json::from_slice(&bytes)
            .map_err(|e| fail(format!("not a radbake manifest: {e}")))?;
        let relative = |name: &str| {
            path.resolve_embed_str(name)
                .map_err(|e| fail(format!("bad file name {name:?}: {e}")))
        };
        let gltf_name = file
            .baked_gltf
            .ok_or_else(|| fail("the bake has no baked glTF (baked_gltf is null)".into()))?;
        let gltf = load_context.load(relative(&gltf_name)?);
        let mut pages = Vec::with_capacity(file.pages.len());
        for (k, page) in file.pages.iter().enumerate() {
            let name = page.ktx2.as_deref().ok_or_else(|| {
                fail(format!(
                    "page {k} has no KTX2 file: bake with --ktx2 rgb9e5 (Bevy needs a filterable HDR image)"
                ))
            })?;
            pages.push(load_context.load(relative(name)?));
        }
        if let Some(i) = file.instances.iter().find(|i| i.page >= pages.len()) {
            return Err(fail(format!(
                "instance {} names page {} of {}",
                i.node,
                i.page,
                pages.len()
            )));
        }
        let mut volumes = Vec::new();
        let mut resolutions = Vec::new();
        for v in file.probes.map(|p| p.volumes).unwrap_or_default() {
            resolutions.push(v.resolution);
            volumes.push(Volume {
                voxels: load_context.load(relative(&v.bevy_irradiance_volume)?),
                transform: Transform {
                    translation: Vec3::from_array(v.translation),
                    rotation: Quat::from_array(v.rotation_xyzw),
                    scale: Vec3::from_array(v.scale),
                },
            });
        }
        let mut layers = Vec::with_capacity(file.layers.len());
        for l in file.layers {
            // The layers' images are read on the CPU only.
            let mut cpu = |name: &str| -> Result<Handle<Image>, ManifestError> {
                Ok(load_context
                    .load_builder()
                    .with_settings(|s: &mut bevy::image::ImageLoaderSettings| {
                        s.asset_usage = bevy::asset::RenderAssetUsages::MAIN_WORLD;
                    })
                    .load(relative(name)?))
            };
            let mut layer_pages = Vec::with_capacity(l.pages.len());
            for (k, page) in l.pages.iter().enumerate() {
                let name = page
                    .ktx2
                    .as_deref()
                    .ok_or_else(|| fail(format!("layer `{}` page {k} has no KTX2 file", l.name)))?;
                layer_pages.push(cpu(name)?);
            }
            let names = l
                .probes
                .map(|p| p.bevy_irradiance_volumes)
                .unwrap_or_default();
            if layer_pages.len() != pages.len() || names.len() != volumes.len() {
                return Err(fail(format!(
                    "layer `{}` has {} pages and {} volumes, the bake {} and {}",
                    l.name,
                    layer_pages.len(),
                    names.len(),
                    pages.len(),
                    volumes.len()
                )));
            }
            let layer_volumes = names.iter().map(|n| cpu(n)).collect::<Result<_, _>>()?;
            layers.push(Layer {
                name: l.name,
                lights: l.lights,
                materials: l.materials,
                pages: layer_pages,
                volumes: layer_volumes,
            });
        }
        let live = match file.live {
            Some(l) => {
                let at = relative(&l.file)?;
                let bytes = load_context
                    .read_asset_bytes(at.clone())
                    .await
                    .map_err(|e| fail(format!("cannot read {at}: {e}")))?;
                let data = radbake_live::LiveData::from_bytes(&bytes)
                    .map_err(|e| fail(format!("{at}: {e}")))?;
                let layer = &data.header.layer;
                if !layers.iter().any(|l| &l.name == layer) {
                    return Err(fail(format!(
                        "{at}: its layer `{layer}` is not among the bake's layers"
                    )));
                }
                if let Some(q) = &data.header.probes {
                    let same = q.grids.len() == resolutions.len()
                        && (q.grids.iter().zip(&resolutions))
                            .all(|(g, r)| r.is_none_or(|r| r == g.resolution));
                    if !same {
                        return Err(fail(format!(
                            "{at}: its probe grids are not the bake's irradiance volumes (probes.json)"
                        )));
                    }
                }
                Some(std::sync::Arc::new(data))
            }
            None => None,
        };
        Ok(RadbakeManifest {
            gltf,
            pages,
            instances: file.instances,
            volumes,
            layers,
            live,
        })
    }

    fn extensions(&self) -> &[&str] {
        &["json"]
    }
}

/// The bake holds the sky's light: Bevy's global ambient light (80 by
/// default) stays off lightmapped meshes.
fn ambient_off_lightmapped(ambient: Option<ResMut<GlobalAmbientLight>>) {
    if let Some(mut a) = ambient {
        a.affects_lightmapped_meshes = false;
    }
}

/// Gives a [`RadbakeBake`] entity its glTF scene once the manifest is
/// loaded, or [`RadbakeFailed`] if it or a file it names failed to load.
fn spawn_baked_scenes(
    mut commands: Commands,
    bakes: Waiting,
    server: Res<AssetServer>,
    manifests: Res<Assets<RadbakeManifest>>,
    gltfs: Res<Assets<Gltf>>,
) {
    for (entity, bake) in &bakes {
        if let RecursiveDependencyLoadState::Failed(e) =
            server.recursive_dependency_load_state(&bake.manifest)
        {
            error!("radbake: the bake could not be loaded: {e}");
            commands.entity(entity).insert(RadbakeFailed(e.to_string()));
            continue;
        }
        let Some(gltf) = manifests
            .get(&bake.manifest)
            .and_then(|m| gltfs.get(&m.gltf))
        else {
            continue;
        };
        let Some(scene) = gltf
            .default_scene
            .clone()
            .or_else(|| gltf.scenes.first().cloned())
        else {
            warn!("radbake: the baked glTF has no scene");
            continue;
        };
        commands.entity(entity).insert(WorldAssetRoot(scene));
    }
}

/// Bakes waiting for their scene.
type Waiting<'w, 's> = Query<
    'w,
    's,
    (Entity, &'static RadbakeBake),
    (
        Without<WorldAssetRoot>,
        Without<RadbakeApplied>,
        Without<RadbakeFailed>,
    ),
>;
/// Bakes whose scene is spawned or spawning, not yet applied.
type Spawned<'w, 's> =
    Query<'w, 's, (Entity, &'static RadbakeBake), (With<WorldAssetRoot>, Without<RadbakeApplied>)>;
/// Everything [`apply_bakes`] reads from the world.
type MeshEntities<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static Mesh3d,
        Option<&'static MeshMaterial3d<StandardMaterial>>,
    ),
>;

/// Once a bake's scene is spawned: lightmaps, material exposure, volumes and
/// lights (see the crate's doc).
#[allow(clippy::too_many_arguments)]
fn apply_bakes(
    mut commands: Commands,
    settings: Res<RadbakePlugin>,
    bakes: Spawned,
    children: Query<&Children>,
    meshes: MeshEntities,
    mut lights: ParamSet<(
        Query<&mut PointLight>,
        Query<&mut SpotLight>,
        Query<&mut DirectionalLight>,
    )>,
    parents: Query<&ChildOf>,
    extras: Query<&GltfExtras>,
    manifests: Res<Assets<RadbakeManifest>>,
    gltfs: Res<Assets<Gltf>>,
    gltf_nodes: Res<Assets<GltfNode>>,
    gltf_meshes: Res<Assets<GltfMesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for (root, bake) in &bakes {
        let Some(manifest) = manifests.get(&bake.manifest) else {
            continue;
        };
        let Some(gltf) = gltfs.get(&manifest.gltf) else {
            continue;
        };
        let descendants: Vec<Entity> = children.iter_descendants(root).collect();
        let by_mesh: HashMap<AssetId<Mesh>, Vec<Entity>> = descendants
            .iter()
            .filter_map(|&e| meshes.get(e).ok())
            .fold(HashMap::default(), |mut map, (e, mesh, _)| {
                map.entry(mesh.id()).or_default().push(e);
                map
            });
        if by_mesh.is_empty() {
            continue; // the scene is not spawned yet
        }
        let mut applied = RadbakeApplied::default();
        let mut exposed = HashSet::new();
        for inst in manifest.instances.iter().filter(|i| i.lightmap) {
            let handles = instance_meshes(gltf, &gltf_nodes, &gltf_meshes, inst.node_index);
            let entities: Vec<Entity> = handles
                .iter()
                .flat_map(|h| by_mesh.get(h).into_iter().flatten().copied())
                .collect();
            if entities.is_empty() {
                applied.missing.push(inst.node.clone());
                continue;
            }
            let [x0, y0, x1, y1] = inst.uv_rect;
            for e in entities {
                commands.entity(e).insert(Lightmap {
                    image: manifest.pages[inst.page].clone(),
                    uv_rect: Rect::new(x0, y0, x1, y1),
                    bicubic_sampling: false,
                });
                applied.lightmapped += 1;
                if let Ok((_, _, Some(mat))) = meshes.get(e) {
                    if exposed.insert(mat.id()) {
                        if let Some(mut m) = materials.get_mut(&mat.0) {
                            m.lightmap_exposure = settings.exposure;
                        }
                    }
                }
            }
        }
        if settings.probes {
            for v in &manifest.volumes {
                let volume = commands
                    .spawn((
                        v.transform,
                        LightProbe {
                            falloff: Vec3::ZERO,
                        },
                        IrradianceVolume {
                            voxels: v.voxels.clone(),
                            intensity: settings.exposure,
                            affects_lightmapped_meshes: false,
                        },
                    ))
                    .id();
                commands.entity(root).add_child(volume);
                applied.volumes += 1;
            }
        }
        let realtime = |e: Entity| light_mode(e, &parents, &extras).is_some_and(|m| m != "baked");
        (applied.lights, applied.realtime_lights) =
            baked_lights(&descendants, &mut lights, settings.exposure, &realtime);
        if !applied.missing.is_empty() {
            warn!(
                "radbake: {} baked instances not found in the scene: {:?}",
                applied.missing.len(),
                applied.missing
            );
        }
        info!(
            "radbake: {} lightmapped meshes, {} irradiance volumes, {} baked lights, {} real-time lights",
            applied.lightmapped, applied.volumes, applied.lights, applied.realtime_lights
        );
        commands.entity(root).insert(applied);
    }
}

/// The `Mesh` assets of glTF node `index`'s primitives.
fn instance_meshes(
    gltf: &Gltf,
    nodes: &Assets<GltfNode>,
    meshes: &Assets<GltfMesh>,
    index: usize,
) -> Vec<AssetId<Mesh>> {
    gltf.nodes
        .get(index)
        .and_then(|h| nodes.get(h))
        .and_then(|n| n.mesh.as_ref())
        .and_then(|m| meshes.get(m))
        .map(|m| m.primitives.iter().map(|p| p.mesh.id()).collect())
        .unwrap_or_default()
}

/// The bake mode radbake wrote on a light's glTF node: Bevy's glTF loader
/// spawns the light as a child of its node's entity, which carries the
/// node's extras (`{"radbake": {"mode": …}}`). `None` where there is none.
fn light_mode(
    light: Entity,
    parents: &Query<&ChildOf>,
    extras: &Query<&GltfExtras>,
) -> Option<String> {
    let node = parents.get(light).ok()?.parent();
    let value: serde_json::Value = serde_json::from_str(&extras.get(node).ok()?.value).ok()?;
    value["radbake"]["mode"].as_str().map(str::to_owned)
}

/// The scene's lights: each one's intensity is scaled by `exposure` (see
/// the crate's doc); a baked one's diffuse light on lightmapped meshes is
/// switched off (it is in the lightmap), a `realtime(e)` one's kept.
/// Returns how many lights of each.
fn baked_lights(
    entities: &[Entity],
    lights: &mut ParamSet<(
        Query<&mut PointLight>,
        Query<&mut SpotLight>,
        Query<&mut DirectionalLight>,
    )>,
    exposure: f32,
    realtime: &dyn Fn(Entity) -> bool,
) -> (usize, usize) {
    let (mut baked, mut live) = (0, 0);
    for &e in entities {
        let engine = realtime(e);
        let mut found = false;
        if let Ok(mut l) = lights.p0().get_mut(e) {
            l.affects_lightmapped_mesh_diffuse = engine;
            l.intensity *= exposure;
            l.color = gltf_light_colour(l.color);
            found = true;
        }
        if let Ok(mut l) = lights.p1().get_mut(e) {
            l.affects_lightmapped_mesh_diffuse = engine;
            l.intensity *= exposure;
            l.color = gltf_light_colour(l.color);
            found = true;
        }
        if let Ok(mut l) = lights.p2().get_mut(e) {
            l.affects_lightmapped_mesh_diffuse = engine;
            l.illuminance *= exposure;
            l.color = gltf_light_colour(l.color);
            found = true;
        }
        match (found, engine) {
            (true, false) => baked += 1,
            (true, true) => live += 1,
            _ => {}
        }
    }
    (baked, live)
}

/// A glTF light's colour as `KHR_lights_punctual` defines it: linear RGB.
/// Bevy 0.19's glTF loader reads it as sRGB (`Color::srgb_from_array`,
/// `bevy_gltf` `loader/mod.rs`), which darkens and tints a coloured light
/// against the bake; its sRGB components are the glTF's numbers.
fn gltf_light_colour(c: Color) -> Color {
    let s = c.to_srgba();
    Color::linear_rgb(s.red, s.green, s.blue)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The factor cancels the exposure of Bevy's default camera exactly.
    #[test]
    fn default_exposure_cancels_bevys_default_camera() {
        let camera = bevy::camera::Exposure::default();
        assert_eq!(camera.ev100, bevy::camera::Exposure::EV100_BLENDER);
        assert!((DEFAULT_EXPOSURE * camera.exposure() - 1.0).abs() < 1e-6);
    }
}
