//! What the preview draws, built on the CPU from a baked `.glb`: world-space
//! triangles grouped by material, the materials' GPU parameters, the
//! lightmap pages, and the bake's light probes with a sphere per probe.
//!
//! **How lightmaps are loaded.** Only the `.glb` is read (no `manifest.json`
//! or EXR is needed, so a baked `.glb` can be previewed anywhere):
//! [`crate::scene::load`] gives the meshes with `TEXCOORD_1` (`Mesh::uv1`)
//! and the materials, and each glTF material's `MOZ_lightmap` extension is
//! parsed from the document's JSON ([`crate::scene::SourceDocument`]): its
//! `index` names the page's texture (an sRGB PNG embedded in the `.glb`), its
//! `KHR_texture_transform` the instance's atlas rectangle (atlas UV =
//! offset + scale × `TEXCOORD_1`), and its `intensity` k gives the linear
//! value `srgb_to_linear(png) × k / π` (incident irradiance / π).
//!
//! **How probes are loaded.** `probes.json` (and the `probes.bin` it names)
//! in the `.glb`'s folder, read by [`Probes::read`]; none there is not an
//! error (the preview warns where it matters), a malformed one is.
//! Instances (`Scene::instances`) are lightmapped; dynamic nodes
//! (`Scene::dynamic`, glTF `extras.radbake.dynamic`) have no lightmap and
//! carry, per vertex, irradiance / π interpolated from the probes at the
//! vertex's world position and normal ([`probe_light::vertex_light`],
//! evaluated per vertex, not per pixel), or black without probes.

use super::gpu::{self, Vertex};
use super::probe_light;
use crate::probes::Probes;
use crate::scene::{Alpha, Scene, TextureRef};
use anyhow::{anyhow, bail, Context as _, Result};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A material's `MOZ_lightmap`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightmapRef {
    /// Index into [`Model::lightmaps`].
    pub page: usize,
    /// `MOZ_lightmap.intensity` (π × the page's PNG scale).
    pub intensity: f32,
    /// `KHR_texture_transform.offset` (the instance's `uv_rect` min).
    pub offset: Vec2,
    /// `KHR_texture_transform.scale` (`uv_rect` max − min).
    pub scale: Vec2,
}

/// An RGBA8 image whose RGB is sRGB-encoded.
#[derive(Clone, Debug)]
pub struct Image {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGBA8.
    pub rgba: Vec<u8>,
}

/// A lightmap page in linear floats, irradiance / π per texel: a
/// light-layered bake's page recombined at the preview's layer weights
/// ([`Model::load_weighted`]).
#[derive(Clone, Debug)]
pub struct LinearPage {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGB.
    pub rgb: Vec<Vec3>,
}

/// A range of [`Model::vertices`] drawn with one material.
#[derive(Clone, Debug)]
pub struct Batch {
    /// Index into [`Model::materials`].
    pub material: usize,
    /// Vertex range.
    pub vertices: std::ops::Range<u32>,
    /// For a blended (glTF `BLEND`) material, the batch is one three.js
    /// object (one glTF primitive of one node) and this is the world
    /// position three.js sorts it by: the centre of its bounding box (the
    /// centre of `BufferGeometry.computeBoundingSphere`), placed by the
    /// node's transform. None for opaque and masked materials, whose
    /// batches hold all their triangles.
    pub origin: Option<Vec3>,
}

/// A material as the preview draws it.
#[derive(Clone, Debug)]
pub struct PreviewMaterial {
    /// GPU parameters.
    pub gpu: gpu::Material,
    /// Base colour texture (index into [`Scene::textures`]).
    pub base_texture: Option<u32>,
    /// Emissive texture (index into [`Scene::textures`]).
    pub emissive_texture: Option<u32>,
    /// Lightmap page (index into [`Model::lightmaps`]).
    pub lightmap: Option<usize>,
    /// Drawn without back-face culling.
    pub double_sided: bool,
    /// glTF `BLEND`: alpha blended after the opaque batches, back to front,
    /// without writing depth (three.js `transparent`, `depthWrite: false`).
    pub blend: bool,
}

