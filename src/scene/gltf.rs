//! glTF 2.0 import (the only file that uses the `gltf` crate).
//!
//! Reads `.gltf` and `.glb`, with GLB-embedded, data-URI and external
//! buffers and images. External files must stay inside the scene's folder
//! (checked after resolving symlinks, before the file is opened). Every
//! accessor's byte range is checked against its buffer before any is read,
//! so the crate's readers never index out of bounds. The node hierarchy is
//! flattened into [`Instance`]s; primitives are triangulated (lists, strips,
//! fans), degenerate triangles dropped and counted.

use super::texture::{Filter, Filters, Texture, TextureRef, Wrap};
use super::{
    Alpha, Camera, ImportStats, Instance, Light, LightKind, LightMode, Material, Mesh, Scene,
    Specular,
};
use crate::error::{Error, Result};
use base64::Engine as _;
use glam::{Mat4, Vec2, Vec3, Vec4};
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

/// Limits applied while importing.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Largest scene, buffer or image file read (bytes).
    pub max_file_bytes: u64,
    /// Largest image accepted (width or height, texels), checked from the
    /// header before decoding.
    pub max_image_dimension: u32,
    /// Largest decoded image allocation (bytes).
    pub max_image_bytes: u64,
    /// Refuse scenes whose estimated bake memory exceeds this many bytes
    /// (estimated from accessor counts before any geometry is read).
    pub max_memory: Option<u64>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            max_file_bytes: 2 << 30,
            max_image_dimension: 16384,
            max_image_bytes: 1 << 30,
            max_memory: None,
        }
    }
}

/// Deepest node hierarchy followed (a guard against cycles).
const MAX_NODE_DEPTH: usize = 256;

struct Ctx<'a> {
    path: &'a Path,
    base_dir: PathBuf,
    options: &'a LoadOptions,
}

impl Ctx<'_> {
    fn invalid(&self, location: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Invalid {
            path: self.path.to_path_buf(),
            location: location.into(),
            message: message.into(),
        }
    }

    fn read_limited(&self, file: &Path, location: &str) -> Result<Vec<u8>> {
        let meta = std::fs::metadata(file).map_err(|e| {
            self.invalid(location, format!("cannot read `{}`: {e}", file.display()))
        })?;
        if meta.len() > self.options.max_file_bytes {
            return Err(self.invalid(
                location,
                format!(
                    "`{}` is {} bytes, over the {} byte limit",
                    file.display(),
                    meta.len(),
                    self.options.max_file_bytes
                ),
            ));
        }
        std::fs::read(file)
            .map_err(|e| self.invalid(location, format!("cannot read `{}`: {e}", file.display())))
    }

    /// Resolves a relative URI against the scene folder, refusing absolute
    /// paths, schemes, and anything (`..`, symlinks) that leaves the folder.
    fn resolve_uri(&self, uri: &str, location: &str) -> Result<PathBuf> {
        let decoded = percent_encoding::percent_decode_str(uri)
            .decode_utf8()
            .map_err(|_| self.invalid(location, format!("URI `{uri}` is not UTF-8")))?;
        let rel = Path::new(decoded.as_ref());
        let has_scheme = decoded
            .split_once(':')
            .is_some_and(|(s, _)| !s.is_empty() && !s.contains('/'));
        if rel.is_absolute() || has_scheme || decoded.starts_with('\\') {
            return Err(self.invalid(
                location,
                format!("URI `{uri}` is absolute; only paths relative to the scene's folder are allowed"),
            ));
        }
        let mut depth = 0i32;
        for c in rel.components() {
            match c {
                Component::ParentDir => depth -= 1,
                Component::Normal(_) => depth += 1,
                Component::CurDir => {}
                _ => depth = -1,
            }
            if depth < 0 {
                return Err(
                    self.invalid(location, format!("URI `{uri}` leaves the scene's folder"))
                );
            }
        }
        let joined = self.base_dir.join(rel);
        let canonical_base = self
            .base_dir
            .canonicalize()
            .unwrap_or_else(|_| self.base_dir.clone());
        let canonical = joined.canonicalize().map_err(|e| {
            self.invalid(location, format!("cannot read `{}`: {e}", joined.display()))
        })?;
        if !canonical.starts_with(&canonical_base) {
            return Err(self.invalid(
                location,
                format!("URI `{uri}` resolves (through a link) outside the scene's folder"),
            ));
        }
        Ok(canonical)
    }

    fn data_uri(&self, uri: &str, location: &str) -> Result<Option<Vec<u8>>> {
        let Some(rest) = uri.strip_prefix("data:") else {
            return Ok(None);
        };
        let Some((header, payload)) = rest.split_once(',') else {
            return Err(self.invalid(location, "malformed data URI (no comma)"));
        };
        if !header.ends_with(";base64") {
            return Err(self.invalid(location, "data URI is not base64"));
        }
        base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map(Some)
            .map_err(|e| self.invalid(location, format!("bad base64 in data URI: {e}")))
    }
}

/// Loads a `.gltf` or `.glb` file into a [`Scene`].
///
/// # Errors
/// [`Error::Parse`] if the file can't be read or isn't valid
/// glTF (including unsupported required extensions), [`Error::Invalid`] naming
/// the glTF path of bad data, [`Error::Empty`] if it has no triangles.
pub fn load(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let base_dir = path
        .parent()
        .map(Path::to_path_buf)
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or_else(|| PathBuf::from("."));
    let ctx = Ctx {
        path,
        base_dir,
        options,
    };
    let bytes = read_scene_file(path, options)?;
    let gltf = parse_checked(&ctx, &bytes)?;
    let (buffers, mut files) = load_buffers(&ctx, &gltf)?;
    check_accessors(&ctx, &gltf.document, &buffers)?;
    check_memory(path, options, &gltf.document)?;

    let mut scene = Scene::default();
    // The document as written (for the baked glTF's round trip) and the
    // bytes of every image it names.
    let json = source_json(path, &bytes)?;
    let images = image_bytes(&ctx, &gltf.document, &buffers, &mut files)?;
    let mut image_cache: HashMap<(usize, Option<usize>), u32> = HashMap::new();
    for material in gltf.document.materials() {
        let m = import_material(&ctx, &material, &buffers, &mut scene, &mut image_cache)?;
        scene.materials.push(m);
    }
    let fallback_material = scene.materials.len() as u32;
    scene.materials.push(Material::fallback());
    import_nodes(
        &ctx,
        &gltf.document,
        &buffers,
        fallback_material,
        &mut scene,
    )?;
    if scene.instances.is_empty() {
        return Err(Error::Empty {
            path: path.to_path_buf(),
            message: "the scene has no triangles to bake".into(),
        });
    }
    if scene.instances.iter().all(|i| !i.cast_shadows) {
        return Err(Error::Empty {
            path: path.to_path_buf(),
            message: "every node has extras.radbake.cast_shadows = false: rays would meet nothing"
                .into(),
        });
    }
    scene.source = Some(super::SourceDocument {
        json,
        buffers,
        images,
        files,
    });
    Ok(scene)
}

