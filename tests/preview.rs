//! The wgpu preview (`radbake preview`, feature `preview`): WGSL/Rust layout
//! agreement, the model builder, headless renders of the baked Cornell box
//! against a golden image, and light probes (a dynamic node lit from them,
//! the probes view) on a floor under a sky.
//!
//! GPU tests need an adapter; Mesa's lavapipe (software Vulkan) is enough
//! (`.ci/run` installs it). Where none exists at all they print why and
//! return. The golden image is regenerated only with `RADBAKE_UPDATE_GOLDEN=1`;
//! a missing golden fails.
#![cfg(feature = "preview")]

mod common;

use common::{centre_linear, quad, scene_path, srgb_to_linear, temp_dir, GltfBuilder};
use glam::{Vec2, Vec3};
use radbake::preview::{gpu, model};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// Golden comparison thresholds, in 8-bit sRGB levels (0–255), of the
/// per-pixel largest channel difference: the mean over the image, and the
/// 99th percentile (which lets a few edge pixels differ between
/// rasterizers, but not a region).
const MAX_MEAN_ABS_ERROR: f64 = 1.5;
const MAX_P99_ERROR: u8 = 24;
const GOLDEN_SIZE: &str = "320x240";

fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/cornell_preview.png")
}

/// The Cornell box baked once (low settings) for every test here.
fn baked_cornell() -> &'static Path {
    static BAKED: OnceLock<PathBuf> = OnceLock::new();
    BAKED.get_or_init(|| {
        let dir = temp_dir("preview-bake");
        let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
            .args([
                "bake",
                "-q",
                "--debug-maps",
                "--texels-per-meter",
                "40",
                "--out",
            ])
            .arg(&dir)
            .arg(scene_path("cornell_box.gltf"))
            .output()
            .expect("run radbake bake");
        assert!(
            out.status.success(),
            "bake failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let glb = dir.join("cornell_box.baked.glb");
        assert!(glb.exists());
        glb
    })
}

/// Runs `radbake preview <glb> --headless --out <png> <extra>`; None (after
/// printing why) when the machine has no graphics adapter at all.
fn headless(glb: &Path, png: &Path, extra: &[&str]) -> Option<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("preview")
        .arg(glb)
        .args(["--headless", "--out"])
        .arg(png)
        .args(extra)
        .output()
        .expect("run radbake preview");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() && stderr.contains("no graphics adapter") {
        eprintln!("SKIPPED (no GPU or software adapter on this machine): {stderr}");
        return None;
    }
    assert!(out.status.success(), "preview failed: {stderr}");
    assert!(png.exists(), "{} was not written", png.display());
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn load_rgba(path: &Path) -> image::RgbaImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8()
}

#[test]
fn wgsl_struct_layouts_match_rust() {
    let module = naga::front::wgsl::parse_str(gpu::SHADER).expect("WGSL parses");
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .expect("WGSL validates");
    let find = |name: &str| {
        module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("WGSL struct {name} not found"))
            .1
            .inner
            .clone()
    };
    for (name, size, fields) in gpu::layouts() {
        let naga::TypeInner::Struct { members, span } = find(name) else {
            panic!("{name} is not a struct");
        };
        assert_eq!(span as usize, size, "{name}: WGSL size {span}, Rust {size}");
        let wgsl: Vec<(String, usize)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
            .collect();
        let rust: Vec<(String, usize)> = fields.iter().map(|(n, o)| (n.to_string(), *o)).collect();
        assert_eq!(wgsl, rust, "{name}: WGSL vs Rust (field, offset)");
    }
    // The vertex: shader locations 0.. in field order, same sizes as the
    // buffer layout's formats, at the Rust field offsets.
    let naga::TypeInner::Struct { members, .. } = find("VertexIn") else {
        panic!("VertexIn is not a struct");
    };
    let offsets = gpu::vertex_offsets();
    assert_eq!(members.len(), gpu::Vertex::ATTRIBUTES.len());
    for (i, (m, attr)) in members.iter().zip(gpu::Vertex::ATTRIBUTES).enumerate() {
        assert!(
            matches!(m.binding, Some(naga::Binding::Location { location, .. }) if location == i as u32),
            "VertexIn member {i} is not at location {i}"
        );
        assert_eq!(attr.shader_location, i as u32);
        assert_eq!(attr.offset as usize, offsets[i], "attribute {i} offset");
        let size = module.types[m.ty].inner.size(module.to_ctx()) as u64;
        assert_eq!(size, attr.format.size(), "attribute {i} size");
    }
    assert_eq!(
        std::mem::size_of::<gpu::Vertex>(),
        offsets[gpu::Vertex::ATTRIBUTES.len() - 1] + 16,
        "Vertex has no tail padding"
    );
    // The constants written in both languages.
    let constant = |name: &str| {
        let (_, c) = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("WGSL constant {name} not found"));
        match module.global_expressions[c.init] {
            naga::Expression::Literal(l) => l,
            ref e => panic!("{name} is not a literal: {e:?}"),
        }
    };
    for view in radbake::preview::ViewMode::ALL {
        let name = format!("VIEW_{view:?}").to_uppercase();
        assert_eq!(constant(&name), naga::Literal::U32(view as u32), "{name}");
    }
    for (name, value) in [
        ("PROBE_NONE", gpu::PROBE_NONE),
        ("PROBE_LIT", gpu::PROBE_LIT),
        ("PROBE_INVALID", gpu::PROBE_INVALID),
    ] {
        assert_eq!(constant(name), naga::Literal::F32(value), "{name}");
    }
    for (name, value) in [
        ("FLAG_BASE_TEXTURE", gpu::FLAG_BASE_TEXTURE),
        ("FLAG_EMISSIVE_TEXTURE", gpu::FLAG_EMISSIVE_TEXTURE),
        ("FLAG_LIGHTMAP", gpu::FLAG_LIGHTMAP),
        ("FLAG_BLEND", gpu::FLAG_BLEND),
        ("FLAG_BASE_UV1", gpu::FLAG_BASE_UV1),
        ("FLAG_EMISSIVE_UV1", gpu::FLAG_EMISSIVE_UV1),
    ] {
        assert_eq!(constant(name), naga::Literal::U32(value), "{name}");
    }
}

#[test]
fn chart_borders_are_uv_seams_and_boundaries() {
    // A unit quad as two triangles sharing the diagonal 0–2.
    let p = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let uv: Vec<Vec2> = p.iter().map(|v| v.truncate()).collect();
    let tris = [[0, 1, 2], [0, 2, 3]];
    // Same UVs on both sides of the diagonal: only the outer edges border.
    // Edge k joins corners k and k + 1: the diagonal is edge 2 of triangle 0
    // (2→0) and edge 0 of triangle 1 (0→2).
    assert_eq!(
        model::chart_border_edges(&p, &uv, &tris),
        vec![0b011, 0b110]
    );
    // Split the diagonal into a seam (vertices 4, 5 duplicate 0, 2 with other UVs).
    let mut p2 = p.to_vec();
    p2.extend([p[0], p[2]]);
    let mut uv2 = uv.clone();
    uv2.extend([Vec2::new(5.0, 5.0), Vec2::new(6.0, 6.0)]);
    let tris2 = [[0, 1, 2], [4, 5, 3]];
    assert_eq!(
        model::chart_border_edges(&p2, &uv2, &tris2),
        vec![0b111, 0b111]
    );
}

#[test]
fn moz_lightmap_is_parsed_per_material() {
    let json = serde_json::json!({"materials": [
        {"name": "plain"},
        {"extensions": {"MOZ_lightmap": {"index": 3, "texCoord": 1, "intensity": 6.0,
            "extensions": {"KHR_texture_transform": {"offset": [0.25, 0.5], "scale": [0.125, 0.25]}}}}},
        {"extensions": {"MOZ_lightmap": {"index": 3, "intensity": 2.0}}},
        {"extensions": {"MOZ_lightmap": {"index": 7, "intensity": 1.0}}}
    ]});
    let (per_material, pages) = model::parse_moz_lightmaps(&json).unwrap();
    assert_eq!(pages, vec![3, 7]);
    assert_eq!(per_material[0], None);
    let a = per_material[1].unwrap();
    assert_eq!((a.page, a.intensity), (0, 6.0));
    assert_eq!(
        (a.offset, a.scale),
        (Vec2::new(0.25, 0.5), Vec2::new(0.125, 0.25))
    );
    let b = per_material[2].unwrap();
    assert_eq!((b.page, b.offset, b.scale), (0, Vec2::ZERO, Vec2::ONE));
    assert_eq!(per_material[3].unwrap().page, 1);
}

