//! The baked glTF: the input document, round-tripped, with lightmaps.
//!
//! - Every baked primitive gets `TEXCOORD_1` (its vertices split at chart
//!   seams: each output vertex copies all attributes, morph targets
//!   included, of the input vertex it came from) and new indices.
//! - Lightmap pages are embedded as PNG textures (see [`super::png8`]: one
//!   scale per instance, carried by its `MOZ_lightmap.intensity`).
//! - Each material that is lightmapped references its page through the
//!   `MOZ_lightmap` extension (`index`, `texCoord: 1`, `intensity`), whose
//!   `KHR_texture_transform` maps the instance's `[0, 1]` UVs to its atlas
//!   rectangle. Instances of one mesh get mesh and material copies (sharing
//!   every accessor) so each can carry its own rectangle.
//! - Everything else (nodes, animations, skins, extras, other extensions)
//!   is kept; all buffers and images are packed into the GLB's one binary
//!   chunk.

use super::png8::EncodedPage;
use crate::error::{Error, Result};
use crate::layout::atlas::Atlas;
use crate::scene::Scene;
use serde_json::{json, Value};
use std::collections::HashMap;

/// Bytes per component of a glTF `componentType`.
fn component_size(ct: u64) -> Option<usize> {
    match ct {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// Components of a glTF accessor `type`.
fn type_count(t: &str) -> Option<usize> {
    Some(match t {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// The packed binary being built, and the document's new views/accessors.
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn align(&mut self) {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
    }

    fn view(&mut self, bytes: &[u8], stride: Option<usize>, target: Option<u32>) -> usize {
        self.align();
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }
}

/// Reads every element of accessor `a` as raw bytes (sparse applied).
fn accessor_elements(
    doc: &Value,
    bin: &[u8],
    view_offsets: &[usize],
    a: usize,
) -> Option<(Vec<u8>, usize, usize)> {
    let acc = doc["accessors"].get(a)?;
    let cs = component_size(acc["componentType"].as_u64()?)?;
    let tc = type_count(acc["type"].as_str()?)?;
    let elem = cs * tc;
    let count = acc["count"].as_u64()? as usize;
    let mut out = vec![0u8; elem * count];
    if let Some(v) = acc.get("bufferView").and_then(Value::as_u64) {
        let view = &doc["bufferViews"][v as usize];
        let stride = view["byteStride"].as_u64().map_or(elem, |s| s as usize);
        let start = view_offsets[v as usize] + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
        for k in 0..count {
            let src = start + k * stride;
            out[k * elem..(k + 1) * elem].copy_from_slice(bin.get(src..src + elem)?);
        }
    }
    if let Some(sp) = acc.get("sparse") {
        let n = sp["count"].as_u64()? as usize;
        let iv = sp["indices"]["bufferView"].as_u64()? as usize;
        let ics = component_size(sp["indices"]["componentType"].as_u64()?)?;
        let istart = view_offsets[iv] + sp["indices"]["byteOffset"].as_u64().unwrap_or(0) as usize;
        let vv = sp["values"]["bufferView"].as_u64()? as usize;
        let vstart = view_offsets[vv] + sp["values"]["byteOffset"].as_u64().unwrap_or(0) as usize;
        for k in 0..n {
            let ib = bin.get(istart + k * ics..istart + (k + 1) * ics)?;
            let idx = match ics {
                1 => ib[0] as usize,
                2 => u16::from_le_bytes([ib[0], ib[1]]) as usize,
                _ => u32::from_le_bytes([ib[0], ib[1], ib[2], ib[3]]) as usize,
            };
            let src = bin.get(vstart + k * elem..vstart + (k + 1) * elem)?;
            out.get_mut(idx * elem..(idx + 1) * elem)?
                .copy_from_slice(src);
        }
    }
    Some((out, elem, count))
}

/// Builds the baked `.glb` for `scene` with `lightmaps` laid out by `atlas`:
/// the source document with its buffers packed into one, its images
/// embedded, the lightmap pages as textures, every primitive re-indexed
/// with the unwrap's `TEXCOORD_1`, and each instance's materials carrying
/// `MOZ_lightmap` with its own page rectangle.
///
/// # Errors
/// [`Error::Encode`] when the scene was not loaded from a file or its
/// document cannot be round-tripped.
pub fn baked_glb(
    scene: &Scene,
    atlas: &Atlas,
    pages: &[EncodedPage],
    masks: Option<Masks>,
    name: &str,
) -> Result<Vec<u8>> {
    let fail = |m: String| encode_error(name, m);
    let src = scene
        .source
        .as_ref()
        .ok_or_else(|| fail("the scene has no source document".into()))?;
    let mut doc = src.json.clone();
    let (mut b, view_offsets) = pack_buffers(&doc, &src.buffers);
    embed_images(&mut doc, &src.images, &mut b, name)?;
    let pages = lightmap_textures(&mut doc, &mut b, pages);
    let mask_textures = masks.map(|m| shadowmask_textures(&mut doc, &mut b, m.png));
    let prims = reindex_primitives(scene, atlas, &doc, &mut b, &view_offsets, name)?;
    lightmapped_instances(scene, atlas, &mut doc, &prims, &pages);
    if let (Some(textures), Some(m)) = (&mask_textures, &masks) {
        shadowmask_extras(scene, atlas, &mut doc, textures, m.channel);
    }
    light_modes(scene, masks.map(|m| m.channel), &mut doc);
    Ok(finish(doc, b))
}

/// Writes each light's bake mode to its node's `extras.radbake.mode` (the
/// key the bake reads), so an engine or the preview knows which lights
/// to draw in real time whatever set the mode (the node, the config or the
/// CLI). A node whose `extras` is not an object keeps it (the manifest
/// lists the mode as well). A shadowmask light also gets its
/// `shadowmask_channel` (`r`, `g`, `b` or `a`); one that got no channel
/// is written as `indirect`, the mode it was baked in.
fn light_modes(scene: &Scene, channel: Option<&[Option<u8>]>, doc: &mut Value) {
    for (l, light) in scene.lights.iter().enumerate() {
        let Some(node) = doc["nodes"].get_mut(light.node_index) else {
            continue;
        };
        let Some(node) = node.as_object_mut() else {
            continue;
        };
        let extras = node.entry("extras").or_insert_with(|| json!({}));
        let Some(extras) = extras.as_object_mut() else {
            continue;
        };
        let radbake = extras.entry("radbake").or_insert_with(|| json!({}));
        let Some(radbake) = radbake.as_object_mut() else {
            continue;
        };
        let c = channel.and_then(|c| c[l]);
        let mode = crate::maps::shadowmask::baked_mode(light, c);
        radbake.insert("mode".into(), json!(mode.name()));
        if let Some(c) = c {
            radbake.insert(
                "shadowmask_channel".into(),
                json!(CHANNEL_NAMES[c as usize]),
            );
        }
    }
}

/// An [`Error::Encode`] for the output `name`.
fn encode_error(name: &str, message: String) -> Error {
    Error::Encode {
        path: name.into(),
        message,
    }
}

/// Step 1: every buffer packed into one; the buffer views moved there.
/// Returns the builder and each original view's offset in the new buffer.
fn pack_buffers(doc: &Value, buffers: &[Vec<u8>]) -> (Builder, Vec<usize>) {
    let mut b = Builder {
        bin: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut buffer_base = Vec::new();
    for buf in buffers {
        b.align();
        buffer_base.push(b.bin.len());
        b.bin.extend_from_slice(buf);
    }
    let views = doc["bufferViews"].as_array().cloned().unwrap_or_default();
    let mut view_offsets = Vec::with_capacity(views.len());
    for v in &views {
        let buf = v["buffer"].as_u64().unwrap_or(0) as usize;
        let off = buffer_base.get(buf).copied().unwrap_or(0)
            + v["byteOffset"].as_u64().unwrap_or(0) as usize;
        view_offsets.push(off);
    }
    b.views = views
        .into_iter()
        .zip(&view_offsets)
        .map(|(mut v, &off)| {
            v["buffer"] = json!(0);
            v["byteOffset"] = json!(off);
            v
        })
        .collect();
    b.accessors = doc["accessors"].as_array().cloned().unwrap_or_default();
    (b, view_offsets)
}

/// Step 2: images with URIs become buffer views.
fn embed_images(
    doc: &mut Value,
    images_src: &[Option<(Vec<u8>, String)>],
    b: &mut Builder,
    name: &str,
) -> Result<()> {
    let Some(images) = doc["images"].as_array_mut() else {
        return Ok(());
    };
    for (i, img) in images.iter_mut().enumerate() {
        if img.get("uri").is_none() {
            continue;
        }
        if let Some(Some((bytes, mime))) = images_src.get(i) {
            b.align();
            let off = b.bin.len();
            b.bin.extend_from_slice(bytes);
            b.views
                .push(json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()}));
            let view = b.views.len() - 1;
            let obj = img
                .as_object_mut()
                .ok_or_else(|| encode_error(name, format!("images[{i}] is not an object")))?;
            obj.remove("uri");
            obj.insert("bufferView".into(), json!(view));
            obj.insert("mimeType".into(), json!(mime));
        }
    }
    Ok(())
}

/// The lightmap pages as textures, and each instance's `MOZ_lightmap`
/// intensity.
struct PageTextures {
    texture: Vec<usize>,
    intensity: Vec<f32>,
}

/// Step 3: the lightmap pages as PNG textures.
fn lightmap_textures(doc: &mut Value, b: &mut Builder, encoded: &[EncodedPage]) -> PageTextures {
    let mut pages = PageTextures {
        texture: Vec::new(),
        intensity: Vec::new(),
    };
    let sampler = push(
        doc,
        "samplers",
        json!({"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}),
    );
    for (page, e) in encoded.iter().enumerate() {
        let view = b.view(&e.png, None, None);
        let image = push(
            doc,
            "images",
            json!({"bufferView": view, "mimeType": "image/png", "name": format!("lightmap_{page}")}),
        );
        pages.texture.push(push(
            doc,
            "textures",
            json!({"source": image, "sampler": sampler, "name": format!("lightmap_{page}")}),
        ));
    }
    // MOZ_lightmap's intensity includes π: three.js reads texel × intensity
    // as irradiance. One scale per instance (its page's encoding).
    pages.intensity = (0..encoded.first().map_or(0, |e| e.scales.len()))
        .map(|i| {
            let s = encoded.iter().find_map(|e| e.scales[i]).unwrap_or(1.0);
            std::f32::consts::PI * s
        })
        .collect();
    pages
}

/// The shadowmask for the baked `.glb`: each page's PNG and each scene
/// light's channel.
#[derive(Clone, Copy)]
pub struct Masks<'a> {
    /// PNG bytes per page.
    pub png: &'a [Vec<u8>],
    /// Per scene light, its channel.
    pub channel: &'a [Option<u8>],
}

use crate::maps::shadowmask::CHANNEL_NAMES;

/// The shadowmask pages as PNG textures (linear data, clamped, filtered
/// bilinearly), in page order.
fn shadowmask_textures(doc: &mut Value, b: &mut Builder, png: &[Vec<u8>]) -> Vec<usize> {
    let sampler = push(
        doc,
        "samplers",
        json!({"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}),
    );
    (0..png.len())
        .map(|page| {
            let view = b.view(&png[page], None, None);
            let name = format!("shadowmask_{page}");
            let image = push(
                doc,
                "images",
                json!({"bufferView": view, "mimeType": "image/png", "name": name}),
            );
            push(
                doc,
                "textures",
                json!({"source": image, "sampler": sampler, "name": name}),
            )
        })
        .collect()
}

/// Every lightmapped material (each instance has its own copies, see
/// [`lightmapped_instances`]) references its shadowmask page in
/// `extras.radbake.shadowmask`: `index` (texture), `texCoord: 1`, `offset`
/// and `scale` (the instance rectangle, as `MOZ_lightmap`'s
/// `KHR_texture_transform`), and `channels`: the glTF node index of the
/// light each of r, g, b, a holds (null where none).
fn shadowmask_extras(
    scene: &Scene,
    atlas: &Atlas,
    doc: &mut Value,
    textures: &[usize],
    channel: &[Option<u8>],
) {
    let mut holders = [const { Vec::new() }; 4];
    for (l, c) in channel.iter().enumerate() {
        if let Some(c) = c {
            holders[*c as usize].push(scene.lights[l].node_index);
        }
    }
    let channels: serde_json::Map<String, Value> = CHANNEL_NAMES
        .iter()
        .zip(&holders)
        .map(|(n, h)| (n.to_string(), json!(h)))
        .collect();
    for (i, inst) in scene.instances.iter().enumerate() {
        let rect = atlas.instances[i];
        let entry = json!({
            "index": textures[rect.page as usize],
            "texCoord": 1,
            "offset": [rect.min[0], rect.min[1]],
            "scale": [rect.max[0] - rect.min[0], rect.max[1] - rect.min[1]],
            "channels": channels,
        });
        let Some(mesh) = doc["nodes"][inst.node_index]["mesh"].as_u64() else {
            continue;
        };
        let materials: Vec<u64> = doc["meshes"][mesh as usize]["primitives"]
            .as_array()
            .map(|ps| ps.iter().filter_map(|p| p["material"].as_u64()).collect())
            .unwrap_or_default();
        for m in materials {
            let material = &mut doc["materials"][m as usize];
            if material["extensions"].get("MOZ_lightmap").is_none() {
                // A primitive the bake left alone keeps its shared material.
                continue;
            }
            if !material["extras"].is_object() {
                material["extras"] = json!({});
            }
            if !material["extras"]["radbake"].is_object() {
                material["extras"]["radbake"] = json!({});
            }
            material["extras"]["radbake"]["shadowmask"] = entry.clone();
        }
    }
}

/// Re-indexed primitives by (glTF mesh, primitive): (attributes, targets)
/// and the indices' accessor.
struct Primitives {
    data: HashMap<(usize, usize), (Value, Value)>,
    indices: HashMap<(usize, usize), usize>,
}

/// Step 4: every primitive re-indexed once per (mesh, primitive), with the
/// unwrap's vertices: attributes and morph targets copied per output
/// vertex, `TEXCOORD_1` from the unwrap.
fn reindex_primitives(
    scene: &Scene,
    atlas: &Atlas,
    doc: &Value,
    b: &mut Builder,
    view_offsets: &[usize],
    name: &str,
) -> Result<Primitives> {
    let mut out = Primitives {
        data: HashMap::new(),
        indices: HashMap::new(),
    };
    for (m, mesh) in scene.meshes.iter().enumerate() {
        let unwrap = &atlas.meshes[m];
        let gm = mesh.gltf_index;
        let prims = doc["meshes"][gm]["primitives"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        for (p, prim) in prims.iter().enumerate() {
            // Output triangles of this primitive and their output vertices.
            let mut remap: HashMap<u32, u32> = HashMap::new();
            let mut order: Vec<u32> = Vec::new();
            let mut indices: Vec<u32> = Vec::new();
            for (t, tri) in unwrap.triangles.iter().enumerate() {
                if mesh.triangle_primitive[t] as usize != p {
                    continue;
                }
                for &o in tri {
                    let id = *remap.entry(o).or_insert_with(|| {
                        order.push(o);
                        order.len() as u32 - 1
                    });
                    indices.push(id);
                }
            }
            if indices.is_empty() {
                continue;
            }
            let source: Vec<usize> = order
                .iter()
                .map(|&o| mesh.vertex_source[unwrap.xref[o as usize] as usize] as usize)
                .collect();
            let copy = Copy {
                doc,
                view_offsets,
                source: &source,
                location: format!("meshes[{gm}].primitives[{p}]"),
                name,
            };
            let mut attributes = serde_json::Map::new();
            if let Some(attrs) = prim["attributes"].as_object() {
                for (sem, acc) in attrs {
                    if sem == "TEXCOORD_1" {
                        continue;
                    }
                    let acc = acc.as_u64().ok_or_else(|| {
                        encode_error(name, format!("{}.attributes.{sem}", copy.location))
                    })? as usize;
                    attributes.insert(sem.clone(), json!(copy.attribute(b, acc, sem)?));
                }
            }
            let mut targets = Vec::new();
            if let Some(ts) = prim["targets"].as_array() {
                for t in ts {
                    let mut target = serde_json::Map::new();
                    if let Some(t) = t.as_object() {
                        for (sem, acc) in t {
                            let acc = acc.as_u64().unwrap_or(u64::MAX) as usize;
                            target.insert(sem.clone(), json!(copy.attribute(b, acc, sem)?));
                        }
                    }
                    targets.push(Value::Object(target));
                }
            }
            // TEXCOORD_1: the unwrap's UV in [0, 1] of the instance rectangle.
            let uv: Vec<u8> = order
                .iter()
                .flat_map(|&o| unwrap.uv[o as usize].to_array())
                .flat_map(f32::to_le_bytes)
                .collect();
            let view = b.view(&uv, None, Some(34962));
            b.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": order.len(), "type": "VEC2"}));
            attributes.insert("TEXCOORD_1".into(), json!(b.accessors.len() - 1));
            // Texture coordinate sets must be numbered from 0 without gaps.
            if !attributes.contains_key("TEXCOORD_0") {
                attributes.insert("TEXCOORD_0".into(), json!(b.accessors.len() - 1));
            }
            let idx: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
            let view = b.view(&idx, None, Some(34963));
            b.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}));
            out.indices.insert((gm, p), b.accessors.len() - 1);
            out.data
                .insert((gm, p), (Value::Object(attributes), Value::Array(targets)));
        }
    }
    Ok(out)
}

/// Copies a primitive's attributes per output vertex (step 4).
struct Copy<'a> {
    doc: &'a Value,
    view_offsets: &'a [usize],
    /// Output vertex → the primitive's own vertex.
    source: &'a [usize],
    location: String,
    name: &'a str,
}

impl Copy<'_> {
    /// Accessor `acc`'s elements for the output vertices, as a new accessor
    /// (tightly packed, 4-byte aligned; a float VEC3's bounds recomputed).
    fn attribute(&self, b: &mut Builder, acc: usize, semantic: &str) -> Result<usize> {
        let fail = |m: String| encode_error(self.name, m);
        let (data, elem, count) = accessor_elements(self.doc, &b.bin, self.view_offsets, acc)
            .ok_or_else(|| fail(format!("{}: accessor {acc} cannot be read", self.location)))?;
        let stride = elem.div_ceil(4) * 4;
        let mut bytes = vec![0u8; stride * self.source.len()];
        for (k, &s) in self.source.iter().enumerate() {
            if s >= count {
                return Err(fail(format!(
                    "{}.attributes.{semantic}: vertex {s} out of range",
                    self.location
                )));
            }
            bytes[k * stride..k * stride + elem].copy_from_slice(&data[s * elem..(s + 1) * elem]);
        }
        let view = b.view(&bytes, (stride != elem).then_some(stride), Some(34962));
        let mut a = b.accessors[acc].clone();
        let obj = a
            .as_object_mut()
            .ok_or_else(|| fail(format!("accessors[{acc}] is not an object")))?;
        obj.remove("sparse");
        obj.remove("byteOffset");
        obj.insert("bufferView".into(), json!(view));
        obj.insert("count".into(), json!(self.source.len()));
        if obj.contains_key("min") || semantic == "POSITION" {
            // Bounds of the elements actually kept (float VEC3 positions).
            if b.accessors[acc]["componentType"] == json!(5126)
                && b.accessors[acc]["type"] == json!("VEC3")
            {
                let (lo, hi) = vec3_bounds(&bytes, stride, self.source.len());
                obj.insert("min".into(), json!(lo));
                obj.insert("max".into(), json!(hi));
            } else {
                obj.remove("min");
                obj.remove("max");
            }
        }
        b.accessors.push(a);
        Ok(b.accessors.len() - 1)
    }
}

/// Component-wise bounds of `n` float VEC3 elements `stride` bytes apart.
fn vec3_bounds(bytes: &[u8], stride: usize, n: usize) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for k in 0..n {
        for c in 0..3 {
            let o = k * stride + 4 * c;
            let v = f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
            lo[c] = lo[c].min(v);
            hi[c] = hi[c].max(v);
        }
    }
    (lo, hi)
}

/// Step 5: per instance, its mesh (the original for the first instance,
/// copies after), with lightmapped copies of its materials.
fn lightmapped_instances(
    scene: &Scene,
    atlas: &Atlas,
    doc: &mut Value,
    prims: &Primitives,
    pages: &PageTextures,
) {
    let mut first_use: HashMap<usize, bool> = HashMap::new();
    let pristine = doc["meshes"].clone();
    for (i, inst) in scene.instances.iter().enumerate() {
        if !inst.lightmap {
            continue;
        }
        let mesh = &scene.meshes[inst.mesh as usize];
        let gm = mesh.gltf_index;
        let rect = atlas.instances[i];
        let mut mesh_json = doc["meshes"][gm].clone();
        if let Some(list) = mesh_json["primitives"].as_array_mut() {
            for (p, prim) in list.iter_mut().enumerate() {
                let Some((attrs, targets)) = prims.data.get(&(gm, p)) else {
                    continue;
                };
                prim["attributes"] = attrs.clone();
                if prim.get("targets").is_some() {
                    prim["targets"] = targets.clone();
                }
                prim["indices"] = json!(prims.indices[&(gm, p)]);
                prim["mode"] = json!(4);
                let mut material = match prim.get("material").and_then(Value::as_u64) {
                    Some(m) => doc["materials"][m as usize].clone(),
                    None => {
                        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0}})
                    }
                };
                if !material.is_object() {
                    material = json!({});
                }
                let page = rect.page as usize;
                let lightmap = json!({
                    "index": pages.texture[page],
                    "texCoord": 1,
                    "intensity": pages.intensity[i],
                    "extensions": {"KHR_texture_transform": {
                        "offset": [rect.min[0], rect.min[1]],
                        "scale": [rect.max[0] - rect.min[0], rect.max[1] - rect.min[1]],
                    }},
                });
                if !material["extensions"].is_object() {
                    material["extensions"] = json!({});
                }
                material["extensions"]["MOZ_lightmap"] = lightmap;
                prim["material"] = json!(push(doc, "materials", material));
            }
        }
        let index = if first_use.insert(gm, true).is_none() {
            doc["meshes"][gm] = mesh_json;
            gm
        } else {
            push(doc, "meshes", mesh_json)
        };
        doc["nodes"][inst.node_index]["mesh"] = json!(index);
    }
    // Nodes without a lightmap keep their mesh as it came, or a copy of it
    // where a lightmapped node re-indexed it.
    for inst in scene.instances.iter().filter(|i| !i.lightmap) {
        let gm = scene.meshes[inst.mesh as usize].gltf_index;
        let index = if first_use.insert(gm, true).is_none() {
            gm
        } else {
            push(doc, "meshes", pristine[gm].clone())
        };
        doc["nodes"][inst.node_index]["mesh"] = json!(index);
    }
}

