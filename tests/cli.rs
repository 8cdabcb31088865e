//! The `radbake` binary: a good bake writes its files and report; every bad
//! input gives one line naming the problem and exit code 1, never a panic.

mod common;

use common::*;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

struct Run {
    code: i32,
    stderr: String,
}

fn radbake(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(args)
        .output()
        .expect("radbake runs");
    Run {
        code: out.status.code().unwrap_or(-1),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn bake(scene: &Path, out: &Path, extra: &[&str]) -> Run {
    let mut args = vec![
        "bake",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--texels-per-meter",
        "20",
        "--rays-per-patch",
        "64",
    ];
    args.extend_from_slice(extra);
    radbake(&args)
}

/// A bad input must fail with exit 1 and one line that mentions `needle`.
fn assert_rejected(scene: &Path, needle: &str) {
    let out = scene.with_extension("out");
    let r = bake(scene, &out, &[]);
    assert_eq!(
        r.code,
        1,
        "exit code for {}: stderr {}",
        scene.display(),
        r.stderr
    );
    assert!(
        !r.stderr.contains("panicked") && !r.stderr.contains("internal error"),
        "{}",
        r.stderr
    );
    let lines: Vec<&str> = r.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line expected: {:?}", lines);
    assert!(lines[0].starts_with("error: "), "{}", lines[0]);
    assert!(r.stderr.contains(needle), "`{needle}` not in: {}", r.stderr);
    assert!(
        !out.join("report.json").exists(),
        "a failed bake wrote a report"
    );
}

/// A valid single-quad scene with an emitter above it.
fn plates() -> GltfBuilder {
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("lamp", m);
    b
}

fn write_json(dir: &Path, name: &str, v: &Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_vec(v).unwrap()).unwrap();
    p
}

/// A GLB container (radbake's own writer).
fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    radbake::output::baked::glb(json, bin)
}

fn plates_glb() -> Vec<u8> {
    let b = plates();
    let mut doc = b.json();
    doc["buffers"] = json!([{"byteLength": b.buffer.len()}]);
    glb(&doc, &b.buffer)
}