#[test]
fn baked_cornell_model_has_lightmaps_on_every_surface() {
    let m = model::Model::load(baked_cornell()).unwrap();
    assert_eq!(m.lightmaps.len(), 1);
    assert!(!m.batches.is_empty());
    for b in &m.batches {
        let mat = &m.materials[b.material];
        assert_eq!(
            mat.lightmap,
            Some(0),
            "batch material {} has no lightmap",
            b.material
        );
        assert!(mat.gpu.lightmap_scale > 0.0);
        let [_, _, w, h] = mat.gpu.lightmap_rect;
        assert!(w > 0.0 && h > 0.0 && w <= 1.0 && h <= 1.0);
    }
    assert_eq!(m.vertices.len() % 3, 0);
    // Every triangle has some chart border (each wall is its own chart).
    assert!(m.vertices.iter().any(|v| v.corner_edges >> 2 != 0));
}

#[test]
fn headless_cornell_matches_golden() {
    let glb = baked_cornell();
    let dir = temp_dir("preview-golden");
    let png = dir.join("cornell_preview.png");
    let Some(_) = headless(glb, &png, &["--size", GOLDEN_SIZE]) else {
        return;
    };
    let golden = golden_path();
    if std::env::var_os("RADBAKE_UPDATE_GOLDEN").is_some_and(|v| v == "1") {
        std::fs::copy(&png, &golden).unwrap();
        eprintln!("updated {}", golden.display());
        return;
    }
    assert!(
        golden.exists(),
        "golden image {} is missing: generate it with RADBAKE_UPDATE_GOLDEN=1 cargo test --release --test preview, look at it, and commit it",
        golden.display()
    );
    let (a, b) = (load_rgba(&png), load_rgba(&golden));
    assert_eq!(
        a.dimensions(),
        b.dimensions(),
        "image size differs from the golden"
    );
    let mut errors: Vec<u8> = a
        .pixels()
        .zip(b.pixels())
        .map(|(p, q)| (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap())
        .collect();
    let mean = errors.iter().map(|&e| e as f64).sum::<f64>() / errors.len() as f64;
    errors.sort_unstable();
    let p99 = errors[(errors.len() * 99 / 100).min(errors.len() - 1)];
    eprintln!("golden: mean abs error {mean:.3}, p99 {p99} (limits {MAX_MEAN_ABS_ERROR}, {MAX_P99_ERROR}); render at {}", png.display());
    assert!(
        mean <= MAX_MEAN_ABS_ERROR && p99 <= MAX_P99_ERROR,
        "render differs from {}: mean abs error {mean:.3} (limit {MAX_MEAN_ABS_ERROR}), p99 {p99} (limit {MAX_P99_ERROR}); the render is {}",
        golden.display(),
        png.display()
    );
    // The golden itself is the lit room, not a blank frame: the lamp is
    // white, the walls left and right of the centre are red and green, the
    // back wall is lit.
    let (w, h) = b.dimensions();
    let mean = |x0: f32, x1: f32, y0: f32, y1: f32| {
        let (mut sum, mut n) = ([0f64; 3], 0f64);
        for y in (y0 * h as f32) as u32..(y1 * h as f32) as u32 {
            for x in (x0 * w as f32) as u32..(x1 * w as f32) as u32 {
                let p = b.get_pixel(x, y);
                (0..3).for_each(|c| sum[c] += p[c] as f64);
                n += 1.0;
            }
        }
        sum.map(|s| s / n)
    };
    let lamp = b
        .pixels()
        .filter(|p| p[0] > 240 && p[1] > 240 && p[2] > 240)
        .count();
    assert!(lamp > 20, "no white lamp ({lamp} pixels)");
    let left = mean(0.15, 0.25, 0.3, 0.6);
    let right = mean(0.75, 0.85, 0.3, 0.6);
    let back = mean(0.45, 0.55, 0.25, 0.35);
    eprintln!("left {left:?} right {right:?} back {back:?}");
    assert!(
        left[0] > 20.0 && left[0] > 3.0 * left[1],
        "left wall {left:?} is not red"
    );
    assert!(
        right[1] > 20.0 && right[1] > 1.5 * right[0],
        "right wall {right:?} is not green"
    );
    assert!(
        back[0] > 50.0 && back[1] > 40.0,
        "back wall {back:?} is dark"
    );
}

#[test]
fn headless_debug_views_and_timing() {
    let glb = baked_cornell();
    let dir = temp_dir("preview-views");
    let lit = dir.join("lit.png");
    let Some(stdout) = headless(glb, &lit, &["--size", "160x120", "--frames", "5"]) else {
        return;
    };
    assert!(stdout.contains("ms/frame"), "no timing in: {stdout}");
    let lit = load_rgba(&lit);
    let mut renders = Vec::new();
    for view in ["lightmap", "albedo", "checker", "charts"] {
        let png = dir.join(format!("{view}.png"));
        headless(glb, &png, &["--size", "160x120", "--view", view]).unwrap();
        renders.push((view, load_rgba(&png)));
    }
    let differs = |a: &image::RgbaImage, b: &image::RgbaImage| {
        a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count() > 100
    };
    for (view, img) in &renders {
        assert!(differs(&lit, img), "view {view} looks like lit");
    }
    // Chart borders are drawn in red (1, 0.02, 0).
    let charts = &renders[3].1;
    let red = charts
        .pixels()
        .filter(|p| p[0] > 240 && p[1] < 120 && p[2] < 80)
        .count();
    assert!(red > 50, "chart view has only {red} border pixels");
    // Bicubic filtering changes the image a little, a camera moves it a lot.
    let cubic = dir.join("cubic.png");
    headless(glb, &cubic, &["--size", "160x120", "--bicubic"]).unwrap();
    assert!(differs(&lit, &load_rgba(&cubic)));
    let moved = dir.join("moved.png");
    headless(
        glb,
        &moved,
        &[
            "--size",
            "160x120",
            "--look-from",
            "0.278,0.5,-0.5",
            "--look-at",
            "0.278,0.2,0.3",
        ],
    )
    .unwrap();
    assert!(differs(&lit, &load_rgba(&moved)));
    // The named glTF camera is the default one.
    let named = dir.join("named.png");
    headless(glb, &named, &["--size", "160x120", "--camera", "camera"]).unwrap();
    assert_eq!(lit.as_raw(), load_rgba(&named).as_raw());
}

/// The patch and validity views read the bake's `--debug-maps` output:
/// patches in many colours; the floor texels under the blocks (inside
/// geometry) in red; without the maps (the `.glb` alone) magenta stripes.
#[test]
fn patch_and_invalid_texel_views() {
    let glb = baked_cornell();
    assert!(glb.with_file_name("lightmap_0_debug.png").exists());
    let dir = temp_dir("preview-debug-views");
    let patches = dir.join("patches.png");
    if headless(glb, &patches, &["--size", "160x160", "--view", "patches"]).is_none() {
        return;
    }
    let colours: std::collections::HashSet<[u8; 3]> = load_rgba(&patches)
        .pixels()
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    assert!(
        colours.len() > 200,
        "{} colours in the patch view",
        colours.len()
    );
    let invalid = dir.join("invalid.png");
    headless(glb, &invalid, &["--size", "160x160", "--view", "invalid"]).unwrap();
    let red = load_rgba(&invalid)
        .pixels()
        .filter(|p| p[0] > 240 && p[1] < 80 && p[2] < 60)
        .count();
    assert!(red > 5, "{red} invalid-texel pixels");
    // The .glb alone: no debug map next to it.
    let alone = dir.join("alone.glb");
    std::fs::copy(glb, &alone).unwrap();
    let striped = dir.join("striped.png");
    headless(
        &alone,
        &striped,
        &["--size", "160x160", "--view", "patches"],
    )
    .unwrap();
    let magenta = load_rgba(&striped)
        .pixels()
        .filter(|p| p[0] > 240 && p[1] < 30 && p[2] > 240)
        .count();
    assert!(
        magenta > 1000,
        "{magenta} magenta pixels without a debug map"
    );
}

#[test]
fn unknown_camera_is_a_clear_error() {
    let glb = baked_cornell();
    let png = temp_dir("preview-badcam").join("x.png");
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("preview")
        .arg(glb)
        .args(["--headless", "--out"])
        .arg(&png)
        .args(["--camera", "nope"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("no camera named `nope`") && stderr.contains("camera"),
        "{stderr}"
    );
    assert!(!png.exists());
}

/// The probe scene's uniform sky radiance and floor albedo.
const SKY: f32 = 1.0;
/// Base colour of the dynamic box (not grey, so the floor behind it
/// cannot pass for it).
const BOX_COLOUR: [f32; 3] = [0.6, 0.4, 0.2];
/// The dynamic box: x, z in [−1.25, −0.75], y in [0.5, 1.0].
const BOX_MIN: [f32; 3] = [-1.25, 0.5, -1.25];
const BOX_SIZE: f32 = 0.5;
/// The closed block holding 27 probes: x in [0.5, 2], y in [0, 1.5],
/// z in [−2, −0.5].
const BLOCK_MIN: [f32; 3] = [0.5, 0.0, -2.0];
const BLOCK_SIZE: f32 = 1.5;

/// A closed axis-aligned cube's six faces, facing outward, as one mesh.
fn cube(min: [f32; 3], size: f32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let [x, y, z] = min;
    let s = size;
    let faces = [
        quad([x, y, z + s], [s, 0.0, 0.0], [0.0, s, 0.0]),
        quad([x + s, y, z], [-s, 0.0, 0.0], [0.0, s, 0.0]),
        quad([x + s, y, z + s], [0.0, 0.0, -s], [0.0, s, 0.0]),
        quad([x, y, z], [0.0, 0.0, s], [0.0, s, 0.0]),
        quad([x, y + s, z + s], [s, 0.0, 0.0], [0.0, 0.0, -s]),
        quad([x, y, z], [s, 0.0, 0.0], [0.0, 0.0, s]),
    ];
    let (mut p, mut i) = (Vec::new(), Vec::new());
    for (fp, fi) in faces {
        let base = p.len() as u32;
        p.extend(fp);
        i.extend(fi.iter().map(|k| base + k));
    }
    (p, i)
}

/// A 10 m floor (albedo 0.5) under a uniform sky, a closed block on it, a
/// probe grid over the middle (4 × 2 × 4 m at 0.5 m: 8 × 4 × 8 probes at
/// cell centres, 27 of them inside the block) and a dynamic box, baked in
/// process once; returns the folder (`scene.baked.glb`, `probes.json`).
fn baked_probe_scene() -> &'static Path {
    static BAKED: OnceLock<PathBuf> = OnceLock::new();
    BAKED.get_or_init(|| {
        let dir = temp_dir("preview-probes");
        let mut b = GltfBuilder::default();
        let grey = b.material([0.5; 3], [0.0; 3]);
        let colour = b.material(BOX_COLOUR, [0.0; 3]);
        let (p, i) = quad([-5.0, 0.0, -5.0], [0.0, 0.0, 10.0], [10.0, 0.0, 0.0]);
        let m = b.mesh(&p, &i, Some(grey));
        b.node("floor", m);
        let (p, i) = cube(BLOCK_MIN, BLOCK_SIZE);
        let m = b.mesh(&p, &i, Some(grey));
        b.node("block", m);
        let (p, i) = cube(BOX_MIN, BOX_SIZE);
        let m = b.mesh(&p, &i, Some(colour));
        let dynamic = b.node("dynamic_box", m);
        let mut doc = b.json();
        doc["nodes"][dynamic]["extras"] = serde_json::json!({"radbake": {"dynamic": true}});
        let nodes = doc["nodes"].as_array_mut().unwrap();
        nodes.push(serde_json::json!({
            "name": "probe_box", "translation": [0.0, 1.0, 0.0], "scale": [4.0, 2.0, 4.0],
            "extras": {"radbake": {"probe_volume": {"spacing": 0.5}}}
        }));
        let n = nodes.len();
        doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
        let gltf = dir.join("scene.gltf");
        std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
        let scene = radbake::scene::load(&gltf, &Default::default()).unwrap();
        assert_eq!((scene.instances.len(), scene.dynamic.len()), (2, 1));
        let config = radbake::BakeConfig {
            sky: [SKY; 3],
            texels_per_meter: 8.0,
            ..Default::default()
        };
        let bake = radbake::bake(&scene, &config, &radbake::Silent).unwrap();
        let out = dir.join("out");
        radbake::output::write_engine_outputs(&out, "scene", &bake).unwrap();
        out
    })
}

/// `--look-from` and `--look-at` for `from` and `at` (with `=`: the
/// coordinates may start with a minus sign).
fn look_args(from: Vec3, at: Vec3) -> [String; 2] {
    let v = |p: Vec3| format!("{},{},{}", p.x, p.y, p.z);
    [
        format!("--look-from={}", v(from)),
        format!("--look-at={}", v(at)),
    ]
}

/// Renders `glb` from `from` towards `at` at 160×120, no tone map, EV 0;
/// None without an adapter.
fn render_at(glb: &Path, png: &Path, view: &str, from: Vec3, at: Vec3) -> Option<image::RgbaImage> {
    let args = ["--size", "160x120", "--tone-map", "none", "--view", view];
    let look = look_args(from, at);
    let extra: Vec<&str> = args
        .iter()
        .copied()
        .chain(look.iter().map(String::as_str))
        .collect();
    headless(glb, png, &extra)?;
    Some(load_rgba(png))
}

/// The dynamic box is lit by the probes: the centre of its top face,
/// seen from above, is base colour × E/π(+Y) interpolated from the probes
/// (the mean over the face's corners, which agree within 1 %) within 3 %
/// per channel; the model marks its vertices probe-lit and the floor's
/// lightmapped. Without `probes.json` beside the `.glb` it is black and the
/// preview warns once.
#[test]
fn dynamic_node_is_lit_by_the_probes() {
    let out = baked_probe_scene();
    let glb = out.join("scene.baked.glb");
    let probes = radbake::probes::Probes::read(&out.join("probes.json")).unwrap();
    // Base colour × E/π(+Y) at the top face's corners.
    let top_y = BOX_MIN[1] + BOX_SIZE;
    let corners: Vec<Vec3> = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .map(|&(a, b)| {
            let p = Vec3::new(BOX_MIN[0] + a * BOX_SIZE, top_y, BOX_MIN[2] + b * BOX_SIZE);
            probes
                .irradiance_over_pi(p, Vec3::Y)
                .unwrap()
                .max(Vec3::ZERO)
        })
        .collect();
    let mean = corners.iter().sum::<Vec3>() / 4.0;
    for c in &corners {
        assert!(
            ((*c - mean).abs() / mean).max_element() < 0.01,
            "{c} vs {mean}"
        );
    }
    assert!(
        mean.min_element() > 0.5,
        "E/π(+Y) {mean} under a sky of {SKY}"
    );
    let want = Vec3::from(BOX_COLOUR) * mean;

    // The model: the box's 36 vertices probe-lit with that light.
    let m = model::Model::load(&glb).unwrap();
    let lit: Vec<&gpu::Vertex> = m
        .vertices
        .iter()
        .filter(|v| v.probe[3] == gpu::PROBE_LIT)
        .collect();
    assert_eq!(lit.len(), 36);
    assert!(m
        .vertices
        .iter()
        .all(|v| v.probe[3] == gpu::PROBE_LIT || v.probe[3] == gpu::PROBE_NONE));
    let top: Vec<_> = lit.iter().filter(|v| v.normal[1] > 0.99).collect();
    assert_eq!(top.len(), 6);
    for v in top {
        let e = Vec3::from_slice(&v.probe[..3]);
        assert!(
            ((e - mean).abs() / mean).max_element() < 0.011,
            "{e} vs {mean}"
        );
    }

    let dir = temp_dir("preview-dynamic");
    let centre = Vec3::new(
        BOX_MIN[0] + 0.5 * BOX_SIZE,
        top_y,
        BOX_MIN[2] + 0.5 * BOX_SIZE,
    );
    let eye = centre + Vec3::new(0.0, 1.2, 0.6);
    let Some(img) = render_at(&glb, &dir.join("lit.png"), "lit", eye, centre) else {
        return;
    };
    let got = centre_linear(&img);
    eprintln!("dynamic box top: rendered {got}, base colour × E/π {want}");
    let err = ((got - want).abs() / want).max_element();
    assert!(
        err < 0.03,
        "rendered {got} vs {want} ({:.1} %)",
        err * 100.0
    );

    // The .glb alone: no probes, the box unlit (black), one warning.
    let alone = dir.join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    std::fs::copy(&glb, alone.join("scene.baked.glb")).unwrap();
    let png = dir.join("alone.png");
    let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("preview")
        .arg(alone.join("scene.baked.glb"))
        .args(["--headless", "--out"])
        .arg(&png)
        .args(["--size", "160x120", "--tone-map", "none"])
        .arg(format!("--look-from={},{},{}", eye.x, eye.y, eye.z))
        .arg(format!("--look-at={},{},{}", centre.x, centre.y, centre.z))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(
        stderr.matches("light probes not found").count(),
        1,
        "{stderr}"
    );
    let dark = centre_linear(&load_rgba(&png));
    assert!(dark.max_element() < 0.01, "unlit box {dark}");

    // A malformed probes.json: a one-line error naming it, no panic.
    std::fs::write(alone.join("probes.json"), "{").unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("preview")
        .arg(alone.join("scene.baked.glb"))
        .args(["--headless", "--out"])
        .arg(dir.join("bad.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(!stderr.contains("panicked"), "{stderr}");
    let error: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("probes.json"))
        .collect();
    assert_eq!(error.len(), 1, "{stderr}");
    assert!(error[0].contains("not JSON"), "{stderr}");
}

/// The probes view draws a sphere at each probe: a valid probe's, seen
/// from its −Z side, shows E/π(−Z) of that probe (white albedo) within
/// 3 %, where the lit view shows the far background; a probe inside the
/// closed block, seen from inside the block (its faces culled from there),
/// is red. Each is seen from halfway to its neighbour probe (0.25 m).
#[test]
fn probes_view_draws_spheres_and_marks_invalid_probes() {
    let out = baked_probe_scene();
    let glb = out.join("scene.baked.glb");
    let probes = radbake::probes::Probes::read(&out.join("probes.json")).unwrap();
    assert_eq!(probes.len(), 256);
    assert_eq!(probes.invalid(), 27, "probes inside the block");
    let find = |p: Vec3| {
        (0..probes.len())
            .find(|&i| probes.position(i).distance(p) < 1e-4)
            .unwrap_or_else(|| panic!("no probe at {p}"))
    };
    let dir = temp_dir("preview-probe-view");
    // A valid probe, from its −Z side.
    let valid = find(Vec3::new(-0.75, 0.75, 0.75));
    assert!(probes.valid[valid]);
    let at = probes.position(valid);
    let eye = at - Vec3::Z * 0.25;
    let Some(img) = render_at(&glb, &dir.join("probes.png"), "probes", eye, at) else {
        return;
    };
    let got = centre_linear(&img);
    let want = radbake::probes::sh::irradiance_over_pi(&probes.sh[valid], Vec3::NEG_Z);
    eprintln!("valid probe sphere: rendered {got}, E/π(−Z) {want}");
    assert!(want.min_element() > 0.3);
    let err = ((got - want).abs() / want).max_element();
    assert!(
        err < 0.03,
        "rendered {got} vs {want} ({:.1} %)",
        err * 100.0
    );
    let lit = centre_linear(&render_at(&glb, &dir.join("lit.png"), "lit", eye, at).unwrap());
    assert!(
        (lit - got).abs().max_element() > 0.1,
        "the lit view shows {lit} there too"
    );

    // An invalid probe, from inside the block.
    let invalid = find(Vec3::new(1.25, 0.75, -1.25));
    assert!(!probes.valid[invalid]);
    let at = probes.position(invalid);
    let eye = at + Vec3::Z * 0.25;
    let img = render_at(&glb, &dir.join("invalid.png"), "probes", eye, at).unwrap();
    let red = centre_linear(&img);
    eprintln!("invalid probe sphere: {red}");
    assert!(
        red.x > 0.95 && red.y < 0.02 && red.z < 0.02,
        "{red} is not red"
    );
    // The spheres of valid probes are not red anywhere in the first image.
    let reds = load_rgba(&dir.join("probes.png"))
        .pixels()
        .filter(|p| p[0] > 200 && p[1] < 30 && p[2] < 30)
        .count();
    assert_eq!(reds, 0);
}

// ---------------------------------------------------------------------------
// Agreement with three.js r187 (issue #21): mipmaps, alpha modes, vertex
// colours, texture coordinate sets, emission, double-sided lightmapped faces.
// The scenes are small hand-written glTFs (quads, PNG data URIs, and where
// a lightmap is needed a hand-written `MOZ_lightmap`).

/// One quad of a material test scene: spanned from `origin` by `u` and `v`
/// (facing u × v), with per-corner `TEXCOORD_0` and `TEXCOORD_1` (corner
/// order (0,0), (1,0), (1,1), (0,1)), an optional `COLOR_0`, and its
/// glTF material (JSON).
struct TestQuad {
    origin: [f32; 3],
    u: [f32; 3],
    v: [f32; 3],
    uv0: [[f32; 2]; 4],
    uv1: [[f32; 2]; 4],
    color: Option<[f32; 4]>,
    material: serde_json::Value,
}

impl TestQuad {
    /// A quad with the same UV at every corner of both sets.
    fn flat(origin: [f32; 3], u: [f32; 3], v: [f32; 3], uv0: [f32; 2], uv1: [f32; 2]) -> Self {
        TestQuad {
            origin,
            u,
            v,
            uv0: [uv0; 4],
            uv1: [uv1; 4],
            color: None,
            material: serde_json::json!({}),
        }
    }
}

/// A texture of a test scene: its pixels (RGBA8, RGB sRGB) and its glTF
/// sampler (JSON; `null` for none).
struct TestTexture {
    image: image::RgbaImage,
    sampler: serde_json::Value,
}

/// Appends a data-URI buffer, its view and an accessor of `count` elements
/// of `kind` (floats) to `doc`; returns the accessor.
fn append_floats(doc: &mut serde_json::Value, data: &[f32], count: usize, kind: &str) -> usize {
    use base64::Engine as _;
    let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    let push = |doc: &mut serde_json::Value, key: &str, v: serde_json::Value| {
        let a = doc[key].as_array_mut().unwrap();
        a.push(v);
        a.len() - 1
    };
    let buffer = push(
        doc,
        "buffers",
        serde_json::json!({"byteLength": bytes.len(), "uri": uri}),
    );
    let view = push(
        doc,
        "bufferViews",
        serde_json::json!({"buffer": buffer, "byteLength": bytes.len()}),
    );
    push(
        doc,
        "accessors",
        serde_json::json!({"bufferView": view, "componentType": 5126, "count": count, "type": kind}),
    )
}

/// A PNG data URI of `img`.
fn png_data_uri(img: &image::RgbaImage) -> String {
    use base64::Engine as _;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&png)
    )
}