/// Everything the renderer uploads.
pub struct Model {
    /// The imported scene (textures, cameras).
    pub scene: Scene,
    /// Non-indexed world-space triangles of the instances (lightmapped) and
    /// the dynamic nodes (probe-lit), sorted by material.
    pub vertices: Vec<Vertex>,
    /// Draw ranges: one per opaque or masked material used, then one per
    /// object (node × primitive) of each blended material.
    pub batches: Vec<Batch>,
    /// Materials, parallel to [`Scene::materials`], then (with probes) the
    /// probe spheres' white one.
    pub materials: Vec<PreviewMaterial>,
    /// Lightmap pages (sRGB RGBA8).
    pub lightmaps: Vec<Image>,
    /// Per page, the page at the preview's layer weights where they were
    /// given ([`Model::load_weighted`]; drawn in place of
    /// [`Model::lightmaps`], the materials' lightmap scale 1); empty
    /// otherwise.
    pub linear_pages: Vec<Option<LinearPage>>,
    /// Per page, the bake's `lightmap_<page>_debug.png` beside the `.glb`
    /// when it was written (`radbake bake --debug-maps`).
    pub debug_maps: Vec<Option<Image>>,
    /// Per page, its shadowmask (linear RGBA8) where the `.glb` has one
    /// (see [`parse_shadowmasks`]).
    pub shadowmasks: Vec<Option<Image>>,
    /// Per scene light ([`Scene::lights`]), its shadowmask channel (0–3).
    pub light_channels: Vec<Option<u8>>,
    /// World bounds of all vertices (min, max; the probe spheres not included).
    pub bounds: (Vec3, Vec3),
    /// The bake's light probes (`probes.json` beside the `.glb`), if found.
    pub probes: Option<Probes>,
    /// With probes: the index in [`Model::materials`] of the probe spheres'
    /// material (the spheres themselves, [`probe_light::spheres`], are
    /// built by the renderer the first time the probes view is shown).
    pub probe_material: Option<usize>,
    /// The level's signed distance field (the bake's `sdf.ktx2`, found
    /// through `manifest.json` beside the `.glb`), if any.
    pub field: Option<super::field::Field>,
}

/// `MOZ_lightmap` of every glTF material (None where absent), and the glTF
/// texture indices they reference, in page order.
pub fn parse_moz_lightmaps(
    json: &serde_json::Value,
) -> Result<(Vec<Option<LightmapRef>>, Vec<usize>)> {
    let mut pages: Vec<usize> = Vec::new();
    let mut out = Vec::new();
    let empty = Vec::new();
    let materials = json["materials"].as_array().unwrap_or(&empty);
    for (i, m) in materials.iter().enumerate() {
        let Some(lm) = m.pointer("/extensions/MOZ_lightmap") else {
            out.push(None);
            continue;
        };
        let texture = lm["index"]
            .as_u64()
            .ok_or_else(|| anyhow!("materials[{i}].extensions.MOZ_lightmap: no texture index"))?
            as usize;
        let intensity = lm["intensity"].as_f64().unwrap_or(1.0) as f32;
        let t = lm.pointer("/extensions/KHR_texture_transform");
        let vec2 = |key: &str, default: Vec2| -> Vec2 {
            t.and_then(|t| t[key].as_array())
                .and_then(|a| {
                    Some(Vec2::new(
                        a.first()?.as_f64()? as f32,
                        a.get(1)?.as_f64()? as f32,
                    ))
                })
                .unwrap_or(default)
        };
        let page = match pages.iter().position(|&p| p == texture) {
            Some(p) => p,
            None => {
                pages.push(texture);
                pages.len() - 1
            }
        };
        out.push(Some(LightmapRef {
            page,
            intensity,
            offset: vec2("offset", Vec2::ZERO),
            scale: vec2("scale", Vec2::ONE),
        }));
    }
    Ok((out, pages))
}

