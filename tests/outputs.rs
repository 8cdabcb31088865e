//! Engine-facing outputs and build-step behaviour: the baked .glb round
//! trip, the manifest, the PNG encoding, determinism across runs and thread
//! counts, incremental re-runs, presets and config layering, JSON progress.

mod common;

use common::*;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

fn radbake(args: &[&str], threads: Option<&str>) -> (i32, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_radbake"));
    cmd.args(args);
    if let Some(t) = threads {
        cmd.env("RAYON_NUM_THREADS", t);
    }
    let out = cmd.output().expect("radbake runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// GLB → (JSON, BIN).
fn read_glb(path: &Path) -> (Value, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[0..4], b"glTF");
    let jlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + jlen]).unwrap();
    let blen = u32::from_le_bytes(bytes[20 + jlen..24 + jlen].try_into().unwrap()) as usize;
    (doc, bytes[28 + jlen..28 + jlen + blen].to_vec())
}

fn bake_cornell(out: &Path, extra: &[&str], threads: Option<&str>) {
    let scene = scene_path("cornell_box.gltf");
    let mut args = vec![
        "bake",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--texels-per-meter",
        "40",
        "-q",
    ];
    args.extend_from_slice(extra);
    let (code, err) = radbake(&args, threads);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn baked_glb_round_trips() {
    let dir = temp_dir("outputs-glb");
    bake_cornell(&dir, &[], None);
    let glb = dir.join("cornell_box.baked.glb");
    // Our own importer reads it back, with TEXCOORD_1 on every mesh.
    let scene = radbake::scene::load(&glb, &Default::default()).unwrap();
    assert_eq!(scene.instances.len(), 8);
    assert!(scene.meshes.iter().all(|m| m.uv1.is_some()));
    let (doc, _) = read_glb(&glb);
    let manifest = json(&dir.join("manifest.json"));
    let used: Vec<&str> = doc["extensionsUsed"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(used.contains(&"MOZ_lightmap") && used.contains(&"KHR_texture_transform"));
    // Every node's primitives reference a lightmap whose transform is the manifest's uv_rect.
    for inst in manifest["instances"].as_array().unwrap() {
        let node = &doc["nodes"][inst["node_index"].as_u64().unwrap() as usize];
        let mesh = &doc["meshes"][node["mesh"].as_u64().unwrap() as usize];
        let rect: Vec<f64> = inst["uv_rect"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        for prim in mesh["primitives"].as_array().unwrap() {
            assert!(prim["attributes"]["TEXCOORD_1"].is_u64());
            let m = &doc["materials"][prim["material"].as_u64().unwrap() as usize];
            let lm = &m["extensions"]["MOZ_lightmap"];
            assert_eq!(lm["texCoord"], 1);
            let t = &lm["extensions"]["KHR_texture_transform"];
            assert!((t["offset"][0].as_f64().unwrap() - rect[0]).abs() < 1e-6);
            assert!((t["scale"][1].as_f64().unwrap() - (rect[3] - rect[1])).abs() < 1e-6);
            // One scale per instance: its own intensity, π × its png_scale.
            let intensity = lm["intensity"].as_f64().unwrap();
            assert!((intensity - inst["moz_lightmap_intensity"].as_f64().unwrap()).abs() < 1e-4);
            let scale = inst["png_scale"].as_f64().unwrap();
            assert!((intensity - std::f64::consts::PI * scale).abs() < 1e-4);
        }
    }
    // The material's own settings survive (base colour of the red wall).
    let red = doc["materials"]
        .as_array()
        .unwrap()
        .iter()
        .any(|m| m["name"] == "red" && m["extensions"]["MOZ_lightmap"].is_object());
    assert!(red, "lightmapped copy of material `red` missing");
}

/// The sRGB PNG decodes back to the EXR's values: srgb⁻¹(png) × the scale
/// of the instance whose rectangle holds the texel (the page's outside
/// them), within 8-bit quantisation and the dither (one code step).
#[test]
fn png_encoding_decodes_to_the_exr() {
    let dir = temp_dir("outputs-png");
    bake_cornell(&dir, &[], None);
    let manifest = json(&dir.join("manifest.json"));
    let page = &manifest["pages"][0];
    let page_scale = page["png_page_scale"].as_f64().unwrap() as f32;
    let rects: Vec<([f64; 4], f32)> = manifest["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            let r = &i["uv_rect"];
            let f = |k: usize| r[k].as_f64().unwrap();
            (
                [f(0), f(1), f(2), f(3)],
                i["png_scale"].as_f64().unwrap() as f32,
            )
        })
        .collect();
    let png = image::open(dir.join(page["png"].as_str().unwrap()))
        .unwrap()
        .to_rgb8();
    let (w, px) = &read_exr(&dir.join("lightmap_0.exr"));
    let (pw, ph) = (png.width() as f64, png.height() as f64);
    let mut worst = 0.0f32;
    let mut distinct = std::collections::BTreeSet::new();
    for ((x, y, p), exr_px) in png.enumerate_pixels().zip(px) {
        let (u, v) = ((x as f64 + 0.5) / pw, (y as f64 + 0.5) / ph);
        let scale = rects
            .iter()
            .find(|(r, _)| u >= r[0] && u < r[2] && v >= r[1] && v < r[3])
            .map_or(page_scale, |(_, s)| *s);
        distinct.insert(scale.to_bits());
        for (&code8, &want) in p.0.iter().zip(exr_px) {
            // The exact (fractional) sRGB code of the EXR's value.
            let exact = radbake::scene::texture::linear_to_srgb((want / scale).min(1.0)) * 255.0;
            worst = worst.max((code8 as f32 - exact).abs());
        }
    }
    assert_eq!(png.width() as usize, *w);
    // Rounding after a dither of ±½ code: under one code.
    assert!(worst < 1.0 + 1e-3, "PNG off the EXR by {worst} codes");
    assert!(
        distinct.len() >= 8,
        "one scale per instance: {} scales",
        distinct.len()
    );
}

/// Same inputs and settings: byte-identical lightmaps, .glb and manifest on
/// 1 and 2 threads and across runs; report.json identical but for timings.
#[test]
fn outputs_are_deterministic_across_runs_and_threads() {
    let root = temp_dir("outputs-determinism");
    // The Cornell box and a textured scene.
    let textured = root.join("textured.gltf");
    {
        let mut b = GltfBuilder::default();
        let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let m = b.mesh(&p, &i, Some(0));
        b.node("floor", m);
        let (p, i) = quad([0.0, 0.6, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.3]);
        let m = b.mesh(&p, &i, Some(1));
        b.node("lamp", m);
        b.material([1.0; 3], [0.0; 3]);
        b.material([0.0; 3], [4.0; 3]);
        let mut doc = b.json();
        let img = image::RgbaImage::from_fn(8, 8, |x, y| {
            image::Rgba([(x * 30) as u8, (y * 30) as u8, 200, 255])
        });
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        std::fs::write(root.join("checker.png"), &png).unwrap();
        doc["images"] = serde_json::json!([{"uri": "checker.png"}]);
        doc["textures"] = serde_json::json!([{"source": 0}]);
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
            serde_json::json!({"index": 0});
        std::fs::write(&textured, serde_json::to_vec(&doc).unwrap()).unwrap();
    }
    for (k, scene) in [scene_path("cornell_box.gltf"), textured]
        .iter()
        .enumerate()
    {
        let runs: Vec<_> = [("1", "a"), ("2", "b"), ("2", "c")]
            .iter()
            .map(|(threads, tag)| {
                let out = root.join(format!("{k}{tag}"));
                let s = scene.to_str().unwrap();
                let (code, err) = radbake(
                    &[
                        "bake",
                        s,
                        "--out",
                        out.to_str().unwrap(),
                        "--texels-per-meter",
                        "40",
                        "-q",
                    ],
                    Some(threads),
                );
                assert_eq!(code, 0, "{err}");
                out
            })
            .collect();
        let mut files: Vec<String> = std::fs::read_dir(&runs[0])
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        files.sort();
        assert!(files.iter().any(|f| f.ends_with(".baked.glb")), "{files:?}");
        for f in &files {
            let a = std::fs::read(runs[0].join(f)).unwrap();
            for other in &runs[1..] {
                let b = std::fs::read(other.join(f)).unwrap();
                if f == "report.json" {
                    let strip = |bytes: &[u8]| {
                        let mut v: Value = serde_json::from_slice(bytes).unwrap();
                        v.as_object_mut().unwrap().remove("stages");
                        v
                    };
                    assert_eq!(strip(&a), strip(&b), "report.json differs beyond timings");
                } else {
                    assert!(
                        a == b,
                        "{f} differs between {} and {}",
                        runs[0].display(),
                        other.display()
                    );
                }
            }
        }
    }
}

#[test]
fn unchanged_rerun_is_up_to_date_and_force_rebakes() {
    let dir = temp_dir("outputs-incremental");
    bake_cornell(&dir, &[], None);
    let scene = scene_path("cornell_box.gltf");
    let args = [
        "bake",
        scene.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--texels-per-meter",
        "40",
    ];
    let (code, err) = radbake(&args, None);
    assert_eq!(code, 0);
    assert!(err.contains("up to date"), "{err}");
    // A changed setting re-bakes.
    let mut changed = args.to_vec();
    changed.extend(["--seed", "7"]);
    let (code, err) = radbake(&changed, None);
    assert_eq!(code, 0);
    assert!(err.contains("baked"), "{err}");
    let mut forced = changed.clone();
    forced.push("--force");
    let (_, err) = radbake(&forced, None);
    assert!(err.contains("baked"), "{err}");
    // A missing output re-bakes.
    std::fs::remove_file(dir.join("manifest.json")).unwrap();
    let (_, err) = radbake(&changed, None);
    assert!(
        err.contains("baked") && dir.join("manifest.json").is_file(),
        "{err}"
    );
}

#[test]
fn presets_config_and_flags_layer() {
    let dir = temp_dir("outputs-layers");
    std::fs::write(
        dir.join("bake.toml"),
        "rays_per_patch = 100\ntexels_per_meter = 30\n",
    )
    .unwrap();
    let cfg = dir.join("bake.toml");
    let scene = scene_path("cornell_box.gltf");
    let out = dir.join("out");
    let (code, err) = radbake(
        &[
            "bake",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--preset",
            "production",
            "--config",
            cfg.to_str().unwrap(),
            "--texels-per-meter",
            "20",
            "--direct-samples",
            "32",
            "-q",
        ],
        None,
    );
    assert_eq!(code, 0, "{err}");
    let s = &json(&dir.join("out/report.json"))["settings"];
    assert_eq!(s["rays_per_patch"], 100, "config file over preset");
    assert_eq!(s["texels_per_meter"], 20.0, "flag over config file");
    assert_eq!(s["direct_samples"], 32, "flag over preset");
    assert_eq!(s["patch_texels"], 2, "preset over defaults");
}

#[test]
fn json_progress_lines_parse() {
    let dir = temp_dir("outputs-progress");
    let scene = scene_path("cornell_box.gltf");
    let (code, err) = radbake(
        &[
            "bake",
            scene.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--texels-per-meter",
            "20",
            "--progress",
            "json",
            "-q",
        ],
        None,
    );
    assert_eq!(code, 0, "{err}");
    let lines: Vec<Value> = err
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|_| panic!("not JSON: {l}")))
        .collect();
    let stages: std::collections::BTreeSet<&str> =
        lines.iter().map(|v| v["stage"].as_str().unwrap()).collect();
    for s in [
        "unwrap",
        "texels",
        "form_factors",
        "direct",
        "solve",
        "lightmaps",
    ] {
        assert!(stages.contains(s), "no progress for {s}: {stages:?}");
    }
    for v in &lines {
        assert!(v["done"].is_u64() && v["total"].is_u64() && v["elapsed"].is_f64());
    }
}