/// Writes `dir/<name>.gltf`: a node per quad (each its own mesh and
/// material), the textures (texture i = image i, with its sampler), and
/// `extensionsUsed`; returns the path.
fn material_scene(
    dir: &Path,
    name: &str,
    quads: &[TestQuad],
    textures: &[TestTexture],
    extensions: &[&str],
) -> PathBuf {
    let mut b = GltfBuilder::default();
    for (i, q) in quads.iter().enumerate() {
        let (p, idx) = quad(q.origin, q.u, q.v);
        let m = b.mesh(&p, &idx, None);
        b.node(&format!("quad{i}"), m);
    }
    let mut doc = b.json();
    for (i, q) in quads.iter().enumerate() {
        let uv0 = append_floats(&mut doc, q.uv0.as_flattened(), 4, "VEC2");
        let uv1 = append_floats(&mut doc, q.uv1.as_flattened(), 4, "VEC2");
        let prim = &mut doc["meshes"][i]["primitives"][0];
        prim["material"] = serde_json::json!(i);
        prim["attributes"]["TEXCOORD_0"] = serde_json::json!(uv0);
        prim["attributes"]["TEXCOORD_1"] = serde_json::json!(uv1);
        if let Some(c) = q.color {
            let colors = append_floats(&mut doc, &c.repeat(4), 4, "VEC4");
            doc["meshes"][i]["primitives"][0]["attributes"]["COLOR_0"] = serde_json::json!(colors);
        }
    }
    doc["materials"] = quads.iter().map(|q| q.material.clone()).collect();
    let mut samplers = Vec::new();
    let mut texs = Vec::new();
    for (i, t) in textures.iter().enumerate() {
        let mut tex = serde_json::json!({"source": i});
        if !t.sampler.is_null() {
            samplers.push(t.sampler.clone());
            tex["sampler"] = serde_json::json!(samplers.len() - 1);
        }
        texs.push(tex);
    }
    let images: Vec<serde_json::Value> = textures
        .iter()
        .map(|t| serde_json::json!({"uri": png_data_uri(&t.image)}))
        .collect();
    doc["images"] = serde_json::json!(images);
    doc["textures"] = serde_json::json!(texs);
    doc["samplers"] = serde_json::json!(samplers);
    doc["extensionsUsed"] = serde_json::json!(extensions);
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// A texture of `w` × `h` texels, texel (x, y) = `f(x, y)`.
fn texture_of(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> image::RgbaImage {
    image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)))
}