/// The shadowmask of a baked `.glb` (see `output::baked`): per lightmap
/// page (`pages`, glTF texture indices), the texture that its materials'
/// `extras.radbake.shadowmask.index` names, and per glTF node index the
/// channel (0–3 for r, g, b, a) that their `channels` give its light.
pub fn parse_shadowmasks(
    json: &serde_json::Value,
    moz: &[Option<LightmapRef>],
    pages: usize,
) -> (Vec<Option<usize>>, std::collections::BTreeMap<usize, u8>) {
    let mut textures = vec![None; pages];
    let mut channels = std::collections::BTreeMap::new();
    let empty = Vec::new();
    let materials = json["materials"].as_array().unwrap_or(&empty);
    for (m, lm) in materials.iter().zip(moz) {
        let (Some(lm), Some(sm)) = (lm, m.pointer("/extras/radbake/shadowmask")) else {
            continue;
        };
        if let Some(t) = sm["index"].as_u64() {
            textures[lm.page] = Some(t as usize);
        }
        for (c, name) in crate::maps::shadowmask::CHANNEL_NAMES.iter().enumerate() {
            for node in sm["channels"][name].as_array().into_iter().flatten() {
                if let Some(n) = node.as_u64() {
                    channels.insert(n as usize, c as u8);
                }
            }
        }
    }
    (textures, channels)
}

/// Decodes glTF texture `texture`'s image from the loaded document.
fn decode_texture(scene: &Scene, texture: usize) -> Result<Image> {
    let src = scene
        .source
        .as_ref()
        .ok_or_else(|| anyhow!("the scene has no source document"))?;
    let image = src.json["textures"][texture]["source"]
        .as_u64()
        .ok_or_else(|| anyhow!("textures[{texture}] has no image source"))?
        as usize;
    let (bytes, _) = src
        .images
        .get(image)
        .and_then(Option::as_ref)
        .ok_or_else(|| anyhow!("images[{image}] was not loaded"))?;
    let img = image::load_from_memory(bytes)
        .with_context(|| format!("cannot decode lightmap images[{image}]"))?
        .to_rgba8();
    Ok(Image {
        width: img.width(),
        height: img.height(),
        rgba: img.into_raw(),
    })
}

/// The 2×3 matrix rows of `KHR_texture_transform` (see [`TextureRef::transform_uv`]).
fn uv_rows(t: Option<&TextureRef>) -> ([f32; 4], [f32; 4]) {
    match t {
        Some(t) => {
            let (sin, cos) = t.rotation.sin_cos();
            (
                [cos * t.scale.x, sin * t.scale.y, t.offset.x, 0.0],
                [-sin * t.scale.x, cos * t.scale.y, t.offset.y, 0.0],
            )
        }
        None => ([1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]),
    }
}