/// Animations, extras and unknown extensions survive the round trip.
#[test]
fn animations_and_extras_survive() {
    let dir = temp_dir("outputs-animation");
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("lamp", m);
    let input = b.scalars(&[0.0, 1.0]);
    // Output: translations as VEC3 (not a vertex attribute: drop the target).
    let output = b.vec3(&[[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]);
    let mut doc = b.json();
    let view = doc["accessors"][output]["bufferView"].as_u64().unwrap() as usize;
    doc["bufferViews"][view]
        .as_object_mut()
        .unwrap()
        .remove("target");
    doc["animations"] = serde_json::json!([{"name": "bob", "samplers": [{"input": input, "output": output}], "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}]}]);
    doc["nodes"][0]["extras"] = serde_json::json!({"game": {"spawn": true}});
    doc["nodes"][0]["extensions"] = serde_json::json!({"EXT_made_up": {"answer": 42}});
    doc["extensionsUsed"] = serde_json::json!(["EXT_made_up"]);
    let path = dir.join("anim.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let out = dir.join("out");
    let (code, err) = radbake(
        &[
            "bake",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--texels-per-meter",
            "20",
            "-q",
        ],
        None,
    );
    assert_eq!(code, 0, "{err}");
    let (baked, bin) = read_glb(&out.join("anim.baked.glb"));
    assert_eq!(baked["animations"][0]["name"], "bob");
    assert_eq!(
        baked["animations"][0]["channels"],
        doc["animations"][0]["channels"]
    );
    assert_eq!(baked["nodes"][0]["extras"], doc["nodes"][0]["extras"]);
    assert_eq!(baked["nodes"][0]["extensions"]["EXT_made_up"]["answer"], 42);
    // The animation's keyframe times still read 0 and 1 from the packed buffer.
    let acc = &baked["accessors"][input];
    let view = &baked["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let off = view["byteOffset"].as_u64().unwrap() as usize
        + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
    let t1 = f32::from_le_bytes(bin[off + 4..off + 8].try_into().unwrap());
    assert_eq!(t1, 1.0);
}

/// An EXR page: (width, RGB pixels).
fn read_exr(path: &Path) -> (usize, Vec<[f32; 3]>) {
    exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .unwrap()
    .layer_data
    .channel_data
    .pixels
}

/// `lightmap_<page>.ktx2` (RGB9E5, for Bevy) read back with the `ktx2`
/// crate: a 2D image of the page's size whose decoded texels are the EXR's
/// within RGB9E5's quantisation (half a step of the shared exponent: at
/// most the texel's largest channel / 512). `--ktx2 off` writes none.
#[test]
fn ktx2_pages_decode_to_the_exr() {
    let dir = temp_dir("outputs-ktx2");
    bake_cornell(&dir, &[], None);
    let manifest = json(&dir.join("manifest.json"));
    let name = manifest["pages"][0]["ktx2"].as_str().unwrap().to_owned();
    let bytes = std::fs::read(dir.join(&name)).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).unwrap();
    let h = reader.header();
    assert_eq!(h.format, Some(ktx2::Format::E5B9G9R9_UFLOAT_PACK32));
    assert_eq!(h.pixel_depth, 0, "a 2D texture");
    assert_eq!(
        h.supercompression_scheme,
        Some(ktx2::SupercompressionScheme::Zstandard)
    );
    let level = reader.levels().next().unwrap();
    let data = zstd::bulk::decompress(level.data, 1 << 28).unwrap();
    let (w, px) = &read_exr(&dir.join("lightmap_0.exr"));
    assert_eq!(h.pixel_width as usize, *w);
    assert_eq!(data.len(), px.len() * 4);
    assert_eq!(level.uncompressed_byte_length as usize, data.len());
    let mut worst = 0.0f32;
    for (chunk, want) in data.chunks_exact(4).zip(px) {
        // The Vulkan specification's decode, written here again.
        let p = u32::from_le_bytes(chunk.try_into().unwrap());
        let scale = 2f32.powi((p >> 27) as i32 - 15 - 9);
        let got = [p & 0x1ff, (p >> 9) & 0x1ff, (p >> 18) & 0x1ff].map(|m| m as f32 * scale);
        let peak = want.iter().cloned().fold(0.0f32, f32::max);
        for (g, e) in got.iter().zip(want) {
            worst = worst.max((g - e).abs() / (peak / 512.0).max(1e-12));
        }
    }
    assert!(
        worst <= 1.0 + 1e-3,
        "RGB9E5 off the EXR by {worst} × max/512"
    );
    let off = temp_dir("outputs-ktx2-off");
    bake_cornell(&off, &["--ktx2", "off"], None);
    assert!(!off.join("lightmap_0.ktx2").exists());
    assert!(json(&off.join("manifest.json"))["pages"][0]["ktx2"].is_null());
}

/// A one-level KTX2 file of `format`, Zstandard supercompressed, read
/// with the `ktx2` crate: its header and its level decompressed (checked
/// against the level index's uncompressed length).
fn zstd_ktx2(path: &Path, format: ktx2::Format) -> (ktx2::Header, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).unwrap();
    let h = reader.header();
    assert_eq!(h.format, Some(format), "{}", path.display());
    assert_eq!(
        h.supercompression_scheme,
        Some(ktx2::SupercompressionScheme::Zstandard)
    );
    let level = reader.levels().next().unwrap();
    let data = zstd::bulk::decompress(level.data, 1 << 28).unwrap();
    assert_eq!(level.uncompressed_byte_length as usize, data.len());
    (h, data)
}

/// `--ktx2 bc6h`: `lightmap_<page>.ktx2` in `BC6H_UFLOAT_BLOCK` (Zstandard
/// supercompressed), read back with the `ktx2` crate and decoded by
/// `bcdec_rs` (a port of bcdec, sharing nothing with the encoder). The
/// atlas is block aligned (page sizes multiples of 4). BC6H is lossy where
/// a 4 × 4 block holds a sharp light edge (this page is small, 40 texels/m,
/// so many blocks do): measured RMSE 3.5 % of the page's mean, the worst
/// channel at 0.75 of the bound. Bounds: RMSE at most 5 % of the mean,
/// every channel within 35 % of its texel's largest channel plus 2 % of
/// the page's mean. The manifest names the format.
#[test]
fn ktx2_bc6h_pages_decode_to_the_exr() {
    let dir = temp_dir("outputs-ktx2-bc6h");
    bake_cornell(&dir, &["--ktx2", "bc6h"], None);
    let manifest = json(&dir.join("manifest.json"));
    assert_eq!(manifest["pages"][0]["ktx2_format"], "bc6h");
    let name = manifest["pages"][0]["ktx2"].as_str().unwrap().to_owned();
    let (h, data) = zstd_ktx2(&dir.join(&name), ktx2::Format::BC6H_UFLOAT_BLOCK);
    let (w, px) = &read_exr(&dir.join("lightmap_0.exr"));
    let (w, hgt) = (*w, px.len() / *w);
    assert_eq!((h.pixel_width as usize, h.pixel_height as usize), (w, hgt));
    assert!(
        w % 4 == 0 && hgt % 4 == 0,
        "BC6H page {w} × {hgt} is not block aligned"
    );
    let (bw, bh) = (w.div_ceil(4), hgt.div_ceil(4));
    assert_eq!(data.len(), bw * bh * 16);
    let mut decoded = vec![[0f32; 3]; w * hgt];
    for by in 0..bh {
        for bx in 0..bw {
            let block = &data[(by * bw + bx) * 16..][..16];
            let mut out = [0f32; 4 * 4 * 3];
            bcdec_rs::bc6h_float(block, &mut out, 4 * 3, false);
            for y in 0..4 {
                for x in 0..4 {
                    let (px_x, px_y) = (bx * 4 + x, by * 4 + y);
                    if px_x < w && px_y < hgt {
                        let o = &out[(y * 4 + x) * 3..][..3];
                        decoded[px_y * w + px_x] = [o[0], o[1], o[2]];
                    }
                }
            }
        }
    }
    let mean = px
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0)
        .sum::<f64>()
        / px.len() as f64;
    let (mut sq, mut worst) = (0f64, 0f64);
    for (got, want) in decoded.iter().zip(px) {
        let peak = want.iter().cloned().fold(0.0f32, f32::max) as f64;
        for c in 0..3 {
            let e = (got[c] - want[c]) as f64;
            sq += e * e;
            worst = worst.max(e.abs() / (0.35 * peak + 0.02 * mean));
        }
    }
    let rmse = (sq / (3 * px.len()) as f64).sqrt();
    eprintln!(
        "BC6H: RMSE {rmse:.3e} ({:.3} % of the mean {mean:.4}), worst {worst:.3} of the bound",
        100.0 * rmse / mean
    );
    assert!(
        rmse <= 0.05 * mean,
        "BC6H RMSE {rmse} over 5 % of the mean {mean}"
    );
    assert!(worst <= 1.0, "a BC6H texel is off by {worst} × its bound");
}

/// `--directional sh`: each SH page also as `lightmap_<page>_sh_<c>.ktx2`
/// in `R16G16B16A16_SFLOAT` (signed: the linear coefficients are negative
/// where light comes from the −axis side), read back with the `ktx2`
/// crate: the EXR's values to half precision (relative 2⁻¹¹, or half's
/// smallest normal), negative values included.
#[test]
fn ktx2_sh_pages_are_signed_half_floats() {
    let dir = temp_dir("outputs-ktx2-sh");
    bake_cornell(&dir, &["--directional", "sh"], None);
    let manifest = json(&dir.join("manifest.json"));
    let mut negative = 0usize;
    for c in ["a", "x", "y", "z"] {
        let listed = &manifest["pages"][0]["sh"][c];
        assert_eq!(
            listed["ktx2"],
            format!("lightmap_0_sh_{c}.ktx2"),
            "{listed}"
        );
        assert_eq!(listed["ktx2_format"], "rgba16f");
        let (h, data) = zstd_ktx2(
            &dir.join(format!("lightmap_0_sh_{c}.ktx2")),
            ktx2::Format::R16G16B16A16_SFLOAT,
        );
        let (w, px) = &read_exr(&dir.join(format!("lightmap_0_sh_{c}.exr")));
        assert_eq!(h.pixel_width as usize, *w);
        assert_eq!(data.len(), px.len() * 8);
        for (chunk, want) in data.chunks_exact(8).zip(px) {
            for k in 0..3 {
                let got = half::f16::from_le_bytes([chunk[2 * k], chunk[2 * k + 1]]).to_f32();
                let tol = want[k].abs() * 2f32.powi(-11) + 6.2e-5;
                assert!((got - want[k]).abs() <= tol, "sh_{c}: {got} vs {}", want[k]);
                negative += (want[k] < 0.0) as usize;
            }
        }
    }
    assert!(
        negative > 0,
        "no negative coefficient to test the sign with"
    );
}