/// Step 6: the packed buffer, views and accessors into the document, the
/// extensions declared, the generator named; the GLB container.
fn finish(mut doc: Value, mut b: Builder) -> Vec<u8> {
    b.align();
    doc["bufferViews"] = Value::Array(b.views);
    doc["accessors"] = Value::Array(b.accessors);
    doc["buffers"] = json!([{"byteLength": b.bin.len()}]);
    let mut used: Vec<Value> = doc["extensionsUsed"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    for ext in ["MOZ_lightmap", "KHR_texture_transform"] {
        if !used.contains(&json!(ext)) {
            used.push(json!(ext));
        }
    }
    doc["extensionsUsed"] = Value::Array(used);
    if let Some(asset) = doc["asset"].as_object_mut() {
        asset.insert(
            "generator".into(),
            json!(format!("radbake {}", env!("CARGO_PKG_VERSION"))),
        );
    }
    glb(&doc, &b.bin)
}

/// Appends `v` to the array `doc[key]` (created if missing); returns its index.
fn push(doc: &mut Value, key: &str, v: Value) -> usize {
    if !doc[key].is_array() {
        doc[key] = json!([]);
    }
    let a = doc[key].as_array_mut().expect("just made an array");
    a.push(v);
    a.len() - 1
}

/// A GLB container (glTF 2.0 §4.4): header, JSON chunk, BIN chunk.
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(doc).expect("JSON values serialise");
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut bin = bin.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
