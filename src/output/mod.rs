//! The bake's files: lightmap pages as linear float EXR and tone-mapped PNG
//! previews, and `report.json`. Every file is written to a temporary file in
//! the same folder and renamed over the target, so a killed bake never
//! leaves a half-written file where a good one was.

pub mod baked;
pub mod combine;
pub mod ktx2;
pub mod png8;
pub mod probes;
pub mod relight;
pub mod sdf;
pub mod shadowmask;

use crate::error::{Error, Result};
use crate::maps::lightmap::Lightmaps;
use crate::pipeline::report::Report;
use crate::scene::texture::linear_to_srgb;
pub use crate::util::files::{
    remove_stale_temporaries, remove_temporaries, write_atomic, write_bytes_atomic, write_exr_rgb,
    write_png,
};
use std::path::{Path, PathBuf};

/// Writes one page as a linear float RGB OpenEXR file.
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_exr(path: &Path, lightmaps: &Lightmaps, page: usize) -> Result<()> {
    write_exr_rgb(
        path,
        lightmaps.width,
        lightmaps.height,
        &lightmaps.pages[page],
    )
}

/// Writes one page as an 8-bit sRGB PNG preview, tone-mapped by Reinhard
/// (v / (1 + v)); for looking at, not for engines.
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_preview_png(path: &Path, lightmaps: &Lightmaps, page: usize) -> Result<()> {
    let values = &lightmaps.pages[page];
    let img = image::RgbImage::from_fn(lightmaps.width, lightmaps.height, |x, y| {
        let v = values[(y * lightmaps.width + x) as usize];
        let c = |c: f32| (linear_to_srgb((c / (1.0 + c)).clamp(0.0, 1.0)) * 255.0 + 0.5) as u8;
        image::Rgb([c(v.x), c(v.y), c(v.z)])
    });
    write_png(path, &img)
}

/// Writes the lightmap pages into `out_dir` (created if missing) as
/// `lightmap_<page>.exr` and `lightmap_<page>.png`; returns the paths written.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write_lightmaps(out_dir: &Path, lightmaps: &Lightmaps) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out_dir).map_err(|source| Error::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    // Stale temporaries of a killed bake (not this process's: its other
    // outputs may be being written alongside).
    remove_stale_temporaries(out_dir);
    let mut written = Vec::new();
    for page in 0..lightmaps.pages.len() {
        let exr = out_dir.join(format!("lightmap_{page}.exr"));
        write_exr(&exr, lightmaps, page)?;
        written.push(exr);
        let png = out_dir.join(format!("lightmap_{page}.png"));
        write_preview_png(&png, lightmaps, page)?;
        written.push(png);
    }
    Ok(written)
}

/// Writes the optional maps of a bake: directional pages
/// `lightmap_<page>_sh_{a,x,y,z}.exr` (irradiance / π for a normal n =
/// a + n_x x + n_y y + n_z z, world space), each also as
/// `lightmap_<page>_sh_{a,x,y,z}.ktx2` (`R16G16B16A16_SFLOAT`, signed;
/// unless `--ktx2 off`), and AO pages `ao_<page>.png`
/// (8-bit linear, 1 = unoccluded). Returns the paths written.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write_extra_maps(out_dir: &Path, bake: &crate::Bake) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out_dir).map_err(|source| Error::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    if let Some(sh) = &bake.maps.sh {
        for (lm, name) in sh.iter().zip(["a", "x", "y", "z"]) {
            for page in 0..lm.pages.len() {
                let path = out_dir.join(format!("lightmap_{page}_sh_{name}.exr"));
                write_exr(&path, lm, page)?;
                written.push(path);
                if bake.config.ktx2 != crate::config::Ktx2Mode::Off {
                    // Signed (the linear coefficients): half floats.
                    let path = out_dir.join(format!("lightmap_{page}_sh_{name}.ktx2"));
                    let bytes = ktx2::ktx2_rgba16f_zstd(
                        lm.width,
                        lm.height,
                        &lm.pages[page],
                        ktx2::ZSTD_LEVEL,
                    );
                    write_bytes_atomic(&path, &bytes)?;
                    written.push(path);
                }
            }
        }
    }
    if let Some(ao) = &bake.maps.ao {
        for page in 0..ao.pages.len() {
            let path = out_dir.join(format!("ao_{page}.png"));
            let img = image::GrayImage::from_fn(ao.width, ao.height, |x, y| {
                image::Luma([(ao.pages[page][(y * ao.width + x) as usize]
                    .x
                    .clamp(0.0, 1.0)
                    * 255.0)
                    .round() as u8])
            });
            write_png(&path, &img)?;
            written.push(path);
        }
    }
    Ok(written)
}