#[test]
fn bakes_the_cornell_box_and_writes_outputs() {
    let dir = temp_dir("cli-cornell");
    let out = dir.join("cornell");
    let r = bake(&scene_path("cornell_box.gltf"), &out, &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    for f in ["lightmap_0.exr", "lightmap_0.png", "report.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let instances = report["instances"].as_array().unwrap();
    assert_eq!(instances.len(), 8);
    for i in instances {
        assert!(i["texels"].as_u64().unwrap() > 0);
        assert_eq!(i["mean"].as_array().unwrap().len(), 3);
        assert!(
            i["node"].is_string() && i["mesh"].is_string() && i["area"].as_f64().unwrap() > 0.0
        );
    }
    for key in [
        "triangles",
        "instances",
        "texels",
        "patches",
        "nonzeros",
        "rays",
        "iterations",
        "residual",
        "degenerate_triangles",
    ] {
        assert!(report["counts"].get(key).is_some(), "counts.{key} missing");
    }
    assert_eq!(report["settings"]["texels_per_meter"], json!(20.0));
    assert!(report["stages"].as_array().unwrap().len() >= 8);
    // The EXR holds the float values: read it back.
    let img = exr::prelude::read_first_rgba_layer_from_file(
        out.join("lightmap_0.exr"),
        |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .unwrap();
    let size = report["counts"]["page_size"].as_array().unwrap();
    assert_eq!(
        img.layer_data.size.width() as u64,
        size[0].as_u64().unwrap()
    );
    let (_, px) = &img.layer_data.channel_data.pixels;
    assert!(px
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite() && *v >= 0.0)));
    let max = px.iter().fold(0.0f32, |m, p| m.max(p[0]));
    assert!(max > 0.1, "brightest red {max}");
    // Probes by default, listed in the manifest and counted in the report.
    assert!(report["counts"]["probes"].as_u64().unwrap() > 0);
    for f in ["probes.json", "probes.bin", "probes_0.ktx2"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(
        manifest["probes"]["volumes"][0]["bevy_irradiance_volume"],
        "probes_0.ktx2"
    );
    // `--probes off` writes none.
    let off = dir.join("no-probes");
    let r = bake(&scene_path("cornell_box.gltf"), &off, &["--probes", "off"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(!off.join("probes.json").exists() && !off.join("probes_0.ktx2").exists());
    let r = bake(
        &scene_path("cornell_box.gltf"),
        &off,
        &["--probes", "maybe"],
    );
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(r.stderr.contains("on or off"), "{}", r.stderr);
}

#[test]
fn help_documents_flags() {
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(["bake", "--help"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--out",
        "--texels-per-meter",
        "--patch-texels",
        "--rays-per-patch",
        "--tolerance",
        "--max-iterations",
        "--uv",
        "--config",
        "--probes",
        "--probe-spacing",
        "--probe-budget",
        "--probe-rays",
        "--gather-threshold",
        "--gather-near-field",
    ] {
        assert!(text.contains(flag), "{flag} not in --help");
    }
    assert_eq!(out.status.code(), Some(0));
    let r = radbake(&["bake"]);
    assert_eq!(r.code, 2, "usage error exit code");
}

#[test]
fn stats_prints_stages_rays_and_peak_memory() {
    let dir = temp_dir("cli-stats");
    let r = bake(
        &scene_path("cornell_box.gltf"),
        &dir.join("out"),
        // No near field: a close hit's light samples would come on top of
        // the gather's own rays counted below.
        &[
            "--stats",
            "-q",
            "--final-gather",
            "16",
            "--gather-near-field",
            "0",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    for needle in [
        "rays/s",
        "form_factors",
        "final_gather",
        "total",
        "texels",
        "iterations",
    ] {
        assert!(r.stderr.contains(needle), "{needle} missing:\n{}", r.stderr);
    }
    if cfg!(target_os = "linux") {
        assert!(r.stderr.contains("peak memory"), "{}", r.stderr);
    }
    // The final gather's rays: 16 per valid texel, fewer for invalid ones
    // (their gather stops once they are certainly invalid).
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/report.json")).unwrap()).unwrap();
    let c = &report["counts"];
    let (texels, invalid) = (
        c["texels"].as_u64().unwrap(),
        c["invalid_texels"].as_u64().unwrap(),
    );
    let gather = c["rays_gather"].as_u64().unwrap();
    assert!(invalid > 0, "the Cornell box's blocks stand on the floor");
    assert!(
        gather >= 16 * (texels - invalid) && gather < 16 * texels,
        "{gather} gather rays for {texels} texels ({invalid} invalid)"
    );
    assert_eq!(
        c["rays"].as_u64().unwrap(),
        c["rays_form_factors"].as_u64().unwrap()
            + c["rays_direct"].as_u64().unwrap()
            + c["rays_validity"].as_u64().unwrap()
            + c["rays_gather"].as_u64().unwrap()
            + c["rays_burial"].as_u64().unwrap()
            + c["rays_probes"].as_u64().unwrap()
    );
    assert!(r.stderr.contains("probes"), "{}", r.stderr);
    // The validity estimate before the gather: at most 8 rays per texel,
    // fewer for texels found buried early.
    let validity = c["rays_validity"].as_u64().unwrap();
    assert!(
        validity > 0 && validity <= 8 * texels,
        "{validity} validity rays"
    );
}

#[test]
fn glb_with_bin_chunk_bakes() {
    let dir = temp_dir("cli-glb");
    let path = dir.join("plates.glb");
    std::fs::write(&path, plates_glb()).unwrap();
    let r = bake(&path, &dir.join("out"), &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

#[test]
fn external_buffer_inside_folder_bakes() {
    let dir = temp_dir("cli-external");
    let b = plates();
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::write(dir.join("data/plates bin.bin"), &b.buffer).unwrap();
    let mut doc = b.json();
    doc["buffers"][0]["uri"] = json!("data/plates%20bin.bin");
    let path = write_json(&dir, "plates.gltf", &doc);
    let r = bake(&path, &dir.join("out"), &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

#[test]
fn no_emitters_bakes_black_with_a_warning() {
    let dir = temp_dir("cli-dark");
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let path = dir.join("dark.gltf");
    b.write(&path);
    let r = bake(&path, &dir.join("out"), &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("no emissive"), "{}", r.stderr);
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/report.json")).unwrap()).unwrap();
    assert_eq!(report["instances"][0]["mean"], json!([0.0, 0.0, 0.0]));
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let dir = temp_dir("cli-degenerate");
    let mut b = plates();
    // Floor quad plus a zero-area triangle and a repeated-index one.
    let p = vec![
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [2.0, 0.0, 2.0],
        [3.0, 0.0, 3.0],
    ];
    let m = b.mesh(&p, &[0, 1, 2, 0, 3, 4, 1, 1, 2], Some(1));
    b.node("slivers", m);
    let path = dir.join("deg.gltf");
    b.write(&path);
    let r = bake(&path, &dir.join("out"), &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/report.json")).unwrap()).unwrap();
    assert_eq!(report["counts"]["degenerate_triangles"], json!(2));
}

#[test]
fn unreadable_and_unparsable_files() {
    let dir = temp_dir("cli-parse");
    assert_rejected(&dir.join("missing.gltf"), "cannot read");
    std::fs::write(dir.join("empty.gltf"), b"").unwrap();
    assert_rejected(&dir.join("empty.gltf"), "empty");
    std::fs::write(dir.join("text.gltf"), b"this is not json").unwrap();
    assert_rejected(&dir.join("text.gltf"), "not a valid glTF");
    let good = plates_glb();
    // Truncated in the header, in the JSON chunk, in the BIN chunk.
    for (k, cut) in [6usize, 40, good.len() - 10].into_iter().enumerate() {
        let p = dir.join(format!("cut{k}.glb"));
        std::fs::write(&p, &good[..cut]).unwrap();
        assert_rejected(&p, "cut");
    }
    let mut bad_magic = good.clone();
    bad_magic[0] = b'X';
    std::fs::write(dir.join("magic.glb"), &bad_magic).unwrap();
    assert_rejected(&dir.join("magic.glb"), "magic.glb");
    let mut bad_version = good;
    bad_version[4] = 1;
    std::fs::write(dir.join("version.glb"), &bad_version).unwrap();
    assert_rejected(&dir.join("version.glb"), "version.glb");
}

#[test]
fn uris_may_not_leave_the_scene_folder() {
    let root = temp_dir("cli-uri");
    let dir = root.join("scene");
    std::fs::create_dir_all(&dir).unwrap();
    let b = plates();
    std::fs::write(root.join("secret.bin"), &b.buffer).unwrap();
    let mut doc = b.json();
    doc["buffers"][0]["uri"] = json!("../secret.bin");
    assert_rejected(
        &write_json(&dir, "dotdot.gltf", &doc),
        "leaves the scene's folder",
    );
    doc["buffers"][0]["uri"] = json!("sub/../../secret.bin");
    assert_rejected(
        &write_json(&dir, "dotdot2.gltf", &doc),
        "leaves the scene's folder",
    );
    doc["buffers"][0]["uri"] = json!(root.join("secret.bin").to_str().unwrap());
    assert_rejected(&write_json(&dir, "absolute.gltf", &doc), "absolute");
    doc["buffers"][0]["uri"] = json!("file:///etc/passwd");
    assert_rejected(&write_json(&dir, "scheme.gltf", &doc), "absolute");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(root.join("secret.bin"), dir.join("link.bin")).unwrap();
        doc["buffers"][0]["uri"] = json!("link.bin");
        assert_rejected(
            &write_json(&dir, "symlink.gltf", &doc),
            "outside the scene's folder",
        );
    }
    doc["buffers"][0]["uri"] = json!("nothere.bin");
    assert_rejected(&write_json(&dir, "missing.gltf", &doc), "buffers[0]");
}

#[test]
fn bad_geometry_is_named() {
    let dir = temp_dir("cli-geometry");
    // Index past the vertex count.
    let mut b = GltfBuilder::default();
    let m = b.mesh(
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        &[0, 1, 7],
        None,
    );
    b.node("bad", m);
    let path = dir.join("index.gltf");
    b.write(&path);
    assert_rejected(&path, "meshes[0].primitives[0].indices");
    // NaN and infinite positions.
    for (k, v) in [f32::NAN, f32::INFINITY].into_iter().enumerate() {
        let mut b = GltfBuilder::default();
        let m = b.mesh(
            &[[0.0; 3], [v, 0.0, 0.0], [0.0, 0.0, 1.0]],
            &[0, 1, 2],
            None,
        );
        b.node("bad", m);
        let path = dir.join(format!("nan{k}.gltf"));
        b.write(&path);
        assert_rejected(&path, "meshes[0].primitives[0].attributes.POSITION");
    }
    // NaN normals.
    let mut b = GltfBuilder::default();
    let pos = b.vec3(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    let nrm = b.vec3(&[[0.0, 1.0, 0.0], [f32::NAN, 1.0, 0.0], [0.0, 1.0, 0.0]]);
    let mut doc = b.json();
    doc["meshes"] = json!([{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}}]}]);
    doc["nodes"] = json!([{"mesh": 0}]);
    doc["scenes"] = json!([{"nodes": [0]}]);
    assert_rejected(
        &write_json(&dir, "nan_normal.gltf", &doc),
        "meshes[0].primitives[0].attributes.NORMAL",
    );
    // A byte stride that walks past the view.
    let mut doc = plates().json();
    doc["bufferViews"][0]["byteStride"] = json!(64);
    assert_rejected(&write_json(&dir, "stride.gltf", &doc), "accessors[0]");
    // An accessor offset past the view.
    let mut doc = plates().json();
    doc["accessors"][0]["byteOffset"] = json!(40);
    assert_rejected(&write_json(&dir, "offset.gltf", &doc), "accessors[0]");
    // A POSITION accessor that does not exist (made the gltf crate panic; found by fuzzing).
    let mut doc = plates().json();
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99);
    assert_rejected(
        &write_json(&dir, "position.gltf", &doc),
        "meshes[0].primitives[0].attributes.POSITION",
    );
    // An accessor that runs past its buffer view.
    let mut doc = plates().json();
    doc["accessors"][0]["count"] = json!(1000);
    assert_rejected(&write_json(&dir, "count.gltf", &doc), "accessors[0]");
    // A buffer view past its buffer.
    let mut doc = plates().json();
    doc["bufferViews"][0]["byteLength"] = json!(1 << 20);
    assert_rejected(&write_json(&dir, "view.gltf", &doc), "bufferViews[0]");
    // No meshes at all.
    let doc = json!({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"name": "empty"}]});
    assert_rejected(&write_json(&dir, "nomesh.gltf", &doc), "no triangles");
    // A required extension we do not support.
    let mut doc = plates().json();
    doc["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    doc["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    assert_rejected(
        &write_json(&dir, "draco.gltf", &doc),
        "KHR_draco_mesh_compression",
    );
    let mut doc = plates().json();
    doc["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
    doc["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
    assert_rejected(
        &write_json(&dir, "meshopt.gltf", &doc),
        "EXT_meshopt_compression",
    );
}

#[test]
fn huge_image_header_is_refused_before_decoding() {
    let dir = temp_dir("cli-image");
    // A PNG signature and an IHDR chunk claiming 100000 × 100000 pixels.
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(b"IHDR");
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    let crc = crc32(&ihdr);
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc.to_be_bytes());
    std::fs::write(dir.join("huge.png"), &png).unwrap();
    let mut doc = plates().json();
    doc["images"] = json!([{"uri": "huge.png"}]);
    doc["textures"] = json!([{"source": 0}]);
    doc["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    assert_rejected(&write_json(&dir, "huge.gltf", &doc), "images[0]");
    // A JPEG whose frame header claims 65000 × 65000 pixels.
    let mut jpg = vec![0xff, 0xd8, 0xff, 0xc0, 0x00, 0x11, 0x08];
    jpg.extend_from_slice(&65000u16.to_be_bytes());
    jpg.extend_from_slice(&65000u16.to_be_bytes());
    jpg.extend_from_slice(&[
        0x03, 0x01, 0x22, 0x00, 0x02, 0x11, 0x01, 0x03, 0x11, 0x01, 0xff, 0xd9,
    ]);
    std::fs::write(dir.join("huge.jpg"), &jpg).unwrap();
    doc["images"] = json!([{"uri": "huge.jpg"}]);
    assert_rejected(&write_json(&dir, "huge_jpg.gltf", &doc), "images[0]");
}

/// CRC-32 (ISO 3309) for the PNG chunk above.
fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn config_file_is_read_and_unknown_keys_rejected() {
    let dir = temp_dir("cli-config");
    let path = dir.join("plates.gltf");
    plates().write(&path);
    std::fs::write(
        dir.join("good.toml"),
        "patch_texels = 2\nrays_per_patch = 32\n",
    )
    .unwrap();
    std::fs::write(dir.join("bad.toml"), "texels_per_metre = 2\n").unwrap();
    let out = dir.join("out");
    let r = radbake(&[
        "bake",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--config",
        dir.join("good.toml").to_str().unwrap(),
        "--texels-per-meter",
        "16",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let report: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["settings"]["patch_texels"], json!(2));
    assert_eq!(report["settings"]["texels_per_meter"], json!(16.0));
    let r = radbake(&[
        "bake",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--config",
        dir.join("bad.toml").to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("texels_per_metre"), "{}", r.stderr);
    let r = radbake(&[
        "bake",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--patch-texels",
        "0",
    ]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("patch_texels"), "{}", r.stderr);
}

/// Regression for a fuzzing find: a GLB whose JSON (with invalid UTF-8 in it)
/// loses its `accessors` key made the gltf crate's validation panic.
#[test]
fn fuzz_regressions() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/fuzz_position_index.glb");
    let dir = temp_dir("cli-fuzz");
    let copy = dir.join("case.glb");
    std::fs::copy(&path, &copy).unwrap();
    assert_rejected(&copy, "meshes[0].primitives[0].attributes.POSITION");

    // A flipped byte put a vertex 2,097 km away: uvunwrap's packer panicked
    // on the resulting chart. Refused before unwrapping, naming the primitive.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/fuzz_uvunwrap_pack.glb");
    let copy = dir.join("pack.glb");
    std::fs::copy(&path, &copy).unwrap();
    assert_rejected(&copy, "meshes[0].primitives[0]");
    let r = bake(&copy, &dir.join("out"), &[]);
    assert!(r.stderr.contains("texel lightmap limit"), "{}", r.stderr);
}

/// `radbake render`: reference and final pass write an EXR and a PNG;
/// a bake folder of another scene is refused with exit code 1.
#[test]
fn render_reference_and_final_pass() {
    let dir = temp_dir("cli-render");
    let cornell = scene_path("cornell_box.gltf");
    let exe = env!("CARGO_BIN_EXE_radbake");
    let run = |args: &[&str]| {
        std::process::Command::new(exe)
            .args(args)
            .output()
            .expect("radbake runs")
    };
    let out = dir.join("ref.exr");
    let r = run(&[
        "render",
        cornell.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "16x16",
        "--spp",
        "2",
        "-q",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists() && out.with_extension("png").exists());
    let bake_dir = dir.join("bake");
    let r = run(&[
        "bake",
        cornell.to_str().unwrap(),
        "--out",
        bake_dir.to_str().unwrap(),
        "--preset",
        "preview",
        "-q",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = dir.join("final.png");
    let r = run(&[
        "render",
        cornell.to_str().unwrap(),
        "--lightmaps",
        bake_dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "16x16",
        "--spp",
        "2",
        "-q",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists());
    // The plates' scene against the Cornell box's bake: the atlas differs.
    let plates = scene_path("parallel_plates.gltf");
    let r = run(&[
        "render",
        plates.to_str().unwrap(),
        "--lightmaps",
        bake_dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("lightmap_0.exr") && err.lines().count() == 1,
        "{err}"
    );
}

/// `radbake serve` on a port already taken: a one-line error that names the
/// address and says what to do, exit 3; a missing folder: exit 1.
#[test]
fn serve_reports_a_taken_port() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let dir = temp_dir("cli-serve");
    let r = radbake(&["serve", dir.to_str().unwrap(), "--port", &port]);
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr.contains(&format!("127.0.0.1:{port} is in use")) && r.stderr.contains("--port"),
        "{}",
        r.stderr
    );
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    let r = radbake(&["serve", dir.join("nope").to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.stderr);
}

/// `preview --watch` on a folder that does not exist says so at once (no
/// wait for a bake that cannot write there).
#[cfg(feature = "preview")]
#[test]
fn watch_refuses_a_missing_folder() {
    let r = radbake(&["preview", "--watch", "/nonexistent/radbake-watch"]);
    assert_ne!(r.code, 0);
    assert!(r.stderr.contains("no such folder"), "{}", r.stderr);
}