/// glTF sampler JSON: nearest magnification and minification, no mipmaps.
fn nearest() -> serde_json::Value {
    serde_json::json!({"magFilter": 9728, "minFilter": 9728})
}

/// Linear RGB of pixel (x, y).
fn linear_at(img: &image::RgbaImage, (x, y): (u32, u32)) -> Vec3 {
    let p = img.get_pixel(x, y);
    Vec3::new(
        srgb_to_linear(p[0]),
        srgb_to_linear(p[1]),
        srgb_to_linear(p[2]),
    )
}

/// The pixel of a `w` × `h` render by `render_at` (from `from` towards
/// `at`, the preview's 50° field of view) that world point `p` falls on.
fn pixel_of(p: Vec3, from: Vec3, at: Vec3, (w, h): (u32, u32)) -> (u32, u32) {
    use radbake::preview::camera::Camera;
    let c = Camera::look_at(from, at, 50f32.to_radians(), 1.0);
    let clip = c.view_proj(w as f32 / h as f32) * p.extend(1.0);
    let ndc = Vec2::new(clip.x, clip.y) / clip.w;
    let x = ((ndc.x + 1.0) * 0.5 * w as f32).floor();
    let y = ((1.0 - ndc.y) * 0.5 * h as f32).floor();
    (
        x.clamp(0.0, w as f32 - 1.0) as u32,
        y.clamp(0.0, h as f32 - 1.0) as u32,
    )
}