/// Writes `lightmap_<page>_debug.png` per page (RGBA8, not colour data):
/// RGB a colour hashed from the texel's patch, alpha 255 for a valid texel,
/// 128 for an invalid one (inside or under geometry, filled from its
/// neighbours), 0 where there is no texel. The preview's `patches` and
/// `invalid texels` views read it.
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_debug_maps(out_dir: &Path, bake: &crate::Bake) -> Result<Vec<PathBuf>> {
    let lm = &bake.maps.lightmaps;
    let texels = &bake.texels;
    let mut patch_of = vec![u32::MAX; texels.len()];
    for i in 0..bake.patches.len() {
        for &t in bake.patches.texels_of(i) {
            patch_of[t as usize] = i as u32;
        }
    }
    let mut written = Vec::new();
    for page in 0..lm.pages.len() {
        let mut img = image::RgbaImage::new(lm.width, lm.height);
        for (t, &patch) in patch_of.iter().enumerate() {
            if texels.page[t] as usize != page {
                continue;
            }
            let [x, y] = texels.xy[t];
            // SplitMix-style hash of the patch id to a bright colour.
            let mut h = (patch as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
            h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            h ^= h >> 31;
            let c = |k: u32| 64 + ((h >> (8 * k)) & 0xff) as u8 / 4 * 3;
            let alpha = if bake.transport.valid.get(t).copied().unwrap_or(true) {
                255
            } else {
                128
            };
            img.put_pixel(x, y, image::Rgba([c(0), c(1), c(2), alpha]));
        }
        let path = out_dir.join(format!("lightmap_{page}_debug.png"));
        write_png(&path, &img)?;
        written.push(path);
    }
    Ok(written)
}

/// Writes `report.json` into `out_dir` (written last by the CLI, so its
/// presence marks a finished bake).
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write_report(out_dir: &Path, report: &Report) -> Result<PathBuf> {
    std::fs::create_dir_all(out_dir).map_err(|source| Error::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let json = out_dir.join("report.json");
    let text = serde_json::to_vec_pretty(report).map_err(|e| Error::Encode {
        path: json.clone(),
        message: e.to_string(),
    })?;
    write_bytes_atomic(&json, &text)?;
    Ok(json)
}

/// Writes a progressive solve's snapshot ([`crate::Snapshot`]) as a baked
/// `.glb` at `path` (atomically): the scene with these lightmaps, as
/// `write_engine_outputs` writes the final one, for `preview --watch`.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write_snapshot_glb(
    path: &Path,
    scene: &crate::scene::Scene,
    atlas: &crate::layout::atlas::Atlas,
    lightmaps: &Lightmaps,
) -> Result<()> {
    let encoded: Vec<png8::EncodedPage> = (0..lightmaps.pages.len())
        .map(|page| png8::encode_page(lightmaps, atlas, page))
        .collect();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let glb = baked::baked_glb(scene, atlas, &encoded, None, &name)?;
    write_bytes_atomic(path, &glb)
}

/// Writes each lightmap page's 8-bit PNG (`encoded`) and, unless
/// `ktx2 = "off"`, its KTX2 file, adding their paths to `written`; returns
/// the manifest's `pages` entries (with the directional pages'
/// names where the bake has them, which `write_extra_maps` writes).
fn write_pages(
    out_dir: &Path,
    bake: &crate::Bake,
    encoded: &[png8::EncodedPage],
    written: &mut Vec<PathBuf>,
) -> Result<Vec<serde_json::Value>> {
    let lightmaps = &bake.maps.lightmaps;
    let mut pages = Vec::new();
    for (page, e) in encoded.iter().enumerate() {
        let name = format!("lightmap_{page}_srgb.png");
        write_bytes_atomic(&out_dir.join(&name), &e.png)?;
        written.push(out_dir.join(&name));
        use crate::config::Ktx2Mode;
        let mode = bake.config.ktx2;
        let ktx2 = (mode != Ktx2Mode::Off).then(|| format!("lightmap_{page}.ktx2"));
        if let Some(k) = &ktx2 {
            let (w, h, texels) = (lightmaps.width, lightmaps.height, &lightmaps.pages[page]);
            let bytes = if mode == Ktx2Mode::Bc6h {
                ktx2::ktx2_bc6h_zstd(w, h, texels, ktx2::ZSTD_LEVEL)
            } else {
                let packed: Vec<u32> = texels.iter().map(|v| ktx2::rgb9e5(*v)).collect();
                ktx2::ktx2_rgb9e5_zstd([w, h, 0], &packed, ktx2::ZSTD_LEVEL)
            };
            write_bytes_atomic(&out_dir.join(k), &bytes)?;
            written.push(out_dir.join(k));
        }
        pages.push(serde_json::json!({
            "ktx2": ktx2,
            "ktx2_format": mode.name(),
            "page": page,
            "exr": format!("lightmap_{page}.exr"),
            "png": name,
            "png_encoding": "srgb, dithered; one scale per instance rectangle (instances[].png_scale), the page's largest value outside them",
            "png_page_scale": e.page_scale,
        }));
        if bake.maps.sh.is_some() {
            // The directional pages `write_extra_maps` writes.
            let ktx2_on = mode != Ktx2Mode::Off;
            let sh: serde_json::Map<String, serde_json::Value> = ["a", "x", "y", "z"]
                .iter()
                .map(|c| {
                    let file = |ext: &str| format!("lightmap_{page}_sh_{c}.{ext}");
                    let entry = serde_json::json!({
                        "exr": file("exr"),
                        "ktx2": ktx2_on.then(|| file("ktx2")),
                        "ktx2_format": ktx2_on.then_some("rgba16f"),
                    });
                    (c.to_string(), entry)
                })
                .collect();
            pages[page]["sh"] = serde_json::Value::Object(sh);
        }
    }
    Ok(pages)
}

/// Writes each light layer's pages (`lightmap_<page>_<layer>.exr`, and
/// `.ktx2` in RGB9E5 unless `ktx2 = "off"`) and probes
/// ([`probes::write_layer`]), adding their paths to `written`; returns the
/// manifest's `layers` entry, `None` for a bake without layers.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
fn write_layers(
    out_dir: &Path,
    bake: &crate::Bake,
    written: &mut Vec<PathBuf>,
) -> Result<Option<serde_json::Value>> {
    let Some(layers) = &bake.layers else {
        return Ok(None);
    };
    let ktx2_on = bake.config.ktx2 != crate::config::Ktx2Mode::Off;
    let mut entries = Vec::new();
    for (k, (name, lm)) in layers.names.iter().zip(&bake.maps.layers).enumerate() {
        let mut pages = Vec::new();
        for page in 0..lm.pages.len() {
            let exr = format!("lightmap_{page}_{name}.exr");
            write_exr(&out_dir.join(&exr), lm, page)?;
            written.push(out_dir.join(&exr));
            let ktx2 = ktx2_on.then(|| format!("lightmap_{page}_{name}.ktx2"));
            if let Some(file) = &ktx2 {
                let packed: Vec<u32> = lm.pages[page].iter().map(|v| ktx2::rgb9e5(*v)).collect();
                let bytes =
                    ktx2::ktx2_rgb9e5_zstd([lm.width, lm.height, 0], &packed, ktx2::ZSTD_LEVEL);
                write_bytes_atomic(&out_dir.join(file), &bytes)?;
                written.push(out_dir.join(file));
            }
            pages.push(serde_json::json!({ "page": page, "exr": exr, "ktx2": ktx2 }));
        }
        let probes = match (
            &bake.probes,
            bake.probes.as_ref().and_then(|p| p.layers.get(k)),
        ) {
            (Some(p), Some(sh_set)) => {
                let (files, entry) = probes::write_layer(out_dir, p, (name, sh_set))?;
                written.extend(files);
                entry
            }
            _ => serde_json::Value::Null,
        };
        let (lights, materials, sky) = layers.members(bake.scene, k);
        entries.push(serde_json::json!({
            "name": name,
            "lights": lights,
            "materials": materials,
            "sky": sky,
            "pages": pages,
            "probes": probes,
        }));
    }
    Ok(Some(serde_json::Value::Array(entries)))
}

/// Writes the engine outputs into `out_dir`: `<stem>.baked.glb` (see
/// [`baked`]), `lightmap_<page>_srgb.png` (value / scale, sRGB-encoded,
/// the same images the .glb embeds) and `manifest.json` (per instance: the
/// lightmap files, `uv_rect` in Bevy's convention, the PNG scale and the
/// `MOZ_lightmap` intensity), and the probes' files ([`probes::write`])
/// listed in the manifest with their transforms. Returns the paths written.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write_engine_outputs(
    out_dir: &Path,
    stem: &str,
    bake: &crate::Bake,
) -> Result<Vec<PathBuf>> {
    let (scene, atlas, lightmaps) = (bake.scene, &bake.atlas, &bake.maps.lightmaps);
    std::fs::create_dir_all(out_dir).map_err(|source| Error::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    let encoded: Vec<png8::EncodedPage> = (0..lightmaps.pages.len())
        .map(|page| png8::encode_page(lightmaps, atlas, page))
        .collect();
    let pages = write_pages(out_dir, bake, &encoded, &mut written)?;
    let scale_of = |i: usize| encoded.iter().find_map(|e| e.scales[i]).unwrap_or(1.0);
    let mask = match &bake.shadowmask {
        Some(m) => {
            let ktx2_on = bake.config.ktx2 != crate::config::Ktx2Mode::Off;
            let w = shadowmask::write(out_dir, m, &scene.lights, ktx2_on)?;
            written.extend(w.paths.iter().cloned());
            Some((m, w))
        }
        None => None,
    };
    let glb_name = format!("{stem}.baked.glb");
    if scene.source.is_some() {
        let masks = mask.as_ref().map(|(m, w)| baked::Masks {
            png: &w.png,
            channel: &m.channel,
        });
        let glb = baked::baked_glb(scene, atlas, &encoded, masks, &glb_name)?;
        write_bytes_atomic(&out_dir.join(&glb_name), &glb)?;
        written.push(out_dir.join(&glb_name));
    }
    let instances: Vec<serde_json::Value> = scene
        .instances
        .iter()
        .enumerate()
        .map(|(i, inst)| {
            let r = atlas.instances[i];
            serde_json::json!({
                "node": inst.node,
                "node_index": inst.node_index,
                "mesh": scene.meshes[inst.mesh as usize].name,
                "page": r.page,
                "uv_rect": [r.min[0], r.min[1], r.max[0], r.max[1]],
                "png_scale": scale_of(i),
                "moz_lightmap_intensity": std::f32::consts::PI * scale_of(i),
                "lightmap": inst.lightmap,
            })
        })
        .collect();
    let probes_entry = match &bake.probes {
        Some(p) => {
            let (files, json) = probes::write(out_dir, p)?;
            written.extend(files);
            serde_json::json!({
                "json": "probes.json",
                "binary": "probes.bin",
                "count": p.len(),
                "invalid": p.invalid(),
                "volumes": json["volumes"],
            })
        }
        None => serde_json::Value::Null,
    };
    let sdf_entry = match &bake.sdf {
        Some(field) => {
            let path = out_dir.join("sdf.ktx2");
            sdf::write_ktx2(&path, field, bake.config.sdf_format)?;
            written.push(path);
            sdf::manifest_entry(field, None, Some("sdf.ktx2".into()), bake.config.sdf_format)
        }
        None => serde_json::Value::Null,
    };
    let manifest = serde_json::json!({
        "radbake_version": env!("CARGO_PKG_VERSION"),
        "convention": "a texel holds incident irradiance / pi (linear RGB): outgoing radiance = albedo * texel + emission",
        "uv": "TEXCOORD_1 in [0,1] per instance; atlas uv = mix(uv_rect.xy, uv_rect.zw, TEXCOORD_1); (0,0) is the top-left texel corner",
        "png_decoding": "value = srgb_to_linear(png) * png_scale of the instance whose uv_rect holds the texel",
        "baked_gltf": if scene.source.is_some() { serde_json::json!(glb_name) } else { serde_json::Value::Null },
        "pages": pages,
        "instances": instances,
        "lights": crate::pipeline::report::LightReport::all(&scene.lights, bake.shadowmask.as_ref().map(|m| m.channel.as_slice())),
        "probes": probes_entry,
        "shadowmask": mask.map_or(serde_json::Value::Null, |(_, w)| w.manifest),
        "sdf": sdf_entry,
    });
    let mut manifest = manifest;
    if let Some(layers) = write_layers(out_dir, bake, &mut written)? {
        manifest["layers"] = layers;
        manifest["layer_convention"] = serde_json::json!(
            "each layer's pages and probes hold its lights' share of the bake, in the units of the combined files; the bake at weights w is the sum over layers of w (RGB) times the layer; the combined pages and the .glb are that sum at weight 1"
        );
    }
    if let Some(live) = &bake.live {
        let path = out_dir.join(LIVE_FILE);
        write_bytes_atomic(&path, &live.to_bytes())?;
        written.push(path);
        manifest["live"] = live_entry(live);
    }
    let path = out_dir.join("manifest.json");
    write_json(&path, &manifest)?;
    written.push(path);
    Ok(written)
}

/// The live bake's file ([`radbake_live::format`]).
pub const LIVE_FILE: &str = "live.bin";

/// The manifest's `live` entry: the file, the layer its solution
/// replaces, the live lights as baked, the sky's layer.
fn live_entry(live: &radbake_live::LiveData) -> serde_json::Value {
    let h = &live.header;
    serde_json::json!({
        "file": LIVE_FILE,
        "version": h.version,
        "layer": h.layer,
        "grid": h.grid,
        "patches": h.patches,
        "lights": h.lights,
        "sky": h.sky,
        "convention": "the live layer's pages are the live lights' bounced light (irradiance / pi), re-solved at run time for a direction (towards the light, y up) and an irradiance (W/m2); the engine draws their direct light",
    })
}

/// Writes `value` as pretty-printed JSON, atomically.
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_vec_pretty(value).map_err(|e| Error::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_bytes_atomic(path, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_keeps_the_old_file() {
        let dir = std::env::temp_dir().join(format!("radbake-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("a.txt");
        write_bytes_atomic(&target, b"good").unwrap();
        let r = write_atomic(&target, |tmp| {
            std::fs::write(tmp, b"half").unwrap();
            Err(Error::Limit("interrupted".into()))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&target).unwrap(), b"good");
        let leftovers = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(leftovers, 1, "temporary file left behind");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