/// The scene file's bytes: not a folder, not empty, within the size limit.
fn read_scene_file(path: &Path, options: &LoadOptions) -> Result<Vec<u8>> {
    let unreadable = |e: std::io::Error| Error::Parse {
        path: path.to_path_buf(),
        message: format!("cannot read the file: {e}"),
    };
    let meta = std::fs::metadata(path).map_err(unreadable)?;
    if meta.is_dir() {
        return Err(Error::Parse {
            path: path.to_path_buf(),
            message: "is a folder, not a .gltf or .glb file".into(),
        });
    }
    if meta.len() > options.max_file_bytes {
        return Err(Error::Limit(format!(
            "{}: {} bytes is over the {} byte file limit",
            path.display(),
            meta.len(),
            options.max_file_bytes
        )));
    }
    let bytes = std::fs::read(path).map_err(unreadable)?;
    if bytes.is_empty() {
        return Err(Error::Parse {
            path: path.to_path_buf(),
            message: "the file is empty".into(),
        });
    }
    Ok(bytes)
}

/// Parses the glTF, checks what the crate's validation would index
/// unchecked, then validates.
fn parse_checked(ctx: &Ctx, bytes: &[u8]) -> Result<gltf::Gltf> {
    let parse_error = |e: gltf::Error| Error::Parse {
        path: ctx.path.to_path_buf(),
        message: if bytes.starts_with(b"glTF") {
            format!("malformed or truncated GLB ({} bytes): {e}", bytes.len())
        } else {
            e.to_string()
        },
    };
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(parse_error)?;
    precheck_positions(ctx, raw.document.as_json())?;
    let blob = raw.blob;
    let document = gltf::Document::from_json(raw.document.into_json()).map_err(parse_error)?;
    Ok(gltf::Gltf { document, blob })
}

/// Refuses a scene whose estimated bake memory is over `options.max_memory`.
fn check_memory(path: &Path, options: &LoadOptions, document: &gltf::Document) -> Result<()> {
    if let Some(limit) = options.max_memory {
        let estimate = estimate_memory(document);
        if estimate > limit {
            return Err(Error::Limit(format!(
                "{}: baking this scene needs an estimated {} MB ({} instanced triangles), over the {} MB memory limit",
                path.display(),
                estimate >> 20,
                estimate / BYTES_PER_TRIANGLE,
                limit >> 20
            )));
        }
    }
    Ok(())
}