fn assert_close(got: Vec3, want: Vec3, tol: f32, what: &str) {
    assert!(
        (got - want).abs().max_element() <= tol,
        "{what}: got {got}, want {want} (±{tol})"
    );
}

/// Every base-colour and emissive texture is uploaded with its full mip
/// chain (1 + ⌊log2 max(w, h)⌋ levels), so the GPU can filter trilinearly.
#[test]
fn textures_are_uploaded_with_full_mip_chains() {
    let dir = temp_dir("preview-mip-levels");
    let mut q = TestQuad::flat(
        [-1.0, -1.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [0.5; 2],
        [0.5; 2],
    );
    q.material = serde_json::json!({
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
        "emissiveTexture": {"index": 1}, "emissiveFactor": [1.0, 1.0, 1.0]
    });
    let grey = |_, _| [90, 90, 90, 255];
    let textures = [
        TestTexture {
            image: texture_of(64, 24, grey),
            sampler: serde_json::Value::Null,
        },
        TestTexture {
            image: texture_of(5, 3, grey),
            sampler: serde_json::Value::Null,
        },
    ];
    let gltf = material_scene(&dir, "mips", &[q], &textures, &[]);
    let model = model::Model::load(&gltf).unwrap();
    assert_eq!(model.scene.textures.len(), 2);
    let (_, device, queue) = match radbake::preview::offscreen_device() {
        Ok(d) => d,
        Err(e @ radbake::Error::NoAdapter(_)) => {
            eprintln!("SKIPPED (no GPU or software adapter on this machine): {e}");
            return;
        }
        Err(e) => panic!("{e:#}"),
    };
    let camera = radbake::preview::initial_camera(&model, &Default::default()).unwrap();
    let r = radbake::preview::renderer::Renderer::new(
        &device,
        &queue,
        wgpu::TextureFormat::Rgba8Unorm,
        &model,
        camera,
        Default::default(),
    );
    // 64 × 24: 64, 32, …, 1 (7 levels); 5 × 3: 5, 2, 1 (3 levels).
    assert_eq!(r.texture_mip_levels(), [7, 3]);
}

/// Mipmapping: a 400 m floor under a 64 × 64 one-texel checker (sRGB 40 and
/// 240; 10 cm texels) seen at a grazing angle from 1 m up. Far away, where
/// a pixel covers many texels, trilinear filtering gives the checker's
/// linear mean (sRGB 178) in every pixel; level 0 alone (the preview
/// before mipmaps) gave grain of 40s and 240s. Close by, the checker is
/// still resolved (the mips do not blur what a pixel can show).
#[test]
fn distant_textured_floor_is_filtered_to_its_mean() {
    let dir = temp_dir("preview-mip-floor");
    let size = 400.0;
    let h = size * 0.5;
    let uv = |x: f32, z: f32| [x / 6.4, z / 6.4];
    let q = TestQuad {
        origin: [-h, 0.0, -h],
        u: [0.0, 0.0, size],
        v: [size, 0.0, 0.0],
        uv0: [uv(-h, -h), uv(-h, h), uv(h, h), uv(h, -h)],
        uv1: [[0.0; 2]; 4],
        color: None,
        material: serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
    };
    let checker = texture_of(64, 64, |x, y| {
        let v = if (x + y) % 2 == 0 { 40 } else { 240 };
        [v, v, v, 255]
    });
    let textures = [TestTexture {
        image: checker,
        sampler: serde_json::Value::Null,
    }];
    let gltf = material_scene(&dir, "floor", &[q], &textures, &[]);
    let png = dir.join("floor.png");
    let Some(img) = render_at(
        &gltf,
        &png,
        "albedo",
        Vec3::new(0.0, 1.0, 190.0),
        Vec3::new(0.0, -1.0, 170.0),
    ) else {
        return;
    };
    let (w, hgt) = img.dimensions();
    // The horizon: the first row (from the top) where the floor shows.
    let horizon = (0..hgt)
        .find(|&y| img.get_pixel(w / 2, y)[0] > 0)
        .expect("the floor is visible");
    let stats = |rows: std::ops::Range<u32>| {
        let v: Vec<f64> = rows
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| img.get_pixel(x, y)[1] as f64)
            .collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
        (mean, var.sqrt())
    };
    let want = 255.0 * srgb_linear_to_encoded(0.5 * (srgb_to_linear(40) + srgb_to_linear(240)));
    let (far_mean, far_sd) = stats(horizon + 2..horizon + 22);
    let (near_mean, near_sd) = stats(hgt - 6..hgt);
    eprintln!(
        "horizon row {horizon}: far mean {far_mean:.1} sd {far_sd:.2} (want {want:.1}); near mean {near_mean:.1} sd {near_sd:.1}"
    );
    assert!(
        horizon > 10 && horizon + 22 < hgt - 6,
        "horizon at row {horizon}"
    );
    assert!(
        (far_mean - want).abs() < 4.0 && far_sd < 3.0,
        "far floor: mean {far_mean:.1} (want {want:.1}), sd {far_sd:.2} (want < 3)"
    );
    assert!(
        near_sd > 15.0,
        "near floor: the checker is blurred away (sd {near_sd:.1})"
    );
}

/// sRGB encoding of a linear value in [0, 1] (IEC 61966-2-1).
fn srgb_linear_to_encoded(c: f32) -> f64 {
    let e = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    e as f64
}

/// The albedo view's colour at the centres of the three quads the
/// material tests lay out along x (None without a graphics adapter).
fn three_quads_albedo(gltf: &std::path::Path) -> Option<Vec<Vec3>> {
    let points: Vec<Vec3> = (0..3)
        .map(|k| Vec3::new(-2.0 + 2.2 * k as f32, 0.0, 0.0))
        .collect();
    colours_at(
        gltf,
        "albedo",
        Vec3::new(0.2, 0.0, 9.0),
        Vec3::new(0.2, 0.0, 0.0),
        &points,
    )
}

/// Pixels at the centres of `points`, rendered (albedo or lit view, no
/// tone map) from `from` towards `at`; None without an adapter.
fn colours_at(gltf: &Path, view: &str, from: Vec3, at: Vec3, points: &[Vec3]) -> Option<Vec<Vec3>> {
    let png = gltf.with_extension(format!("{view}.{}.png", from.z.signum()));
    let img = render_at(gltf, &png, view, from, at)?;
    Some(
        points
            .iter()
            .map(|&p| linear_at(&img, pixel_of(p, from, at, img.dimensions())))
            .collect(),
    )
}