/// For each triangle of a mesh, the mask of its edges that lie on a chart
/// border: edges not shared, with the same positions *and* the same
/// `TEXCOORD_1` at both ends, by another triangle of the mesh (so UV seams
/// and open boundaries both count).
pub fn chart_border_edges(positions: &[Vec3], uv1: &[Vec2], triangles: &[[u32; 3]]) -> Vec<u8> {
    type Key = ([u32; 5], [u32; 5]);
    let corner = |v: u32| -> [u32; 5] {
        let p = positions[v as usize];
        let u = uv1[v as usize];
        [p.x, p.y, p.z, u.x, u.y].map(|f| (f + 0.0).to_bits())
    };
    let key = |a: u32, b: u32| -> Key {
        let (ka, kb) = (corner(a), corner(b));
        if ka <= kb {
            (ka, kb)
        } else {
            (kb, ka)
        }
    };
    let mut count: HashMap<Key, u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *count.entry(key(t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    triangles
        .iter()
        .map(|t| {
            (0..3).fold(0u8, |mask, k| {
                if count[&key(t[k], t[(k + 1) % 3])] == 1 {
                    mask | (1 << k)
                } else {
                    mask
                }
            })
        })
        .collect()
}

/// A material's preview parameters; `lm` is its `MOZ_lightmap`, if any.
fn preview_material(m: &crate::scene::Material, lm: Option<LightmapRef>) -> PreviewMaterial {
    let (base_uv0, base_uv1) = uv_rows(m.albedo_texture.as_ref());
    let (emissive_uv0, emissive_uv1) = uv_rows(m.emission_texture.as_ref());
    let mut flags = 0;
    if m.albedo_texture.is_some() {
        flags |= gpu::FLAG_BASE_TEXTURE;
    }
    if m.emission_texture.is_some() {
        flags |= gpu::FLAG_EMISSIVE_TEXTURE;
    }
    if lm.is_some() {
        flags |= gpu::FLAG_LIGHTMAP;
    }
    if m.blend {
        flags |= gpu::FLAG_BLEND;
    }
    // three.js reads a texture with `channel` 1 through TEXCOORD_1 (in a
    // baked .glb, the lightmap UV); sets above 1 are read through
    // TEXCOORD_0 here (the preview carries no third set).
    if m.albedo_texture.as_ref().is_some_and(|t| t.tex_coord == 1) {
        flags |= gpu::FLAG_BASE_UV1;
    }
    if m.emission_texture
        .as_ref()
        .is_some_and(|t| t.tex_coord == 1)
    {
        flags |= gpu::FLAG_EMISSIVE_UV1;
    }
    let lm_rect = lm.map_or([0.0, 0.0, 1.0, 1.0], |l| {
        [l.offset.x, l.offset.y, l.scale.x, l.scale.y]
    });
    PreviewMaterial {
        gpu: gpu::Material {
            base_color: [m.albedo.x, m.albedo.y, m.albedo.z, m.alpha_factor],
            emissive: [m.emission.x, m.emission.y, m.emission.z, 0.0],
            base_uv0,
            base_uv1,
            emissive_uv0,
            emissive_uv1,
            lightmap_rect: lm_rect,
            lightmap_scale: lm.map_or(0.0, |l| l.intensity / std::f32::consts::PI),
            flags,
            // three.js sets alphaTest for MASK only; BLEND blends uncut.
            alpha_cutoff: match m.alpha {
                Alpha::Mask { cutoff } if !m.blend => cutoff,
                _ => -1.0,
            },
            _pad: 0.0,
        },
        base_texture: m.albedo_texture.as_ref().map(|t| t.texture),
        emissive_texture: m.emission_texture.as_ref().map(|t| t.texture),
        lightmap: lm.map(|l| l.page),
        double_sided: m.double_sided,
        blend: m.blend,
    }
}

/// The probe spheres' material: white, opaque, no texture, no lightmap.
fn sphere_material() -> PreviewMaterial {
    let (uv0, uv1) = uv_rows(None);
    PreviewMaterial {
        gpu: gpu::Material {
            base_color: [1.0; 4],
            emissive: [0.0; 4],
            base_uv0: uv0,
            base_uv1: uv1,
            emissive_uv0: uv0,
            emissive_uv1: uv1,
            lightmap_rect: [0.0, 0.0, 1.0, 1.0],
            lightmap_scale: 0.0,
            flags: 0,
            alpha_cutoff: -1.0,
            _pad: 0.0,
        },
        base_texture: None,
        emissive_texture: None,
        lightmap: None,
        double_sided: false,
        blend: false,
    }
}

/// How an instance's vertices are lit.
#[derive(Clone, Copy)]
enum Light<'a> {
    /// By its materials' lightmaps (chart borders per source triangle).
    Lightmap(&'a [u8]),
    /// By the probes, evaluated per vertex (a dynamic node; black without probes).
    Probes(Option<&'a Probes>),
}

/// Triangles gathered for the draw batches: per material for opaque and
/// masked materials, per object (node × glTF primitive) for blended ones.
#[derive(Default)]
struct Gathered {
    per_material: Vec<Vec<Vertex>>,
    /// (material, world origin, triangles) per blended object, in order.
    blended: Vec<(usize, Vec3, Vec<Vertex>)>,
}

/// Appends `inst`'s triangles, in world space, to `out`; `blend[m]`:
/// material m is blended.
fn push_instance(
    out: &mut Gathered,
    scene: &Scene,
    inst: &crate::scene::Instance,
    light: Light,
    blend: &[bool],
) {
    let mesh = &scene.meshes[inst.mesh as usize];
    let m = inst.world_from_local;
    let nm = inst.normal_matrix();
    let corners = if inst.mirrors() { [0, 2, 1] } else { [0, 1, 2] };
    // Blended triangles by glTF primitive: (material, local bounds, vertices).
    let mut objects: std::collections::BTreeMap<u32, (usize, Vec3, Vec3, Vec<Vertex>)> =
        Default::default();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let mat = mesh.triangle_material[t] as usize;
        let edges = match light {
            Light::Lightmap(borders) => borders[t] as u32,
            Light::Probes(_) => 0,
        };
        let target = if blend[mat] {
            let o = objects
                .entry(mesh.triangle_primitive[t])
                .or_insert_with(|| (mat, Vec3::INFINITY, Vec3::NEG_INFINITY, Vec::new()));
            for &v in tri {
                let p = mesh.positions[v as usize];
                (o.1, o.2) = (o.1.min(p), o.2.max(p));
            }
            &mut o.3
        } else {
            &mut out.per_material[mat]
        };
        // The corner index stays the source triangle's, so the edge mask
        // holds whatever the drawing order.
        for c in corners {
            let v = tri[c] as usize;
            let p = m.transform_point3(mesh.positions[v]);
            let n = (nm * mesh.normals[v]).normalize_or_zero();
            target.push(Vertex {
                position: p.to_array(),
                normal: n.to_array(),
                uv0: mesh.uv0[v].to_array(),
                uv1: mesh.uv1.as_ref().map_or([0.0; 2], |u| u[v].to_array()),
                corner_edges: c as u32 | (edges << 2),
                probe: match light {
                    Light::Lightmap(_) => [0.0, 0.0, 0.0, gpu::PROBE_NONE],
                    Light::Probes(probes) => probe_light::vertex_light(probes, p, n),
                },
                color: mesh.colors.as_ref().map_or([1.0; 4], |c| c[v].to_array()),
            });
        }
    }
    for (_, (mat, lo, hi, vertices)) in objects {
        let origin = m.transform_point3(0.5 * (lo + hi));
        out.blended.push((mat, origin, vertices));
    }
}

/// Points the scene's light `name` towards `towards` with `irradiance`
/// (the preview draws it in real time); false where there is none.
pub fn place_sun(
    scene: &mut crate::scene::Scene,
    name: &str,
    towards: Vec3,
    irradiance: Vec3,
) -> bool {
    match scene.lights.iter_mut().find(|l| l.name == name) {
        Some(l) => {
            l.direction = -towards.normalize();
            l.intensity = irradiance;
            true
        }
        None => false,
    }
}

/// The recombined `pages` of a layered bake as the preview's pages, each
/// checked against the size of the `.glb`'s page it replaces.
fn linear_pages(
    pages: &[crate::maps::lightmap::Lightmaps],
    glb: &[Image],
) -> Result<Vec<Option<LinearPage>>> {
    if pages.len() != glb.len() {
        bail!(
            "the bake's manifest.json lists {} lightmap pages, its .glb has {}",
            pages.len(),
            glb.len()
        );
    }
    (pages.iter().zip(glb).enumerate())
        .map(|(p, (lm, img))| {
            if (lm.width, lm.height) != (img.width, img.height) {
                bail!(
                    "lightmap page {p}: the layers' pages are {} × {}, the .glb's {} × {}",
                    lm.width,
                    lm.height,
                    img.width,
                    img.height
                );
            }
            Ok(Some(LinearPage {
                width: lm.width,
                height: lm.height,
                rgb: lm.pages[0].clone(),
            }))
        })
        .collect()
}

/// Where `Model::load` looks for a baked `.glb`'s probes: `probes.json` in
/// its folder.
pub fn probes_path(glb: &Path) -> PathBuf {
    glb.with_file_name("probes.json")
}

impl Model {
    /// Loads a baked `.glb` (or any glTF; surfaces without `MOZ_lightmap`
    /// get no lightmap), and the probes beside it (`probes.json`, see
    /// [`probes_path`]) when there are any.
    ///
    /// # Errors
    /// The scene cannot be imported, a lightmap page cannot be decoded, or
    /// `probes.json` exists but cannot be read (a one-line message naming
    /// the file).
    pub fn load(path: &Path) -> Result<Model> {
        Self::load_weighted(path, &[])
    }

    /// [`Model::load`], with a light-layered bake's layers at `weights`
    /// (`radbake preview --layer NAME=R,G,B`; layers not named keep 1):
    /// its pages and probes the layers' weighted sum
    /// ([`crate::output::combine::recombined`], read through the
    /// `manifest.json` beside the `.glb`). No weights: the `.glb`'s pages.
    ///
    /// # Errors
    /// As [`Model::load`]'s; and a weight naming no layer, a bake without
    /// layers, or a layer page whose size is not the `.glb`'s page's.
    pub fn load_weighted(path: &Path, weights: &[(String, Vec3)]) -> Result<Model> {
        Self::load_relit(path, weights, None)
    }

    /// [`Model::load_weighted`], and with `sun` a live bake relit for it
    /// (`radbake preview --sun-direction`): the pages and probes
    /// [`crate::output::relight::relit`] gives, the layers at `weights`.
    ///
    /// # Errors
    /// As [`Model::load_weighted`]'s, and [`crate::output::relight::relit`]'s
    /// (a bake without live lights, a bad `live.bin`, a bad sun).
    pub fn load_relit(
        path: &Path,
        weights: &[(String, Vec3)],
        sun: Option<&crate::output::relight::Relight>,
    ) -> Result<Model> {
        let scene = crate::scene::load(path, &Default::default())
            .with_context(|| format!("cannot load {}", path.display()))?;
        let (moz, pages) = match &scene.source {
            Some(src) => parse_moz_lightmaps(&src.json)?,
            None => (Vec::new(), Vec::new()),
        };
        let lightmaps = pages
            .iter()
            .map(|&t| decode_texture(&scene, t))
            .collect::<Result<Vec<_>>>()?;
        // Debug maps are named after the page's texture (`lightmap_<page>`).
        let debug_maps = pages
            .iter()
            .map(|&t| {
                let name = scene.source.as_ref()?.json["textures"][t]["name"].as_str()?;
                let file = path.parent()?.join(format!("{name}_debug.png"));
                let img = image::open(&file).ok()?.to_rgba8();
                Some(Image {
                    width: img.width(),
                    height: img.height(),
                    rgba: img.into_raw(),
                })
            })
            .collect();
        let probes_json = probes_path(path);
        let mut probes = if probes_json.exists() {
            Some(Probes::read(&probes_json)?)
        } else {
            None
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        // The live light's new direction and irradiance, where relit.
        let mut relit_sun = None;
        let linear_pages = match sun {
            Some(sun) => {
                let sun = crate::output::relight::Relight {
                    weights: weights.to_vec(),
                    ..sun.clone()
                };
                let (pages, relit, solve) = crate::output::relight::relit(dir, &sun)?;
                probes = relit.or(probes);
                relit_sun = Some((solve.light, sun.sun_direction, solve.irradiance));
                linear_pages(&pages, &lightmaps)?
            }
            None if weights.is_empty() => Vec::new(),
            None => {
                let (pages, weighted) = crate::output::combine::recombined(dir, weights)?;
                probes = weighted.or(probes);
                linear_pages(&pages, &lightmaps)?
            }
        };
        let (mask_textures, channels) = match &scene.source {
            Some(src) => parse_shadowmasks(&src.json, &moz, pages.len()),
            None => Default::default(),
        };
        let shadowmasks = mask_textures
            .iter()
            .map(|t| t.map(|t| decode_texture(&scene, t)).transpose())
            .collect::<Result<Vec<_>>>()?;
        let light_channels = scene
            .lights
            .iter()
            .map(|l| channels.get(&l.node_index).copied())
            .collect();
        let mut scene = scene;
        if let Some((name, towards, irradiance)) = relit_sun {
            place_sun(&mut scene, &name, towards, irradiance);
        }
        let mut model = Self::build(scene, &moz, lightmaps, probes);
        for m in &mut model.materials {
            if m.lightmap
                .is_some_and(|p| matches!(linear_pages.get(p), Some(Some(_))))
            {
                m.gpu.lightmap_scale = 1.0;
            }
        }
        model.linear_pages = linear_pages;
        model.debug_maps = debug_maps;
        model.shadowmasks = shadowmasks;
        model.light_channels = light_channels;
        model.field = super::field::find(path)?;
        Ok(model)
    }

    /// Builds the model from an imported scene, its materials' lightmaps
    /// (`moz[m]` for glTF material m) and the bake's probes: the instances
    /// are lightmapped, the dynamic nodes lit by the probes per vertex
    /// ([`probe_light::vertex_light`]), and with probes the spheres' white
    /// material is added.
    pub fn build(
        scene: Scene,
        moz: &[Option<LightmapRef>],
        lightmaps: Vec<Image>,
        probes: Option<Probes>,
    ) -> Model {
        let mut materials: Vec<PreviewMaterial> = scene
            .materials
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let lm = moz.get(i).copied().flatten();
                preview_material(m, lm.filter(|l| l.page < lightmaps.len()))
            })
            .collect();
        // Chart borders once per mesh.
        let borders: Vec<Vec<u8>> = scene
            .meshes
            .iter()
            .map(|mesh| match &mesh.uv1 {
                Some(uv1) => chart_border_edges(&mesh.positions, uv1, &mesh.triangles),
                None => vec![0; mesh.triangles.len()],
            })
            .collect();
        // Triangles per material (per object where blended), then concatenated.
        let blend: Vec<bool> = materials.iter().map(|m| m.blend).collect();
        let mut gathered = Gathered {
            per_material: vec![Vec::new(); materials.len()],
            blended: Vec::new(),
        };
        for inst in &scene.instances {
            // A node without a lightmap (`extras.radbake.lightmap: false`)
            // is lit by the probes, as a dynamic one.
            let light = if inst.lightmap {
                Light::Lightmap(&borders[inst.mesh as usize])
            } else {
                Light::Probes(probes.as_ref())
            };
            push_instance(&mut gathered, &scene, inst, light, &blend);
        }
        for inst in &scene.dynamic {
            let light = Light::Probes(probes.as_ref());
            push_instance(&mut gathered, &scene, inst, light, &blend);
        }
        let mut vertices = Vec::new();
        let mut batches = Vec::new();
        let groups = gathered.per_material.into_iter().enumerate();
        let opaque = groups.map(|(material, vs)| (material, None, vs));
        let blended = gathered
            .blended
            .into_iter()
            .map(|(m, o, vs)| (m, Some(o), vs));
        for (material, origin, vs) in opaque.chain(blended) {
            if vs.is_empty() {
                continue;
            }
            let start = vertices.len() as u32;
            vertices.extend(vs);
            batches.push(Batch {
                material,
                vertices: start..vertices.len() as u32,
                origin,
            });
        }
        let bounds = if vertices.is_empty() {
            (Vec3::splat(-1.0), Vec3::splat(1.0))
        } else {
            vertices.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), v| (lo.min(v.position.into()), hi.max(v.position.into())),
            )
        };
        let probe_material = probes.as_ref().map(|_| {
            materials.push(sphere_material());
            materials.len() - 1
        });
        Model {
            scene,
            vertices,
            batches,
            materials,
            lightmaps,
            bounds,
            linear_pages: Vec::new(),
            debug_maps: Vec::new(),
            shadowmasks: Vec::new(),
            light_channels: Vec::new(),
            field: None,
            probes,
            probe_material,
        }
    }

    /// Triangles of the scene (the probe spheres not counted).
    pub fn triangles(&self) -> usize {
        self.vertices.len() / 3
    }
}