/// The glTF JSON document as written (for a `.glb`, its JSON chunk).
fn source_json(path: &Path, bytes: &[u8]) -> Result<serde_json::Value> {
    let json_bytes: Vec<u8> = if bytes.starts_with(b"glTF") {
        gltf::Glb::from_slice(bytes)
            .map(|g| g.json.into_owned())
            .map_err(|e| Error::Parse {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?
    } else {
        bytes.to_vec()
    };
    serde_json::from_slice(&json_bytes).map_err(|e| Error::Parse {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// An image's encoded bytes and MIME type.
type EncodedImage = (Vec<u8>, String);

/// Every image's encoded bytes and MIME type (external files confined to
/// the scene's folder and added to `files`).
fn image_bytes(
    ctx: &Ctx,
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    files: &mut Vec<PathBuf>,
) -> Result<Vec<Option<EncodedImage>>> {
    let mut images = Vec::new();
    for image in document.images() {
        let location = format!("images[{}]", image.index());
        images.push(match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let data = &buffers[view.buffer().index()];
                Some((
                    data[view.offset()..view.offset() + view.length()].to_vec(),
                    mime_type.to_owned(),
                ))
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let data = match ctx.data_uri(uri, &location)? {
                    Some(d) => d,
                    None => {
                        let file = ctx.resolve_uri(uri, &location)?;
                        let d = ctx.read_limited(&file, &location)?;
                        files.push(file);
                        d
                    }
                };
                let mime = mime_type.map(str::to_owned).unwrap_or_else(|| {
                    if data.starts_with(b"\x89PNG") {
                        "image/png".into()
                    } else {
                        "image/jpeg".into()
                    }
                });
                Some((data, mime))
            }
        });
    }
    Ok(images)
}

/// Walks the default scene's node hierarchy depth first, in document
/// order: instances of meshes (each mesh imported on first use), lights
/// and perspective cameras, with their world transforms.
fn import_nodes(
    ctx: &Ctx,
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    fallback_material: u32,
    scene: &mut Scene,
) -> Result<()> {
    let mut mesh_slot: HashMap<usize, u32> = HashMap::new();
    let root_nodes: Vec<gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(s) => s.nodes().collect(),
        None => {
            return Err(Error::Empty {
                path: ctx.path.to_path_buf(),
                message: "the glTF has no scene to bake".into(),
            })
        }
    };
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = root_nodes
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY, 0))
        .collect();
    while let Some((node, parent, depth)) = stack.pop() {
        let location = format!("nodes[{}]", node.index());
        if depth > MAX_NODE_DEPTH {
            return Err(ctx.invalid(location, "node hierarchy deeper than 256 levels (a cycle?)"));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        if !local.is_finite() {
            return Err(ctx.invalid(location, "transform is not finite"));
        }
        let world = parent * local;
        let node_name = node
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| format!("node{}", node.index()));
        let extras = radbake_extras(ctx, &node, &location)?;
        scene.warnings.extend(extras.unknown.iter().cloned());
        if let Some(spacing) = extras.probe_volume {
            scene
                .probe_volumes
                .push(crate::scene::probe_volume::VolumeSpec {
                    name: node_name.clone(),
                    world_from_box: world,
                    spacing,
                });
        }
        let at = NodeAt {
            node: &node,
            world,
            name: &node_name,
            location: &location,
            extras: &extras,
        };
        if let Some(mesh) = node.mesh() {
            let sources = (buffers, fallback_material);
            add_mesh_instance(ctx, &at, &mesh, sources, &mut mesh_slot, scene)?;
        }
        add_light(ctx, document, &at, scene)?;
        if let Some(camera) = node.camera() {
            if let gltf::camera::Projection::Perspective(p) = camera.projection() {
                scene.cameras.push(Camera {
                    name: node_name.clone(),
                    world_from_camera: world,
                    yfov: p.yfov(),
                    aspect_ratio: p.aspect_ratio(),
                });
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    Ok(())
}

/// Where a node stands while it is imported: the node, its world
/// transform, its name, its place in the file (for messages) and its
/// `extras.radbake`.
struct NodeAt<'a, 'd> {
    node: &'a gltf::Node<'d>,
    world: Mat4,
    name: &'a str,
    location: &'a str,
    extras: &'a NodeExtras,
}

/// Node `at`'s mesh (imported once per glTF mesh, `mesh_slot` mapping the
/// glTF index to the scene's) and its instance: static or dynamic, with
/// its texel scale; a warning where its transform has zero scale or the
/// mesh has nothing to bake. `sources`: the buffers, and the material of
/// primitives without one.
fn add_mesh_instance(
    ctx: &Ctx,
    at: &NodeAt,
    mesh: &gltf::Mesh,
    (buffers, fallback_material): (&[Vec<u8>], u32),
    mesh_slot: &mut HashMap<usize, u32>,
    scene: &mut Scene,
) -> Result<()> {
    let (node, world, node_name, location, extras) =
        (at.node, at.world, at.name, at.location, at.extras);
    let slot = match mesh_slot.get(&mesh.index()) {
        Some(&s) => Some(s),
        None => {
            let m = import_mesh(
                ctx,
                mesh,
                buffers,
                fallback_material,
                &mut scene.stats,
                &mut scene.warnings,
            )?;
            if m.triangles.is_empty() {
                None
            } else {
                let s = scene.meshes.len() as u32;
                scene.meshes.push(m);
                mesh_slot.insert(mesh.index(), s);
                Some(s)
            }
        }
    };
    if slot.is_none() && extras.texel_scale.is_some() {
        scene.warnings.push(format!(
            "{location}.extras.radbake.texel_scale: the node has no mesh to bake; ignored"
        ));
    }
    if let Some(mesh_index) = slot {
        if world.determinant().abs() <= f32::MIN_POSITIVE {
            scene.warnings.push(format!(
                "{location}: transform has zero scale; instance skipped"
            ));
        } else {
            let instance = Instance {
                node: node_name.to_owned(),
                node_index: node.index(),
                mesh: mesh_index,
                world_from_local: world,
                // The node's, else its mesh's, else the bake's; a
                // quarter of it without a lightmap (see
                // [`super::LIGHTMAPLESS_SCALE`]).
                texel_scale: extras
                    .texel_scale
                    .or(scene.meshes[mesh_index as usize].texel_scale)
                    .unwrap_or(1.0)
                    * if extras.lightmap == Some(false) {
                        super::LIGHTMAPLESS_SCALE
                    } else {
                        1.0
                    },
                cast_shadows: extras.cast_shadows.unwrap_or(true),
                lightmap: extras.lightmap.unwrap_or(true),
            };
            if extras.dynamic {
                scene.dynamic.push(instance);
            } else {
                scene.instances.push(instance);
            }
        }
    }
    Ok(())
}

/// Node `at`'s light (`KHR_lights_punctual`), with its `extras.radbake`
/// mode, radius and angle; a warning where those are set on a node
/// without a light, or on the wrong kind of light.
fn add_light(ctx: &Ctx, document: &gltf::Document, at: &NodeAt, scene: &mut Scene) -> Result<()> {
    let (node, world, node_name, location, extras) =
        (at.node, at.world, at.name, at.location, at.extras);
    if let Some(light) = node.light() {
        check_light_json(ctx, document, light.index())?;
        let mut light = import_light(ctx, &light, &world, node_name)?;
        light.node_index = node.index();
        light.node_mode = extras.mode;
        light.mode = extras.mode.unwrap_or_default();
        light.layer = extras.layer.clone();
        let directional = light.kind == LightKind::Directional;
        if extras.sun_path.is_some() && !directional {
            scene.warnings.push(format!(
                "{location}.extras.radbake.sun_path: only a directional light has a sun path; ignored"
            ));
        } else {
            light.sun_path = extras.sun_path.clone();
        }
        if let Some(r) = extras.radius {
            if directional {
                scene.warnings.push(format!(
                    "{location}.extras.radbake.radius: a directional light has no radius (use angle); ignored"
                ));
            } else {
                light.radius = r;
            }
        }
        if let Some(a) = extras.angle {
            if directional {
                light.angle = a.to_radians();
            } else {
                scene.warnings.push(format!(
                    "{location}.extras.radbake.angle: only a directional light has an angle (use radius); ignored"
                ));
            }
        }
        scene.lights.push(light);
    } else if extras.layer.is_some() {
        // A layer names lights; on a mesh node it would silently do
        // nothing (an emissive surface's layer is its material's).
        return Err(ctx.invalid(
            format!("{location}.extras.radbake.layer"),
            "the node has no light (KHR_lights_punctual); an emissive surface takes its material's extras.radbake.layer",
        ));
    } else if extras.mode.is_some() || extras.radius.is_some() || extras.angle.is_some() {
        scene.warnings.push(format!(
            "{location}.extras.radbake: mode, radius and angle are for a node with a light; this one has none, ignored"
        ));
    }
    Ok(())
}

/// The largest `texel_scale` a node may ask for (its texels then cover
/// 1/4096 of the area the bake's do).
const MAX_TEXEL_SCALE: f64 = 64.0;

/// The `radbake` object of an `extras` (`raw`, at `location`), with its
/// own location; `None` where there is none.
///
/// # Errors
/// Extras that are not JSON, or a `radbake` that is not an object.
fn radbake_object(
    ctx: &Ctx,
    raw: Option<&serde_json::value::RawValue>,
    location: &str,
) -> Result<Option<(String, serde_json::Map<String, serde_json::Value>)>> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    let mut value: serde_json::Value =
        serde_json::from_str(raw.get()).map_err(|e| ctx.invalid(location, e.to_string()))?;
    let Some(rb) = value.get_mut("radbake").map(serde_json::Value::take) else {
        return Ok(None);
    };
    let at = format!("{location}.radbake");
    match rb {
        serde_json::Value::Object(obj) => Ok(Some((at, obj))),
        _ => Err(ctx.invalid(&at, "must be an object")),
    }
}

/// `texel_scale` under `at` (a node's or a mesh's `extras.radbake`).
fn texel_scale(ctx: &Ctx, at: &str, v: &serde_json::Value) -> Result<f32> {
    match v.as_f64() {
        Some(x) if x.is_finite() && x > 0.0 && x <= MAX_TEXEL_SCALE => Ok(x as f32),
        _ => Err(ctx.invalid(
            format!("{at}.texel_scale"),
            format!("must be a number > 0 and ≤ {MAX_TEXEL_SCALE}"),
        )),
    }
}

/// A mesh's `extras.radbake`: `{"texel_scale": s}`, the density of every
/// node that uses the mesh and sets none of its own; other keys warned
/// about.
fn mesh_extras(ctx: &Ctx, mesh: &gltf::Mesh, warnings: &mut Vec<String>) -> Result<Option<f32>> {
    let location = format!("meshes[{}].extras", mesh.index());
    let Some((at, obj)) = radbake_object(ctx, mesh.extras().as_deref(), &location)? else {
        return Ok(None);
    };
    let mut scale = None;
    for (key, v) in &obj {
        match key.as_str() {
            "texel_scale" => scale = Some(texel_scale(ctx, &at, v)?),
            "layer" => {
                return Err(ctx.invalid(
                    format!("{at}.layer"),
                    "a layer goes on a light's node or on an emissive material, not on a mesh",
                ))
            }
            other => warnings.push(format!(
                "{at}: unknown key `{other}` ignored (known on a mesh: texel_scale)"
            )),
        }
    }
    Ok(scale)
}

/// What a node's `extras.radbake` says.
#[derive(Default)]
struct NodeExtras {
    /// `probe_volume`: the node's box holds a probe grid, with this spacing
    /// (`None`: the bake's).
    probe_volume: Option<Option<f32>>,
    /// `dynamic: true`: not baked, lit by probes.
    dynamic: bool,
    /// `mode`: the bake mode of the node's light.
    mode: Option<LightMode>,
    /// `radius`: a point or spot light's sphere radius (metres).
    radius: Option<f32>,
    /// `angle`: a directional light's angular diameter (degrees).
    angle: Option<f32>,
    /// `texel_scale`: the node's lightmap density over the bake's.
    texel_scale: Option<f32>,
    /// `cast_shadows`: false leaves the node out of the ray caster.
    cast_shadows: Option<bool>,
    /// `lightmap`: false gives the node no lightmap (lit by probes).
    lightmap: Option<bool>,
    /// `layer`: the light layer of the node's light.
    layer: Option<String>,
    /// `sun_path`: a live sun's path.
    sun_path: Option<crate::scene::sun_path::SunPath>,
    /// Keys this version does not know (warned about).
    unknown: Vec<String>,
}

/// Reads `extras.radbake` of `node`: `{"probe_volume": {"spacing": m}}`,
/// `{"dynamic": true}` and a light's `{"mode": "baked" | "indirect" |
/// "shadowmask" | "realtime"}`. A spacing that is not a positive number is an
/// error naming the node; a key this version does not know is a warning.
fn radbake_extras(ctx: &Ctx, node: &gltf::Node, location: &str) -> Result<NodeExtras> {
    let mut out = NodeExtras::default();
    let extras = format!("{location}.extras");
    let Some((at, obj)) = radbake_object(ctx, node.extras().as_deref(), &extras)? else {
        return Ok(out);
    };
    for (key, v) in &obj {
        match key.as_str() {
            "dynamic" => {
                out.dynamic = v
                    .as_bool()
                    .ok_or_else(|| ctx.invalid(format!("{at}.dynamic"), "must be true or false"))?;
            }
            "probe_volume" => {
                let spacing = match v.get("spacing") {
                    None => None,
                    Some(s) => match s.as_f64() {
                        Some(x) if x.is_finite() && x > 0.0 => Some(x as f32),
                        _ => {
                            return Err(ctx.invalid(
                                format!("{at}.probe_volume.spacing"),
                                "must be a positive number of metres",
                            ))
                        }
                    },
                };
                if !v.is_object() {
                    return Err(ctx.invalid(format!("{at}.probe_volume"), "must be an object"));
                }
                out.probe_volume = Some(spacing);
            }
            "mode" => {
                let names = LightMode::ALL.map(LightMode::name).join(", ");
                out.mode = Some(v.as_str().and_then(LightMode::parse).ok_or_else(|| {
                    ctx.invalid(format!("{at}.mode"), format!("must be one of {names}"))
                })?);
            }
            "radius" => {
                out.radius = Some(match v.as_f64() {
                    Some(r) if r.is_finite() && r >= 0.0 => r as f32,
                    _ => {
                        return Err(ctx.invalid(
                            format!("{at}.radius"),
                            "must be a number of metres ≥ 0",
                        ))
                    }
                });
            }
            "angle" => {
                out.angle = Some(match v.as_f64() {
                    Some(a) if a.is_finite() && (0.0..90.0).contains(&a) => a as f32,
                    _ => {
                        return Err(ctx.invalid(
                            format!("{at}.angle"),
                            "must be an angular diameter in degrees, 0 ≤ angle < 90",
                        ))
                    }
                });
            }
            "texel_scale" => out.texel_scale = Some(texel_scale(ctx, &at, v)?),
            "cast_shadows" => {
                out.cast_shadows = Some(v.as_bool().ok_or_else(|| {
                    ctx.invalid(format!("{at}.cast_shadows"), "must be true or false")
                })?);
            }
            "lightmap" => {
                out.lightmap = Some(v.as_bool().ok_or_else(|| {
                    ctx.invalid(format!("{at}.lightmap"), "must be true or false")
                })?);
            }
            "layer" => out.layer = Some(layer_name(ctx, &at, v)?),
            "sun_path" => out.sun_path = Some(sun_path(ctx, &format!("{at}.sun_path"), v)?),
            // Written by radbake on a baked file's shadowmask lights (the
            // channel it assigned); a bake assigns channels afresh.
            "shadowmask_channel" => {}
            other => out.unknown.push(format!(
                "{at}: unknown key `{other}` ignored (known: angle, cast_shadows, dynamic, layer, lightmap, mode, probe_volume, radius, shadowmask_channel, sun_path, texel_scale)"
            )),
        }
    }
    Ok(out)
}

/// `extras.radbake.sun_path`: a list of directions `[x, y, z]` towards
/// the sun (at most 4096), or `{"latitude": deg, "day": 1–366,
/// "samples": n}` (see [`crate::scene::sun_path`]); a path on which the
/// sun never rises is an error.
fn sun_path(ctx: &Ctx, at: &str, v: &serde_json::Value) -> Result<crate::scene::sun_path::SunPath> {
    use crate::scene::sun_path::{SunPath, DEFAULT_SAMPLES};
    let path = if let Some(list) = v.as_array() {
        let dir = |d: &serde_json::Value| -> Option<glam::Vec3> {
            let a = d.as_array().filter(|a| a.len() == 3)?;
            let v = glam::Vec3::new(
                a[0].as_f64()? as f32,
                a[1].as_f64()? as f32,
                a[2].as_f64()? as f32,
            );
            (v.is_finite() && v.length() > 1e-6).then(|| v.normalize())
        };
        let dirs: Option<Vec<glam::Vec3>> = list.iter().map(dir).collect();
        match dirs {
            Some(d) if !d.is_empty() && d.len() <= 4096 => SunPath::Directions(d),
            _ => {
                return Err(ctx.invalid(
                    at.to_owned(),
                    "must be 1 to 4096 directions [x, y, z] (towards the sun, finite, not of zero length), or {\"latitude\", \"day\", \"samples\"}",
                ))
            }
        }
    } else {
        let num = |key: &str| v.get(key).and_then(serde_json::Value::as_f64);
        let (Some(latitude), Some(day)) = (num("latitude"), num("day")) else {
            return Err(ctx.invalid(
                at.to_owned(),
                "must be a list of directions or an object with `latitude` (degrees) and `day` (1–366)",
            ));
        };
        let samples = match v.get("samples") {
            None => DEFAULT_SAMPLES as f64,
            Some(n) => n.as_f64().unwrap_or(-1.0),
        };
        if !(-90.0..=90.0).contains(&latitude)
            || !(1.0..=366.0).contains(&day)
            || !(2.0..=4096.0).contains(&samples)
            || samples.fract() != 0.0
        {
            return Err(ctx.invalid(
                at.to_owned(),
                "latitude must be in −90..90 degrees, day in 1..366, samples a whole number in 2..4096",
            ));
        }
        SunPath::Day {
            latitude: latitude as f32,
            day: day as f32,
            samples: samples as u32,
        }
    };
    path.directions()
        .map_err(|m| ctx.invalid(at.to_owned(), m))?;
    Ok(path)
}

/// Every buffer's bytes, and the external files read.
/// The `gltf` crate's validation indexes `accessors` with each primitive's
/// POSITION index unchecked (found by fuzzing): check those indices on the
/// parsed but not yet validated document. Everything else is left to the
/// crate's validation.
fn precheck_positions(ctx: &Ctx, root: &gltf::json::Root) -> Result<()> {
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position =
                gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
            if let Some(index) = prim.attributes.get(&position) {
                if index.value() >= accessors {
                    return Err(ctx.invalid(
                        format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                        format!(
                            "accessor {} does not exist ({accessors} accessors)",
                            index.value()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Bake memory per instanced triangle (world geometry, BVH, atlas, texels
/// and patches at ordinary densities), measured on the shipped scenes with
/// margin.
const BYTES_PER_TRIANGLE: u64 = 1024;

/// Estimated bake memory from accessor counts and node instancing alone.
fn estimate_memory(doc: &gltf::Document) -> u64 {
    let mut uses: HashMap<usize, u64> = HashMap::new();
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => return 0,
    };
    let mut stack: Vec<(gltf::Node, usize)> = roots.into_iter().map(|n| (n, 0)).collect();
    while let Some((node, depth)) = stack.pop() {
        if depth > MAX_NODE_DEPTH {
            continue;
        }
        if let Some(m) = node.mesh() {
            *uses.entry(m.index()).or_default() += 1;
        }
        stack.extend(node.children().map(|c| (c, depth + 1)));
    }
    let mut triangles = 0u64;
    for mesh in doc.meshes() {
        let n = uses.get(&mesh.index()).copied().unwrap_or(0);
        for prim in mesh.primitives() {
            let count = prim
                .indices()
                .map(|a| a.count())
                .or_else(|| prim.get(&gltf::Semantic::Positions).map(|a| a.count()))
                .unwrap_or(0) as u64;
            triangles = triangles.saturating_add(n.saturating_mul(count / 3));
        }
    }
    triangles.saturating_mul(BYTES_PER_TRIANGLE)
}

fn load_buffers(ctx: &Ctx, gltf: &gltf::Gltf) -> Result<(Vec<Vec<u8>>, Vec<PathBuf>)> {
    let mut out = Vec::new();
    let mut files = Vec::new();
    for buffer in gltf.document.buffers() {
        let location = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                ctx.invalid(
                    &location,
                    "refers to the GLB binary chunk, which is missing",
                )
            })?,
            gltf::buffer::Source::Uri(uri) => match ctx.data_uri(uri, &location)? {
                Some(d) => d,
                None => {
                    let file = ctx.resolve_uri(uri, &location)?;
                    let d = ctx.read_limited(&file, &location)?;
                    files.push(file);
                    d
                }
            },
        };
        if data.len() < buffer.length() {
            return Err(ctx.invalid(
                &location,
                format!(
                    "declares {} bytes but only {} are present (truncated?)",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok((out, files))
}

/// Checks a byte range `offset .. offset + len` against `size`.
fn in_range(offset: usize, len: usize, size: usize) -> bool {
    offset.checked_add(len).is_some_and(|end| end <= size)
}

fn check_view(ctx: &Ctx, view: &gltf::buffer::View, buffers: &[Vec<u8>]) -> Result<()> {
    let size = buffers[view.buffer().index()].len();
    if !in_range(view.offset(), view.length(), size) {
        return Err(ctx.invalid(
            format!("bufferViews[{}]", view.index()),
            format!(
                "bytes {}..{} lie past the end of its {}-byte buffer",
                view.offset(),
                view.offset().saturating_add(view.length()),
                size
            ),
        ));
    }
    Ok(())
}

/// Checks that every accessor (and sparse part) lies within its buffer view.
fn check_accessors(ctx: &Ctx, doc: &gltf::Document, buffers: &[Vec<u8>]) -> Result<()> {
    for view in doc.views() {
        check_view(ctx, &view, buffers)?;
    }
    for acc in doc.accessors() {
        let location = format!("accessors[{}]", acc.index());
        let elem = acc.size();
        if let Some(view) = acc.view() {
            let stride = view.stride().unwrap_or(elem);
            if stride < elem {
                return Err(ctx.invalid(&location, "byteStride is smaller than the element size"));
            }
            let needed = if acc.count() == 0 {
                0
            } else {
                (acc.count() - 1)
                    .checked_mul(stride)
                    .and_then(|b| b.checked_add(elem))
                    .unwrap_or(usize::MAX)
            };
            if !in_range(acc.offset(), needed, view.length()) {
                return Err(ctx.invalid(
                    &location,
                    format!(
                        "{} elements at offset {} (stride {}) run past its {}-byte buffer view",
                        acc.count(),
                        acc.offset(),
                        stride,
                        view.length()
                    ),
                ));
            }
        }
        if let Some(sparse) = acc.sparse() {
            let n = sparse.count();
            let idx = sparse.indices();
            let idx_size = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            if !in_range(
                idx.offset(),
                n.saturating_mul(idx_size),
                idx.view().length(),
            ) {
                return Err(ctx.invalid(
                    format!("{location}.sparse.indices"),
                    "runs past its buffer view",
                ));
            }
            let vals = sparse.values();
            if !in_range(vals.offset(), n.saturating_mul(elem), vals.view().length()) {
                return Err(ctx.invalid(
                    format!("{location}.sparse.values"),
                    "runs past its buffer view",
                ));
            }
            // Sparse indices must address elements of the accessor.
            let view = idx.view();
            let data = &buffers[view.buffer().index()][view.offset() + idx.offset()..];
            for k in 0..n {
                let i = match idx_size {
                    1 => data[k] as usize,
                    2 => u16::from_le_bytes([data[2 * k], data[2 * k + 1]]) as usize,
                    _ => u32::from_le_bytes([
                        data[4 * k],
                        data[4 * k + 1],
                        data[4 * k + 2],
                        data[4 * k + 3],
                    ]) as usize,
                };
                if i >= acc.count() {
                    return Err(ctx.invalid(
                        format!("{location}.sparse.indices"),
                        format!(
                            "index {i} is not below the accessor's count {}",
                            acc.count()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

fn expect_type(
    ctx: &Ctx,
    acc: &gltf::Accessor,
    location: &str,
    dims: &[gltf::accessor::Dimensions],
    types: &[gltf::accessor::DataType],
) -> Result<()> {
    if !dims.contains(&acc.dimensions()) || !types.contains(&acc.data_type()) {
        return Err(ctx.invalid(
            location,
            format!(
                "accessor {} has type {:?}/{:?}, which this attribute does not allow",
                acc.index(),
                acc.dimensions(),
                acc.data_type()
            ),
        ));
    }
    Ok(())
}

fn import_mesh(
    ctx: &Ctx,
    mesh: &gltf::Mesh,
    buffers: &[Vec<u8>],
    fallback_material: u32,
    stats: &mut ImportStats,
    warnings: &mut Vec<String>,
) -> Result<Mesh> {
    let mut out = Mesh {
        name: mesh
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| format!("mesh{}", mesh.index())),
        gltf_index: mesh.index(),
        texel_scale: mesh_extras(ctx, mesh, warnings)?,
        ..Default::default()
    };
    let mut uv1: Vec<Vec2> = Vec::new();
    let mut all_have_uv1 = true;
    let mut colors: Vec<Vec4> = Vec::new();
    let mut any_colors = false;
    for prim in mesh.primitives() {
        let location = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            stats.skipped_primitives += 1;
            warnings.push(format!(
                "{location}: {mode:?} primitive skipped (only triangles are baked)"
            ));
            continue;
        }
        check_attribute_types(ctx, &prim, &location)?;
        let PrimitiveData {
            positions,
            normals,
            uv0,
            uv1: prim_uv1,
            colors: prim_colors,
            indices,
        } = read_primitive(ctx, &prim, buffers, &location, warnings)?;
        any_colors |= prim_colors.is_some();
        let color = |i: u32| prim_colors.as_ref().map_or(Vec4::ONE, |c| c[i as usize]);
        let vcount = positions.len();
        if let Some(problem) = malformed(mode, indices.len()) {
            stats.malformed_primitives += 1;
            warnings.push(format!("{location} (mesh `{}`): {problem}", out.name));
        }
        let tris = triangulate(mode, &indices);
        let material = prim
            .material()
            .index()
            .map_or(fallback_material, |i| i as u32);

        // Missing normals: glTF asks for flat normals, so split the vertices per triangle.
        let base = out.positions.len() as u32;
        let flat = normals.is_none();
        for t in &tris {
            let p = t.map(|i| positions[i as usize]);
            let cross = (p[1] - p[0]).cross(p[2] - p[0]);
            let scale = (p[1] - p[0]).length_squared() + (p[2] - p[0]).length_squared();
            let degenerate = t[0] == t[1]
                || t[1] == t[2]
                || t[0] == t[2]
                || cross.length() <= 1e-7 * scale
                || scale == 0.0;
            if degenerate {
                stats.degenerate_triangles += 1;
                continue;
            }
            if flat {
                let v = out.positions.len() as u32;
                let n = cross.normalize();
                for &i in t {
                    out.positions.push(positions[i as usize]);
                    out.normals.push(n);
                    out.uv0.push(uv0[i as usize]);
                    uv1.push(prim_uv1.as_ref().map_or(Vec2::ZERO, |u| u[i as usize]));
                    colors.push(color(i));
                    out.vertex_source.push(i);
                }
                out.triangles.push([v, v + 1, v + 2]);
            } else {
                out.triangles.push(t.map(|i| base + i));
            }
            out.triangle_material.push(material);
            out.triangle_primitive.push(prim.index() as u32);
        }
        if !flat {
            let normals = normals.unwrap_or_default();
            out.positions.extend_from_slice(&positions);
            out.normals
                .extend(normals.iter().map(|n| n.normalize_or(Vec3::Y)));
            out.uv0.extend_from_slice(&uv0);
            uv1.extend(prim_uv1.clone().unwrap_or_else(|| vec![Vec2::ZERO; vcount]));
            colors.extend((0..vcount as u32).map(color));
            out.vertex_source.extend(0..vcount as u32);
        }
        all_have_uv1 &= prim_uv1.is_some();
    }
    if all_have_uv1 && !out.triangles.is_empty() {
        out.uv1 = Some(uv1);
    }
    if any_colors {
        out.colors = Some(colors);
    }
    Ok(out)
}

/// Checks the types of a primitive's attributes and indices against what
/// glTF allows (POSITION required).
fn check_attribute_types(ctx: &Ctx, prim: &gltf::Primitive, location: &str) -> Result<()> {
    use gltf::accessor::{DataType as T, Dimensions as D};
    let pos_acc = prim
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| ctx.invalid(location, "has no POSITION attribute"))?;
    expect_type(
        ctx,
        &pos_acc,
        &format!("{location}.attributes.POSITION"),
        &[D::Vec3],
        &[T::F32],
    )?;
    if let Some(a) = prim.get(&gltf::Semantic::Normals) {
        expect_type(
            ctx,
            &a,
            &format!("{location}.attributes.NORMAL"),
            &[D::Vec3],
            &[T::F32],
        )?;
    }
    for set in 0..2 {
        if let Some(a) = prim.get(&gltf::Semantic::TexCoords(set)) {
            expect_type(
                ctx,
                &a,
                &format!("{location}.attributes.TEXCOORD_{set}"),
                &[D::Vec2],
                &[T::F32, T::U8, T::U16],
            )?;
        }
    }
    if let Some(a) = prim.indices() {
        expect_type(
            ctx,
            &a,
            &format!("{location}.indices"),
            &[D::Scalar],
            &[T::U8, T::U16, T::U32],
        )?;
    }
    Ok(())
}

/// A triangle primitive's vertex attributes and indices, as read.
struct PrimitiveData {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uv0: Vec<Vec2>,
    uv1: Option<Vec<Vec2>>,
    colors: Option<Vec<Vec4>>,
    indices: Vec<u32>,
}

/// Reads a primitive's attributes and indices: positions and normals
/// finite, indices below the vertex count, every attribute the same count.
/// `COLOR_0`, which the bake does not use, is read where it is valid and
/// otherwise dropped with a warning.
fn read_primitive(
    ctx: &Ctx,
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    location: &str,
    warnings: &mut Vec<String>,
) -> Result<PrimitiveData> {
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| ctx.invalid(format!("{location}.attributes.POSITION"), "cannot be read"))?
        .map(Vec3::from)
        .collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(ctx.invalid(
            format!("{location}.attributes.POSITION"),
            format!("vertex {i} is not finite ({})", positions[i]),
        ));
    }
    let vcount = positions.len();
    let normals: Option<Vec<Vec3>> = reader.read_normals().map(|it| it.map(Vec3::from).collect());
    if let Some(n) = &normals {
        if let Some(i) = n.iter().position(|v| !v.is_finite()) {
            return Err(ctx.invalid(
                format!("{location}.attributes.NORMAL"),
                format!("normal {i} is not finite ({})", n[i]),
            ));
        }
    }
    let read_uv = |set: u32| -> Option<Vec<Vec2>> {
        reader
            .read_tex_coords(set)
            .map(|it| it.into_f32().map(Vec2::from).collect())
    };
    let uv0 = read_uv(0).unwrap_or_else(|| vec![Vec2::ZERO; vcount]);
    let prim_uv1 = read_uv(1);
    let indices: Vec<u32> = match reader.read_indices() {
        Some(it) => it.into_u32().collect(),
        None => (0..vcount as u32).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vcount) {
        return Err(ctx.invalid(
            format!("{location}.indices"),
            format!("index {bad} is not below the vertex count {vcount}"),
        ));
    }
    if uv0.len() != vcount
        || prim_uv1.as_ref().is_some_and(|u| u.len() != vcount)
        || normals.as_ref().is_some_and(|n| n.len() != vcount)
    {
        return Err(ctx.invalid(location, "attributes have different counts"));
    }
    let colors = read_colors(&reader, prim, location, vcount, warnings);
    Ok(PrimitiveData {
        positions,
        normals,
        uv0,
        uv1: prim_uv1,
        colors,
        indices,
    })
}

/// A primitive's `COLOR_0` as linear RGBA (glTF 2.0 §3.7.2.1: float, or
/// normalized unsigned byte or short; VEC3 or VEC4), None where it has
/// none, and None with a warning where it is not one of those or has the
/// wrong count.
fn read_colors<'a, 's, F>(
    reader: &gltf::mesh::Reader<'a, 's, F>,
    prim: &gltf::Primitive,
    location: &str,
    vcount: usize,
    warnings: &mut Vec<String>,
) -> Option<Vec<Vec4>>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    use gltf::accessor::{DataType as T, Dimensions as D};
    let accessor = prim.get(&gltf::Semantic::Colors(0))?;
    let typed = matches!(accessor.dimensions(), D::Vec3 | D::Vec4)
        && matches!(accessor.data_type(), T::F32 | T::U8 | T::U16);
    let colors: Option<Vec<Vec4>> = typed
        .then(|| reader.read_colors(0))
        .flatten()
        .map(|c| c.into_rgba_f32().map(Vec4::from).collect());
    match colors {
        Some(c) if c.len() == vcount && c.iter().all(|v| v.is_finite()) => Some(c),
        _ => {
            warnings.push(format!(
                "{location}.attributes.COLOR_0: not a valid colour accessor of {vcount} elements; ignored"
            ));
            None
        }
    }
}

/// What is wrong with a triangle primitive of `count` indices (or
/// vertices), if anything: TRIANGLES needs a multiple of 3, strips and fans
/// at least 3 (glTF 2.0 §3.7.2.1). The bake drops what cannot form a
/// triangle, and says so.
fn malformed(mode: Mode, count: usize) -> Option<String> {
    match mode {
        Mode::Triangles if count % 3 != 0 => Some(format!(
            "{count} indices are not a multiple of 3 (TRIANGLES): the last {} dropped",
            count % 3
        )),
        Mode::TriangleStrip | Mode::TriangleFan if count < 3 => Some(format!(
            "{count} indices make no triangle ({mode:?}): the primitive is empty"
        )),
        _ => None,
    }
}

/// Triangle lists from glTF's three triangle modes (glTF 2.0 §3.7.2.1).
fn triangulate(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (2..idx.len())
            .map(|i| {
                if i % 2 == 0 {
                    [idx[i - 2], idx[i - 1], idx[i]]
                } else {
                    [idx[i - 1], idx[i - 2], idx[i]]
                }
            })
            .collect(),
        Mode::TriangleFan => (2..idx.len())
            .map(|i| [idx[i - 1], idx[i], idx[0]])
            .collect(),
        _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

fn import_material(
    ctx: &Ctx,
    material: &gltf::Material,
    buffers: &[Vec<u8>],
    scene: &mut Scene,
    cache: &mut HashMap<(usize, Option<usize>), u32>,
) -> Result<Material> {
    let index = material.index().unwrap_or(0);
    let location = format!("materials[{index}]");
    let pbr = material.pbr_metallic_roughness();
    let base = pbr.base_color_factor();
    let emissive = material.emissive_factor();
    let strength = material.emissive_strength().unwrap_or(1.0);
    let values = base
        .iter()
        .chain(emissive.iter())
        .chain(std::iter::once(&strength));
    if values.clone().any(|v| !v.is_finite()) || values.clone().any(|&v| v < 0.0) {
        return Err(ctx.invalid(&location, "colour factors must be finite and non-negative"));
    }
    let mut texture_ref = |info: Option<gltf::texture::Info>,
                           what: &str|
     -> Result<Option<TextureRef>> {
        let Some(info) = info else { return Ok(None) };
        let transform = info.texture_transform();
        let (offset, rotation, scale) = match &transform {
            Some(t) => (Vec2::from(t.offset()), t.rotation(), Vec2::from(t.scale())),
            None => (Vec2::ZERO, 0.0, Vec2::ONE),
        };
        // KHR_texture_transform's texCoord overrides the texture info's.
        let tex_coord = transform
            .and_then(|t| t.tex_coord())
            .unwrap_or(info.tex_coord());
        if tex_coord != 0 {
            scene.warnings.push(format!(
                    "{location}.{what}: uses TEXCOORD_{tex_coord}; the bake samples it through TEXCOORD_0"
                ));
        }
        let texture = info.texture();
        // One decoded texture per image and sampler (as three.js's
        // GLTFLoader caches them): the sampler sets wrap and filters.
        let key = (texture.source().index(), texture.sampler().index());
        let slot = match cache.get(&key) {
            Some(&s) => s,
            None => {
                let img = decode_image(ctx, &texture, buffers)?;
                let s = scene.textures.len() as u32;
                scene.textures.push(img);
                cache.insert(key, s);
                s
            }
        };
        Ok(Some(TextureRef {
            texture: slot,
            offset,
            rotation,
            scale,
            tex_coord,
        }))
    };
    let albedo_texture = texture_ref(
        pbr.base_color_texture(),
        "pbrMetallicRoughness.baseColorTexture",
    )?;
    let emission_texture = texture_ref(material.emissive_texture(), "emissiveTexture")?;
    Ok(Material {
        name: material
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| format!("material{index}")),
        albedo: Vec3::new(base[0], base[1], base[2]),
        alpha_factor: base[3],
        albedo_texture,
        emission: Vec3::from(emissive) * strength,
        emission_texture,
        double_sided: material.double_sided(),
        specular: {
            let pbr = material.pbr_metallic_roughness();
            let transmission = material
                .transmission()
                .map_or(0.0, |t| t.transmission_factor());
            if transmission >= 0.5 {
                // The spec's default index of refraction is 1.5.
                let ior = material.ior().unwrap_or(1.5);
                Specular::Glass {
                    ior: if ior.is_finite() && ior >= 1.0 {
                        ior
                    } else {
                        1.5
                    },
                }
            } else if pbr.metallic_factor() >= 1.0
                && pbr.roughness_factor() <= 0.0
                && pbr.metallic_roughness_texture().is_none()
            {
                Specular::Mirror
            } else {
                Specular::None
            }
        },
        alpha: match material.alpha_mode() {
            gltf::material::AlphaMode::Opaque => Alpha::Opaque,
            gltf::material::AlphaMode::Mask => Alpha::Mask {
                cutoff: material.alpha_cutoff().unwrap_or(0.5),
            },
            gltf::material::AlphaMode::Blend => Alpha::Mask { cutoff: 0.5 },
        },
        blend: material.alpha_mode() == gltf::material::AlphaMode::Blend,
        layer: material_layer(
            ctx,
            material,
            &location,
            Vec3::from(emissive) * strength,
            &mut scene.warnings,
        )?,
    })
}

/// A material's `extras.radbake`: `{"layer": "<name>"}`, the light layer of
/// its emission. A layer on a material that emits nothing is an error (it
/// would put nothing in the layer); other keys are warned about.
fn material_layer(
    ctx: &Ctx,
    material: &gltf::Material,
    location: &str,
    emission: Vec3,
    warnings: &mut Vec<String>,
) -> Result<Option<String>> {
    let extras = format!("{location}.extras");
    let Some((at, obj)) = radbake_object(ctx, material.extras().as_deref(), &extras)? else {
        return Ok(None);
    };
    let mut layer = None;
    for (key, v) in &obj {
        match key.as_str() {
            "layer" => {
                if emission.max_element() <= 0.0 {
                    return Err(ctx.invalid(
                        format!("{at}.layer"),
                        "the material emits nothing (emissiveFactor is black): a layer holds emitters",
                    ));
                }
                layer = Some(layer_name(ctx, &at, v)?);
            }
            other => warnings.push(format!(
                "{at}: unknown key `{other}` ignored (known on a material: layer)"
            )),
        }
    }
    Ok(layer)
}

/// A light layer's name under `at`: a plain identifier (see
/// [`crate::config::valid_layer_name`]).
fn layer_name(ctx: &Ctx, at: &str, v: &serde_json::Value) -> Result<String> {
    match v.as_str() {
        Some(name) if crate::config::valid_layer_name(name) => Ok(name.to_owned()),
        _ => Err(ctx.invalid(
            format!("{at}.layer"),
            "must be a plain identifier (letters, digits, _; at most 32, not starting with a digit)",
        )),
    }
}

fn decode_image(ctx: &Ctx, texture: &gltf::Texture, buffers: &[Vec<u8>]) -> Result<Texture> {
    let image = texture.source();
    let location = format!("images[{}]", image.index());
    let bytes: Vec<u8> = match image.source() {
        gltf::image::Source::View { view, .. } => {
            let data = &buffers[view.buffer().index()];
            data[view.offset()..view.offset() + view.length()].to_vec()
        }
        gltf::image::Source::Uri { uri, .. } => match ctx.data_uri(uri, &location)? {
            Some(d) => d,
            None => {
                let file = ctx.resolve_uri(uri, &location)?;
                ctx.read_limited(&file, &location)?
            }
        },
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| ctx.invalid(&location, format!("cannot read image: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(ctx.options.max_image_dimension);
    limits.max_image_height = Some(ctx.options.max_image_dimension);
    limits.max_alloc = Some(ctx.options.max_image_bytes);
    reader.limits(limits);
    let decoded = reader
        .decode()
        .map_err(|e| ctx.invalid(&location, format!("cannot decode image: {e}")))?
        .to_rgba8();
    let (width, height) = decoded.dimensions();
    if width == 0 || height == 0 {
        return Err(ctx.invalid(&location, "image has no pixels"));
    }
    let wrap = |m: gltf::texture::WrappingMode| match m {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    };
    let sampler = texture.sampler();
    Ok(Texture {
        width,
        height,
        rgba: decoded.pixels().map(|p| p.0).collect(),
        wrap_s: wrap(sampler.wrap_s()),
        wrap_t: wrap(sampler.wrap_t()),
        filters: filters(&sampler),
    })
}

/// A glTF sampler's filters, absent ones as three.js's GLTFLoader sets
/// them (`LINEAR`, `LINEAR_MIPMAP_LINEAR`; see [`Filters`]).
fn filters(sampler: &gltf::texture::Sampler) -> Filters {
    use gltf::texture::{MagFilter, MinFilter};
    let mut f = Filters::default();
    if sampler.mag_filter() == Some(MagFilter::Nearest) {
        f.mag = Filter::Nearest;
    }
    if let Some(min) = sampler.min_filter() {
        (f.min, f.mipmap) = match min {
            MinFilter::Nearest => (Filter::Nearest, None),
            MinFilter::Linear => (Filter::Linear, None),
            MinFilter::NearestMipmapNearest => (Filter::Nearest, Some(Filter::Nearest)),
            MinFilter::LinearMipmapNearest => (Filter::Linear, Some(Filter::Nearest)),
            MinFilter::NearestMipmapLinear => (Filter::Nearest, Some(Filter::Linear)),
            MinFilter::LinearMipmapLinear => (Filter::Linear, Some(Filter::Linear)),
        };
    }
    f
}

/// The `gltf` crate unwraps a spot light's `spot` object: refuse its absence here.
fn check_light_json(ctx: &Ctx, doc: &gltf::Document, index: usize) -> Result<()> {
    use gltf::json::extensions::scene::khr_lights_punctual::Type;
    use gltf::json::validation::Checked;
    let json = doc
        .as_json()
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .and_then(|l| l.lights.get(index));
    let location = format!("extensions.KHR_lights_punctual.lights[{index}]");
    match json {
        Some(l) => match (&l.type_, &l.spot) {
            (Checked::Valid(Type::Spot), None) => {
                Err(ctx.invalid(location, "a spot light needs a `spot` object"))
            }
            (Checked::Invalid, _) => Err(ctx.invalid(location, "unknown light type")),
            _ => Ok(()),
        },
        None => Err(ctx.invalid(location, "no such light")),
    }
}

fn import_light(
    ctx: &Ctx,
    light: &gltf::khr_lights_punctual::Light,
    world: &Mat4,
    node_name: &str,
) -> Result<Light> {
    use gltf::khr_lights_punctual::Kind;
    let location = format!("extensions.KHR_lights_punctual.lights[{}]", light.index());
    let color = Vec3::from(light.color());
    let intensity = light.intensity();
    if !color.is_finite() || !intensity.is_finite() || intensity < 0.0 || color.min_element() < 0.0
    {
        return Err(ctx.invalid(
            location,
            "colour and intensity must be finite and non-negative",
        ));
    }
    let kind = match light.kind() {
        Kind::Directional => LightKind::Directional,
        Kind::Point => LightKind::Point,
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        },
    };
    let name = light.name().unwrap_or(node_name);
    let position = world.transform_point3(Vec3::ZERO);
    let direction = world
        .transform_vector3(Vec3::NEG_Z)
        .normalize_or(Vec3::NEG_Y);
    Ok(Light {
        node: node_name.to_owned(),
        range: light.range(),
        ..Light::delta(name, kind, color * intensity, position, direction)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans() {
        assert_eq!(
            triangulate(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            triangulate(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[1, 2, 0], [2, 3, 0]]
        );
        assert_eq!(triangulate(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
        assert!(malformed(Mode::Triangles, 4).is_some_and(|m| m.contains("last 1 dropped")));
        assert!(malformed(Mode::Triangles, 6).is_none());
        assert!(malformed(Mode::TriangleStrip, 2).is_some());
        assert!(malformed(Mode::TriangleFan, 3).is_none());
    }

    #[test]
    fn ranges() {
        assert!(in_range(0, 4, 4));
        assert!(!in_range(1, 4, 4));
        assert!(!in_range(usize::MAX, 2, 4));
    }
}