/// glTF `BLEND` is blended as three.js blends it on its canvas
/// (`transparent: true`, `NormalBlending`): not cut out (alpha 0.4 is
/// under the 0.5 the preview used to cut BLEND at), colour × α +
/// destination × (1 − α) on sRGB-encoded values (three.js encodes in the
/// shader), after the opaque objects, and back to front by object (so the
/// result depends on the side it is seen from). Here two double-sided
/// 40 %-opaque quads, red at z = 0 and blue at z = −1, seen from +Z over
/// an opaque single-sided green quad at z = −2 (listed last, drawn first),
/// and from −Z over the black background (the green quad's back face is
/// culled).
#[test]
fn blend_materials_are_blended_back_to_front() {
    let dir = temp_dir("preview-blend");
    let mut quads = Vec::new();
    for (z, colour) in [(0.0, [1.0, 0.0, 0.0]), (-1.0, [0.0, 0.0, 1.0])] {
        let mut q = TestQuad::flat(
            [-1.0, -1.0, z],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0; 2],
            [0.0; 2],
        );
        // Black base colour (no lightmap here): the lit view shows the
        // emission, with the base colour's alpha.
        q.material = serde_json::json!({
            "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 0.4]},
            "emissiveFactor": colour,
            "alphaMode": "BLEND", "doubleSided": true
        });
        quads.push(q);
    }
    let mut green = TestQuad::flat(
        [-2.0, -2.0, -2.0],
        [4.0, 0.0, 0.0],
        [0.0, 4.0, 0.0],
        [0.0; 2],
        [0.0; 2],
    );
    green.material = serde_json::json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]},
        "emissiveFactor": [0.0, 1.0, 0.0]
    });
    quads.push(green);
    let gltf = material_scene(&dir, "blend", &quads, &[], &[]);
    let model = model::Model::load(&gltf).unwrap();
    assert!(model.materials[..2].iter().all(|m| m.blend) && !model.materials[2].blend);
    let origins: Vec<bool> = model.batches.iter().map(|b| b.origin.is_some()).collect();
    assert_eq!(
        origins,
        [false, true, true],
        "opaque batches first, one per blended object"
    );
    let centre = [Vec3::new(0.0, 0.0, -0.5)];
    let at = Vec3::new(0.0, 0.0, -0.5);
    // Encoded values, compared in linear.
    let decoded = |v: Vec3| {
        v.to_array()
            .map(|c| srgb_to_linear((c * 255.0).round() as u8))
    };
    // From +Z: green, then blue (far), then red: encoded (0.4, 0.6 × 0.6,
    // 0.6 × 0.4).
    let Some(front) = colours_at(&gltf, "lit", Vec3::new(0.0, 0.0, 6.0), at, &centre) else {
        return;
    };
    let want = Vec3::from_array(decoded(Vec3::new(0.4, 0.36, 0.24)));
    assert_close(front[0], want, 0.005, "seen from +Z");
    // From −Z: red is the far one.
    let back = colours_at(&gltf, "lit", Vec3::new(0.0, 0.0, -7.0), at, &centre).unwrap();
    let want = Vec3::from_array(decoded(Vec3::new(0.24, 0.0, 0.4)));
    assert_close(back[0], want, 0.005, "seen from -Z");
}

/// `COLOR_0` multiplies the base colour (three.js `color_fragment`: RGB
/// and alpha), and `MASK` cuts out at `alphaCutoff` on the product
/// (`alphatest_fragment`): quad 0 (COLOR_0 (0.5, 0.25, 1, 1) × factor
/// (1, 1, 0.5)) shows (0.5, 0.25, 0.5); quad 1 (same colours, COLOR_0
/// alpha 0.3, MASK at 0.5) is cut out; quad 2 (no COLOR_0) shows its factor.
#[test]
fn vertex_colours_multiply_base_colour_and_alpha() {
    let dir = temp_dir("preview-colours");
    let mut quads = Vec::new();
    for (k, (alpha, mode)) in [(1.0, "OPAQUE"), (0.3, "MASK"), (1.0, "OPAQUE")]
        .into_iter()
        .enumerate()
    {
        let x = -3.0 + 2.2 * k as f32;
        let mut q = TestQuad::flat(
            [x, -1.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0; 2],
            [0.0; 2],
        );
        q.color = (k < 2).then_some([0.5, 0.25, 1.0, alpha]);
        q.material = serde_json::json!({
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 0.5, 1.0]},
            "alphaMode": mode
        });
        quads.push(q);
    }
    let gltf = material_scene(&dir, "colours", &quads, &[], &[]);
    let model = model::Model::load(&gltf).unwrap();
    assert!(model.scene.meshes[..2].iter().all(|m| m.colors.is_some()));
    assert!(model.scene.meshes[2].colors.is_none());
    let Some(c) = three_quads_albedo(&gltf) else {
        return;
    };
    assert_close(c[0], Vec3::new(0.5, 0.25, 0.5), 0.01, "COLOR_0 × factor");
    assert_close(c[1], Vec3::ZERO, 0.0, "COLOR_0 alpha under the cutoff");
    assert_close(c[2], Vec3::new(1.0, 1.0, 0.5), 0.01, "no COLOR_0");
}

/// Texture coordinate sets and transforms as three.js's GLTFLoader reads
/// them, through a 2 × 2 texture of four colours sampled NEAREST (the
/// sampler's filters are followed): `texCoord: 1` reads `TEXCOORD_1`
/// (three.js `texture.channel = 1`); `KHR_texture_transform.texCoord`
/// overrides the texture info's; a rotated transform is T·R·S (three.js
/// sets `texture.matrix` so, not its own T·S·R).
#[test]
fn texture_coordinate_sets_and_transforms_follow_gltf() {
    let dir = temp_dir("preview-texcoord");
    // Texels: (0,0) red, (1,0) green, (0,1) blue, (1,1) white.
    let colours = [
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [255; 4],
    ];
    let tex = texture_of(2, 2, |x, y| colours[(y * 2 + x) as usize]);
    let base = |info: serde_json::Value| serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": info}});
    // TEXCOORD_0 points at red, TEXCOORD_1 at green.
    let (uv_red, uv_green) = ([0.25, 0.25], [0.75, 0.25]);
    let transform = |t: serde_json::Value| serde_json::json!({"index": 0, "extensions": {"KHR_texture_transform": t}});
    let materials = [
        base(serde_json::json!({"index": 0, "texCoord": 1})),
        base(transform(serde_json::json!({"texCoord": 1}))),
        // uv' = T R S uv with S = (2, 1), rotation π/2: (v, −2u) =
        // (0.25, −0.5) → (0.25, 0.5) wrapped: blue. T S R would give
        // (0.5, −0.25) → green/white edge, and the other sense of rotation
        // (−0.25, 0.5) → white.
        base(transform(
            serde_json::json!({"rotation": std::f32::consts::FRAC_PI_2, "scale": [2.0, 1.0]}),
        )),
    ];
    let quads: Vec<TestQuad> = materials
        .into_iter()
        .enumerate()
        .map(|(k, material)| {
            let x = -3.0 + 2.2 * k as f32;
            let mut q = TestQuad::flat(
                [x, -1.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                uv_red,
                uv_green,
            );
            q.material = material;
            q
        })
        .collect();
    let textures = [TestTexture {
        image: tex,
        sampler: nearest(),
    }];
    let gltf = material_scene(
        &dir,
        "texcoord",
        &quads,
        &textures,
        &["KHR_texture_transform"],
    );
    let model = model::Model::load(&gltf).unwrap();
    let sets: Vec<u32> = model.scene.materials[..3]
        .iter()
        .map(|m| m.albedo_texture.as_ref().unwrap().tex_coord)
        .collect();
    assert_eq!(sets, [1, 1, 0]);
    let Some(c) = three_quads_albedo(&gltf) else {
        return;
    };
    assert_close(c[0], Vec3::new(0.0, 1.0, 0.0), 0.01, "texCoord 1");
    assert_close(
        c[1],
        Vec3::new(0.0, 1.0, 0.0),
        0.01,
        "KHR_texture_transform.texCoord 1",
    );
    assert_close(c[2], Vec3::new(0.0, 0.0, 1.0), 0.01, "rotation: T·R·S");
}

/// Emission as three.js's Lambert material adds it: `emissiveFactor` ×
/// `KHR_materials_emissive_strength` × the emissive texture (read through
/// its own `texCoord`, here 1) on top of base colour × lightmap (none here,
/// and no ambient or other light: black base colour shows emission alone).
#[test]
fn emission_is_factor_times_strength_times_texture() {
    let dir = temp_dir("preview-emission");
    let tex = texture_of(2, 1, |x, _| {
        if x == 0 {
            [128, 128, 128, 255]
        } else {
            [255, 0, 64, 255]
        }
    });
    let mut q = TestQuad::flat(
        [-1.0, -1.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [0.25, 0.5],
        [0.75, 0.5],
    );
    q.material = serde_json::json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]},
        "emissiveFactor": [1.0, 0.5, 1.0],
        "emissiveTexture": {"index": 0, "texCoord": 1},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 0.5}}
    });
    let textures = [TestTexture {
        image: tex,
        sampler: nearest(),
    }];
    let gltf = material_scene(
        &dir,
        "emission",
        &[q],
        &textures,
        &["KHR_materials_emissive_strength"],
    );
    let Some(c) = colours_at(
        &gltf,
        "lit",
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::ZERO,
        &[Vec3::ZERO],
    ) else {
        return;
    };
    let want = Vec3::new(0.5, 0.0, 0.5 * srgb_to_linear(64));
    assert_close(c[0], want, 0.01, "emission");
}

/// A double-sided lightmapped face reads the same lightmap texel from both
/// sides (three.js flips the normal for back faces, but the lightmap
/// lookup is by `TEXCOORD_1` alone), while a single-sided one is culled
/// from behind. Quad A (double-sided) and quad B (single-sided) share a
/// 2 × 1 lightmap page (sRGB 200 | 60, `MOZ_lightmap.intensity` π, so the
/// value is the decoded texel) across their width; base colour white.
#[test]
fn double_sided_lightmapped_faces_read_the_same_texel_from_both_sides() {
    let dir = temp_dir("preview-two-sided");
    let lightmap = texture_of(2, 1, |x, _| {
        if x == 0 {
            [200, 200, 200, 255]
        } else {
            [60, 60, 60, 255]
        }
    });
    let mut quads = Vec::new();
    for (x, double_sided) in [(-2.2, true), (0.2, false)] {
        let mut q = TestQuad::flat(
            [x, -1.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0; 2],
            [0.0; 2],
        );
        q.uv1 = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        q.material = serde_json::json!({
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0]},
            "doubleSided": double_sided,
            "extensions": {"MOZ_lightmap": {"index": 0, "texCoord": 1, "intensity": std::f32::consts::PI}}
        });
        quads.push(q);
    }
    let textures = [TestTexture {
        image: lightmap,
        // The sampler radbake writes for its pages (three.js then makes no
        // mipmaps and clamps, as the preview samples every lightmap).
        sampler: serde_json::json!({"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}),
    }];
    let gltf = material_scene(&dir, "two_sided", &quads, &textures, &["MOZ_lightmap"]);
    // A's left and right quarters (lightmap texels 0 and 1), B's centre.
    let points = [
        Vec3::new(-1.7, 0.0, 0.0),
        Vec3::new(-0.7, 0.0, 0.0),
        Vec3::new(1.2, 0.0, 0.0),
    ];
    let at = Vec3::new(-0.5, 0.0, 0.0);
    let Some(front) = colours_at(&gltf, "lit", Vec3::new(-0.5, 0.0, 8.0), at, &points) else {
        return;
    };
    let back = colours_at(&gltf, "lit", Vec3::new(-0.5, 0.0, -8.0), at, &points).unwrap();
    let (t0, t1) = (
        Vec3::splat(srgb_to_linear(200)),
        Vec3::splat(srgb_to_linear(60)),
    );
    assert_close(front[0], t0, 0.01, "A's texel 0 from the front");
    assert_close(front[1], t1, 0.01, "A's texel 1 from the front");
    assert_close(back[0], t0, 0.01, "A's texel 0 from behind");
    assert_close(back[1], t1, 0.01, "A's texel 1 from behind");
    assert_close(
        front[2],
        Vec3::splat(0.5 * (t0.x + t1.x)),
        0.02,
        "B from the front",
    );
    assert_close(back[2], Vec3::ZERO, 0.0, "B (single-sided) from behind");
}

/// The sunlit box of the distance-field tests: a 4 m ground (albedo 0.5)
/// at y = 0, a closed 1 m box on it (x, z in [−0.5, 0.5]), a `realtime`
/// sun of `SDF_SUN` W/m² towards `sdf_to_sun()` (so the lightmap holds
/// only the sky's light and the preview draws the sun), a sky of 0.2, a
/// probe volume over the ground, and two dynamic 0.3 m cubes on the
/// ground on the sunlit side: one 5 cm from the box's +x face, one 0.9 m
/// from it. Baked in process once with a distance field of 256 voxels
/// along the longest side (1.6 cm); returns the folder.
fn baked_sdf_scene() -> &'static Path {
    static BAKED: OnceLock<PathBuf> = OnceLock::new();
    BAKED.get_or_init(|| {
        let dir = temp_dir("preview-sdf");
        let mut b = GltfBuilder::default();
        let grey = b.material([0.5; 3], [0.0; 3]);
        let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
        let m = b.mesh(&p, &i, Some(grey));
        b.node("ground", m);
        let (p, i) = cube([-0.5, 0.0, -0.5], 1.0);
        let m = b.mesh(&p, &i, Some(grey));
        b.node("box", m);
        let mut dynamic = Vec::new();
        for (name, x) in [("near", 0.55), ("far", 1.4)] {
            let (p, i) = cube([x, 0.0, -0.15], 0.3);
            let m = b.mesh(&p, &i, Some(grey));
            dynamic.push(b.node(name, m));
        }
        let mut doc = b.json();
        for n in dynamic {
            doc["nodes"][n]["extras"] = serde_json::json!({"radbake": {"dynamic": true}});
        }
        let rot = glam::Quat::from_rotation_arc(Vec3::NEG_Z, -sdf_to_sun());
        let nodes = doc["nodes"].as_array_mut().unwrap();
        nodes.push(
            serde_json::json!({"name": "sun", "rotation": rot.to_array(),
            "extensions": {"KHR_lights_punctual": {"light": 0}},
            "extras": {"radbake": {"mode": "realtime"}}}),
        );
        nodes.push(serde_json::json!({
            "name": "probe_box", "translation": [0.0, 1.0, 0.0], "scale": [4.0, 2.0, 4.0],
            "extras": {"radbake": {"probe_volume": {"spacing": 0.5}}}
        }));
        let n = nodes.len();
        doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
        doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
        doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": SDF_SUN}]}});
        let gltf = dir.join("scene.gltf");
        std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
        let scene = radbake::scene::load(&gltf, &Default::default()).unwrap();
        let config = radbake::BakeConfig {
            sky: [0.2; 3],
            texels_per_meter: 8.0,
            sdf: 256,
            ..Default::default()
        };
        let bake = radbake::bake(&scene, &config, &radbake::Silent).unwrap();
        let out = dir.join("out");
        radbake::output::write_engine_outputs(&out, "scene", &bake).unwrap();
        assert!(out.join("sdf.ktx2").exists());
        out
    })
}

/// The distance-field scene's sun (W/m²) and the unit vector towards it.
const SDF_SUN: f32 = 2.0;
fn sdf_to_sun() -> Vec3 {
    Vec3::new(1.0, 2.0, 0.5).normalize()
}

/// The viewpoint of the shadow test: above the box's shadow, looking
/// down on it.
const SDF_EYE: Vec3 = Vec3::new(-1.2, 3.0, -0.3);
const SDF_AT: Vec3 = Vec3::new(-0.6, 0.0, -0.3);

/// Under the `realtime` sun, the box's shadow on the ground, sphere-traced
/// through the baked field in the preview, covers as many pixels as the
/// ray-cast shadow: every pixel whose camera ray first meets the ground
/// (cast through the scene's BVH) is shadowed in the reference where a
/// ray from that point towards the sun meets the box, and in the preview
/// where the sun's share of the pixel (lit with shadows against lit
/// without, `--no-sdf-shadows`) is under half of base colour × E cos θ / π.
/// The two counts agree within 5 % (the bound); the preview's
/// shadow also lies where the reference's does (≥ 95 % of its pixels).
#[test]
fn sphere_traced_sun_shadow_matches_the_ray_cast_one() {
    let out = baked_sdf_scene();
    let glb = out.join("scene.baked.glb");
    let dir = temp_dir("preview-sdf-shadow");
    let (w, h) = (320u32, 240u32);
    let look = look_args(SDF_EYE, SDF_AT);
    let render = |name: &str, extra: &[&str]| {
        let png = dir.join(name);
        let mut args = vec!["--size", "320x240", "--tone-map", "none"];
        args.extend(look.iter().map(String::as_str));
        args.extend(extra);
        headless(&glb, &png, &args).map(|_| load_rgba(&png))
    };
    let Some(shadowed) = render("shadowed.png", &[]) else {
        return;
    };
    let unshadowed = render("unshadowed.png", &["--no-sdf-shadows"]).unwrap();
    // The reference: the same camera's rays through the BVH.
    let model = model::Model::load(&glb).unwrap();
    let viewpoint = radbake::preview::Viewpoint::LookAt {
        from: SDF_EYE,
        at: Some(SDF_AT),
    };
    let camera = radbake::preview::initial_camera(&model, &viewpoint).unwrap();
    let world_from_clip = camera.view_proj(w as f32 / h as f32).inverse();
    let scene = radbake::scene::load(&glb, &Default::default()).unwrap();
    let geometry = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &geometry);
    let sun_share = 0.5 * SDF_SUN * sdf_to_sun().y / std::f32::consts::PI;
    let (mut reference, mut preview, mut both) = (0usize, 0usize, 0usize);
    for y in 0..h {
        for x in 0..w {
            let ndc = glam::Vec2::new(
                (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / h as f32 * 2.0,
            );
            let near = world_from_clip.project_point3(ndc.extend(1.0));
            let dir = (world_from_clip.project_point3(ndc.extend(0.5)) - near).normalize();
            let Some(hit) = rays.closest_hit(near, dir, 1e3) else {
                continue;
            };
            let p = near + dir * hit.t;
            let ground = p.y.abs() < 1e-3 && geometry.ng_ws[hit.tri as usize].y > 0.99;
            if !ground {
                continue;
            }
            let in_reference = !rays.unoccluded(p + Vec3::Y * 1e-4, sdf_to_sun(), 1e3);
            let lin = |img: &image::RgbaImage| srgb_to_linear(img.get_pixel(x, y)[1]);
            let sun = lin(&unshadowed) - lin(&shadowed);
            let in_preview = sun > 0.5 * sun_share;
            reference += in_reference as usize;
            preview += in_preview as usize;
            both += (in_reference && in_preview) as usize;
        }
    }
    let ratio = preview as f64 / reference as f64;
    eprintln!(
        "sun shadow: ray-cast {reference} px, sphere-traced {preview} px ({:+.2} %), {both} in both",
        (ratio - 1.0) * 100.0
    );
    assert!(
        reference > 3000,
        "the shadow is too small to judge: {reference} px"
    );
    assert!((ratio - 1.0).abs() <= 0.05, "area ratio {ratio}");
    assert!(
        both as f64 >= 0.95 * reference as f64,
        "{both} of {reference}"
    );
}

/// Distance-field ambient occlusion darkens a probe-lit cube next to the
/// box and not one in the open: the lightmap view (the probes' light on
/// dynamic surfaces) of each cube's top face with DFAO (reach 1 m, the
/// default) against without (`--dfao-reach 0`). The far cube keeps ≥ 95 %
/// of its light (only its cone towards the box, 0.9 m away, grazes the
/// box's top edge at the end of its reach); the near one, whose cone
/// towards the box's wall is blocked 5 cm away, keeps at least 15 points
/// less (measured: 0.699 against 0.965 on lavapipe).
#[test]
fn distance_field_occlusion_darkens_a_cube_beside_the_box() {
    let out = baked_sdf_scene();
    let glb = out.join("scene.baked.glb");
    let dir = temp_dir("preview-dfao");
    let eye = Vec3::new(1.0, 3.0, 0.01);
    let at = Vec3::new(1.0, 0.0, 0.0);
    let Some(with) = render_at(&glb, &dir.join("with.png"), "lightmap", eye, at) else {
        return;
    };
    let args = [
        "--size",
        "160x120",
        "--tone-map",
        "none",
        "--view",
        "lightmap",
    ];
    let png = dir.join("without.png");
    let look = look_args(eye, at);
    let mut extra: Vec<&str> = args.to_vec();
    extra.extend(look.iter().map(String::as_str));
    extra.extend(["--dfao-reach", "0"]);
    headless(&glb, &png, &extra).unwrap();
    let without = load_rgba(&png);
    // The top faces' centres, projected.
    let ratio = |centre: Vec3| {
        let (x, y) = pixel_of(centre, eye, at, (160, 120));
        let lin = |img: &image::RgbaImage| srgb_to_linear(img.get_pixel(x, y)[1]);
        lin(&with) / lin(&without)
    };
    let near = ratio(Vec3::new(0.7, 0.3, 0.0));
    let far = ratio(Vec3::new(1.55, 0.3, 0.0));
    eprintln!("DFAO: top face of the near cube keeps {near:.3}, the far one {far:.3}");
    assert!(far >= 0.95, "far cube {far}");
    assert!(near < far - 0.15, "near {near} far {far}");
}

/// The sdf view's sphere tracing (WGSL `sdf_trace`) finds the surfaces
/// that the CPU's [`radbake::sdf::Sdf::march`] finds, ray for ray: an
/// oblique view of the box scene (edges, grazing ground, rays that leave
/// the field), each pixel's ray rebuilt as the shader builds it, hit or
/// miss alike for all but 0.05 % of the pixels (trilinear filtering of
/// R16F on the GPU against f32 on the CPU moves a few silhouette pixels:
/// 4 of 19,200 on lavapipe; the older shader, which stopped within a tenth
/// of a voxel of any surface and stepped at least a quarter voxel, missed
/// 22).
#[test]
fn sdf_view_traces_as_the_cpu_marches() {
    use radbake::preview::camera::Camera;
    let out = baked_sdf_scene();
    let glb = out.join("scene.baked.glb");
    let dir = temp_dir("preview-sdf-march");
    let (eye, at) = (Vec3::new(2.6, 1.4, 3.1), Vec3::new(0.0, 0.25, 0.0));
    let (w, h) = (160u32, 120u32);
    let png = dir.join("surface.png");
    let mut args = vec!["--size", "160x120", "--view", "sdf", "--sdf-slice", "-5"];
    let look = look_args(eye, at);
    args.extend(look.iter().map(String::as_str));
    if headless(&glb, &png, &args).is_none() {
        return;
    }
    let image = load_rgba(&png);
    let field = radbake::preview::field::find(&glb).unwrap().unwrap();
    let sdf = radbake::sdf::Sdf {
        grid: radbake::sdf::Grid {
            origin: field.bounds.0,
            voxel: field.voxel,
            dims: field.dims,
        },
        distance: field.values,
        rays: 0,
    };
    let inv = Camera::look_at(eye, at, 50f32.to_radians(), 1.0)
        .view_proj(w as f32 / h as f32)
        .inverse();
    let (mut hits, mut differ) = (0u32, Vec::new());
    for y in 0..h {
        for x in 0..w {
            let ndc = Vec2::new(
                (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / h as f32 * 2.0,
            );
            let near = inv.project_point3(ndc.extend(1.0));
            let far = inv.project_point3(ndc.extend(0.5));
            let cpu = sdf
                .march(near, (far - near).normalize(), f32::INFINITY)
                .is_some();
            let gpu = image.get_pixel(x, y).0[..3].iter().any(|&c| c > 0);
            hits += cpu as u32;
            if cpu != gpu {
                differ.push((x, y, cpu));
            }
        }
    }
    let n = (w * h) as usize;
    eprintln!(
        "sdf view against the CPU march: {hits} of {n} pixels hit, {} differ: {:?}",
        differ.len(),
        &differ[..differ.len().min(12)]
    );
    assert!(
        hits as usize > n / 4 && (hits as usize) < n - n / 20,
        "{hits} hits"
    );
    assert!(
        differ.len() * 2000 <= n,
        "{} of {n} pixels differ",
        differ.len()
    );
}

/// The sdf view shows the field: looking down on the box scene, the pixel
/// over the box's top is the traced surface (normal +Y: its green
/// channel brightest), and with the slice plane at half the box's height
/// (the box's top cut away) that pixel shows the slice inside the box
/// (blue: d < 0) and a pixel over open ground the slice outside
/// (orange). Without a field the view warns.
#[test]
fn sdf_view_shows_the_surface_and_the_slice() {
    let out = baked_sdf_scene();
    let glb = out.join("scene.baked.glb");
    let dir = temp_dir("preview-sdf-view");
    let eye = Vec3::new(0.0, 4.0, 0.01);
    let at = Vec3::ZERO;
    let look = look_args(eye, at);
    let render = |name: &str, extra: &[&str]| {
        let png = dir.join(name);
        let mut args = vec!["--size", "160x120", "--view", "sdf"];
        args.extend(look.iter().map(String::as_str));
        args.extend(extra);
        headless(&glb, &png, &args).map(|_| load_rgba(&png))
    };
    // Slice below the ground: the traced surface everywhere.
    let Some(surface) = render("surface.png", &["--sdf-slice", "-1"]) else {
        return;
    };
    let centre = surface.get_pixel(80, 60);
    assert!(centre[1] > centre[0] && centre[1] > centre[2], "{centre:?}");
    let slice = render("slice.png", &["--sdf-slice", "0.5"]).unwrap();
    let inside = slice.get_pixel(80, 60);
    assert!(inside[2] > inside[0], "inside the box: {inside:?}");
    // 1.5 m along +x from the centre: open ground, 1 m from the box.
    let (x, y) = pixel_of(Vec3::new(1.5, 0.5, 0.0), eye, at, (160, 120));
    let outside = slice.get_pixel(x, y);
    assert!(outside[0] > outside[2], "outside: {outside:?}");
    // A bake without a field.
    let png = dir.join("none.png");
    let stderr = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("preview")
        .arg(scene_path("cornell_box.gltf"))
        .args(["--headless", "--size", "64x48", "--view", "sdf", "--out"])
        .arg(&png)
        .output()
        .unwrap()
        .stderr;
    let stderr = String::from_utf8_lossy(&stderr);
    assert!(stderr.contains("no distance field"), "{stderr}");
}
