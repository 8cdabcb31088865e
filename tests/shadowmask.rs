//! Shadowmask lights (issue #23): a light in `shadowmask` mode bakes as
//! `indirect` and writes its occlusion into one channel of RGBA pages.
//!
//! - Under a floating box, a point light's mask is exactly 0 in the umbra
//!   and 1 outside; the `baked` bake equals the `shadowmask` bake plus the
//!   light's unshadowed direct light × its mask.
//! - A sphere light's penumbra in the mask against the analytic one.
//! - Five overlapping lights: four channels, one named warning, the least
//!   reaching light baked as `indirect`; lights apart share channels, and
//!   no texel is reached by two lights of one channel.
//! - The files: PNG/EXR/KTX2 pages, the manifest, the report and the baked
//!   `.glb`'s material and light-node extras.

mod common;

use common::{check_penumbra, edge_scene, quad, temp_dir, GltfBuilder, DENSITY, H};
use glam::Vec3;
use radbake::{BakeConfig, Silent};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Ground half size, box (x, z in ±B, y in Y0..Y1), light height.
const A: f32 = 2.0;
const B: f32 = 0.5;
const Y0: f32 = 1.0;
const Y1: f32 = 1.5;
const LIGHT_Y: f32 = 4.0;
const INTENSITY: f32 = 50.0;

/// The six outward faces of the box x, z ∈ ±B, y ∈ Y0..Y1.
fn cube(b: &mut GltfBuilder, material: usize) -> usize {
    let s = 2.0 * B;
    let h = Y1 - Y0;
    let faces = [
        quad([-B, Y1, -B], [0.0, 0.0, s], [s, 0.0, 0.0]),
        quad([-B, Y0, -B], [s, 0.0, 0.0], [0.0, 0.0, s]),
        quad([B, Y0, -B], [0.0, h, 0.0], [0.0, 0.0, s]),
        quad([-B, Y0, -B], [0.0, 0.0, s], [0.0, h, 0.0]),
        quad([-B, Y0, B], [s, 0.0, 0.0], [0.0, h, 0.0]),
        quad([-B, Y0, -B], [0.0, h, 0.0], [s, 0.0, 0.0]),
    ];
    let (mut p, mut i) = (Vec::new(), Vec::new());
    for (fp, fi) in faces {
        let base = p.len() as u32;
        p.extend(fp);
        i.extend(fi.iter().map(|k| k + base));
    }
    b.mesh(&p, &i, Some(material))
}

/// A grey ground (ρ 0.5, half size `A`) under a grey box, lit by point
/// lights (position, range, extras of the node); written to `name`.
fn box_scene(name: &str, ground: f32, lights: &[([f32; 3], Option<f32>, Value)]) -> PathBuf {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad(
        [-ground, 0.0, -A],
        [0.0, 0.0, 2.0 * A],
        [2.0 * ground, 0.0, 0.0],
    );
    let m = b.mesh(&p, &i, Some(grey));
    b.node("ground", m);
    let c = cube(&mut b, grey);
    b.node("box", c);
    let mut doc = b.json();
    let mut defs = Vec::new();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    for (k, (pos, range, extras)) in lights.iter().enumerate() {
        let mut def = json!({"type": "point", "intensity": INTENSITY, "name": format!("lamp{k}")});
        if let Some(r) = range {
            def["range"] = json!(r);
        }
        defs.push(def);
        nodes.push(json!({"name": format!("lamp{k}_node"), "translation": pos,
            "extensions": {"KHR_lights_punctual": {"light": k}}, "extras": extras}));
    }
    let n = nodes.len();
    doc["scenes"][0]["nodes"] = json!((0..n).collect::<Vec<_>>());
    doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc["extensions"] = json!({"KHR_lights_punctual": {"lights": defs}});
    let path = temp_dir(name).join("box.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

fn mode(m: &str) -> Value {
    json!({"radbake": {"mode": m}})
}

fn config() -> BakeConfig {
    BakeConfig {
        texels_per_meter: 20.0,
        probes: false,
        ..BakeConfig::default()
    }
}

/// Ground texels (instance 0) wholly covered by the ground, at density `d`.
fn full_ground_texels(bake: &radbake::Bake, d: f32) -> Vec<usize> {
    let w = 1.0 / d;
    (0..bake.texels.len())
        .filter(|&t| bake.texels.instance[t] == 0 && bake.texels.area[t] >= 0.99 * w * w)
        .collect()
}

/// A delta point light over the box: the mask is 0 on every ground texel
/// inside the box's shadow (the top face's outline projected from the
/// light, half width B·LIGHT_Y/(LIGHT_Y − Y1)) by more than 1.5 texels, 1
/// on every one outside it by as much, and 0 in the unused channels; the
/// pages hold the texels' values. The `baked` bake equals the
/// `shadowmask` bake plus the unshadowed I cos θ / (π d²) × the mask.
#[test]
fn mask_is_zero_in_the_umbra_and_one_outside() {
    let light = [0.0, LIGHT_Y, 0.0];
    let masked = box_scene("mask-box", A, &[(light, None, mode("shadowmask"))]);
    let scene = radbake::scene::load(&masked, &Default::default()).unwrap();
    let bake = radbake::bake(&scene, &config(), &Silent).unwrap();
    let mask = bake.shadowmask.as_ref().expect("a shadowmask");
    assert_eq!(mask.channel, [Some(0)]);
    assert!(
        mask.fallback.is_empty() && bake.warnings.is_empty(),
        "{:?}",
        bake.warnings
    );
    assert!(mask.rays > 0);

    let w = 1.0 / 20.0;
    let edge = B * LIGHT_Y / (LIGHT_Y - Y1);
    let (mut umbra, mut lit) = (0, 0);
    for t in full_ground_texels(&bake, 20.0) {
        let p = bake.texels.p_ws[t];
        let s = p.x.abs().max(p.z.abs());
        let m = mask.texel_values[t];
        assert_eq!(&m[1..], &[0.0; 3], "unused channels at {p}");
        if s < edge - 1.5 * w {
            assert_eq!(m[0], 0.0, "umbra texel at {p}");
            umbra += 1;
        } else if s > edge + 1.5 * w {
            assert_eq!(m[0], 1.0, "lit texel at {p}");
            lit += 1;
        }
        let [x, y] = bake.texels.xy[t];
        let page = &mask.pages[bake.texels.page[t] as usize];
        assert_eq!(page[(y * mask.width + x) as usize], m, "page at texel {t}");
    }
    eprintln!("umbra texels {umbra}, lit texels {lit}");
    assert!(umbra > 500 && lit > 3000);

    // baked = shadowmask + unshadowed direct × mask, per texel within
    // 0.5 % of the light's unshadowed direct light (the two bakes' gathers
    // differ in noise only: their ray counts adapt to different values),
    // and on average over the umbra (bounced light only) within 3 %.
    let baked_path = box_scene("mask-box-baked", A, &[(light, None, mode("baked"))]);
    let scene_b = radbake::scene::load(&baked_path, &Default::default()).unwrap();
    let baked = radbake::bake(&scene_b, &config(), &Silent).unwrap();
    let (mut worst, mut umbra_sum) = (0.0f32, [0.0f64; 2]);
    for t in full_ground_texels(&bake, 20.0) {
        let p = bake.texels.p_ws[t];
        let d = Vec3::from(light) - p;
        let direct = INTENSITY * (d.y / d.length()) / (std::f32::consts::PI * d.length_squared());
        let m = mask.texel_values[t][0];
        let sum = bake.transport.values[t].x + direct * m;
        let want = baked.transport.values[t].x;
        worst = worst.max((sum - want).abs() / direct);
        if m == 0.0 {
            umbra_sum[0] += sum as f64;
            umbra_sum[1] += want as f64;
        }
    }
    let umbra_ratio = umbra_sum[0] / umbra_sum[1];
    eprintln!("worst |shadowmask + direct × mask − baked| / direct: {worst:.2e}; umbra mean ratio {umbra_ratio:.4}");
    assert!(worst < 5e-3);
    assert!((umbra_ratio - 1.0).abs() < 0.03);
}

/// A shadowmask sphere light (R = 5 cm, 30 m up) over a plate's edge:
/// the mask's penumbra on the ground below against the analytic one (see
/// `light_size.rs`, where the same scene's lightmap is checked).
#[test]
fn sphere_light_mask_has_the_analytic_penumbra() {
    let (height, radius) = (30.0f64, 0.05f64);
    let path = edge_scene(
        "mask-sphere",
        Some(json!({"radbake": {"radius": radius, "mode": "shadowmask"}})),
    );
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["extensions"]["KHR_lights_punctual"]["lights"][0] =
        json!({"type": "point", "intensity": 1000.0});
    let nodes = doc["nodes"].as_array_mut().unwrap();
    let light = nodes.len() - 1;
    nodes[light]["translation"] = json!([0.0, height, 0.0]);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let config = BakeConfig {
        texels_per_meter: DENSITY,
        probes: false,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let mask = bake.shadowmask.as_ref().unwrap();
    let h = H as f64;
    let r = h * (radius / height).asin().tan() / (1.0 - h / height);
    check_penumbra(&bake, |t| mask.texel_values[t][0] as f64, r);
    // The lightmap keeps none of the light's direct light (black scene).
    assert!(bake.transport.values.iter().all(|v| *v == Vec3::ZERO));
}

/// Five lights without a range over one ground all overlap: four get the
/// four channels, the fifth (the last of equals) falls back to `indirect`
/// with a warning naming it. Five lights of range 1 m, 2.5 m apart, share
/// channels: all get one, no warning, and (checked from the texels'
/// positions, not the stage's reach test) no ground texel lies within
/// range of two lights of one channel.
#[test]
fn channels_are_limited_to_four_per_texel() {
    let lights: Vec<_> = (0..5)
        .map(|k| {
            (
                [k as f32 * 0.3 - 0.6, LIGHT_Y, 1.2],
                None,
                mode("shadowmask"),
            )
        })
        .collect();
    let path = box_scene("mask-five", A, &lights);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 8.0,
        ..config()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let mask = bake.shadowmask.as_ref().unwrap();
    let mut got: Vec<u8> = mask.channel.iter().flatten().copied().collect();
    got.sort();
    assert_eq!(got, [0, 1, 2, 3]);
    // The one that reaches the fewest texels (the box shades them apart).
    assert_eq!(mask.fallback.len(), 1);
    let f = mask.fallback[0];
    assert_eq!(mask.channel[f], None);
    assert_eq!(bake.warnings.len(), 1, "{:?}", bake.warnings);
    assert!(bake.warnings[0].contains(&format!("`lamp{f}`")));
    let report = bake.report("box.gltf");
    for (k, l) in report.lights.iter().enumerate() {
        if k == f {
            assert_eq!((l.mode, l.requested), ("indirect", Some("shadowmask")));
        } else {
            assert_eq!((l.mode, l.requested), ("shadowmask", None));
            assert!(l.shadowmask_channel.is_some());
        }
    }

    let ground = 4.0;
    let apart: Vec<_> = (0..5)
        .map(|k| {
            (
                [k as f32 * 1.5 - 3.0, 0.5, 0.0],
                Some(1.0),
                mode("shadowmask"),
            )
        })
        .collect();
    let path = box_scene("mask-apart", ground, &apart);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let mask = bake.shadowmask.as_ref().unwrap();
    assert!(
        mask.channel.iter().all(Option::is_some),
        "{:?}",
        mask.channel
    );
    assert!(mask.fallback.is_empty() && bake.warnings.is_empty());
    let used: std::collections::BTreeSet<_> = mask.channel.iter().flatten().collect();
    // A chain of overlaps (each light's reach on the ground is a disk of
    // radius √(1 − 0.5²) = 0.87 m): two channels.
    assert_eq!(used.len(), 2, "{:?}", mask.channel);
    for t in 0..bake.texels.len() {
        let p = bake.texels.p_ws[t];
        for c in 0..4u8 {
            let near = (0..5)
                .filter(|&k| mask.channel[k] == Some(c))
                .filter(|&k| (Vec3::from(apart[k].0) - p).length() < 1.0)
                .count();
            assert!(near <= 1, "texel at {p}: {near} lights of channel {c}");
        }
    }
}

/// `radbake bake` with a shadowmask light: `shadowmask_0.{png,exr,ktx2}`
/// (the PNG's 8-bit codes in the KTX2's zstd level, byte for byte), the
/// manifest's channels, the report's channel, and in the baked `.glb` each
/// lightmapped material's `extras.radbake.shadowmask` (texture, rectangle,
/// channels by light node) and the light node's mode and channel.
#[test]
fn cli_writes_the_shadowmask_files() {
    let path = box_scene(
        "mask-cli",
        A,
        &[([0.0, LIGHT_Y, 0.0], None, mode("shadowmask"))],
    );
    let out = temp_dir("mask-cli-out");
    common::run_ok::<_, std::ffi::OsString>([
        "bake".into(),
        "-q".into(),
        "--force".into(),
        "--texels-per-meter".into(),
        "10".into(),
        "--probes".into(),
        "off".into(),
        std::ffi::OsString::from(&path),
        std::ffi::OsString::from("--out"),
        std::ffi::OsString::from(&out),
    ]);
    let png = image::open(out.join("shadowmask_0.png"))
        .unwrap()
        .to_rgba8();
    let r: Vec<u8> = png.pixels().map(|p| p[0]).collect();
    assert!(r.contains(&0) && r.contains(&255));
    assert!(png.pixels().all(|p| p[1] == 0 && p[2] == 0 && p[3] == 0));
    assert!(out.join("shadowmask_0.exr").is_file());
    let (header, raw) = common::ktx2_level(&out.join("shadowmask_0.ktx2"));
    assert_eq!(header.format, Some(ktx2::Format::R8G8B8A8_UNORM));
    assert_eq!((header.pixel_width, header.pixel_height), png.dimensions());
    assert_eq!(&raw, png.as_raw());

    let manifest = read_json(&out.join("manifest.json"));
    let sm = &manifest["shadowmask"];
    assert_eq!(sm["pages"][0]["png"], "shadowmask_0.png");
    assert_eq!(sm["channels"][0]["lights"][0]["name"], "lamp0");
    assert_eq!(sm["channels"][1]["lights"], json!([]));
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["lights"][0]["shadowmask_channel"], "r");
    assert!(report["counts"]["rays_shadowmask"].as_u64().unwrap() > 0);

    let doc = common::glb_json(&out.join("box.baked.glb"));
    let lamp = doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .position(|n| n["name"] == "lamp0_node")
        .unwrap();
    assert_eq!(
        doc["nodes"][lamp]["extras"]["radbake"]["mode"],
        "shadowmask"
    );
    assert_eq!(
        doc["nodes"][lamp]["extras"]["radbake"]["shadowmask_channel"],
        "r"
    );
    let mut lightmapped = 0;
    for m in doc["materials"].as_array().unwrap() {
        if m["extensions"].get("MOZ_lightmap").is_none() {
            continue;
        }
        lightmapped += 1;
        let e = &m["extras"]["radbake"]["shadowmask"];
        let tex = e["index"].as_u64().unwrap() as usize;
        let image = doc["textures"][tex]["source"].as_u64().unwrap() as usize;
        assert_eq!(doc["images"][image]["name"], "shadowmask_0");
        assert_eq!(e["channels"]["r"], json!([lamp]));
        assert_eq!(e["texCoord"], 1);
        let t = &m["extensions"]["MOZ_lightmap"]["extensions"]["KHR_texture_transform"];
        assert_eq!((&e["offset"], &e["scale"]), (&t["offset"], &t["scale"]));
    }
    assert_eq!(lightmapped, 2);
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// What the preview shows is what an engine would: the `shadowmask`
/// light's bake, with the light's direct light drawn in real time × its
/// channel of the mask, looks as the `baked` light's bake, in the box's
/// umbra (the image's centre, under the box) and over the whole image.
/// Skipped, saying why, without a graphics adapter.
#[test]
fn preview_masks_shadowmask_lights() {
    let exe = env!("CARGO_BIN_EXE_radbake");
    let dir = temp_dir("mask-preview");
    let mut shots = Vec::new();
    for m in ["baked", "shadowmask"] {
        let scene = box_scene(
            &format!("mask-preview-{m}"),
            A,
            &[([0.0, LIGHT_Y, 0.0], None, mode(m))],
        );
        let out = dir.join(m);
        common::run_ok::<_, std::ffi::OsString>([
            "bake".into(),
            "-q".into(),
            "--force".into(),
            "--texels-per-meter".into(),
            "20".into(),
            "--probes".into(),
            "off".into(),
            std::ffi::OsString::from(&scene),
            std::ffi::OsString::from("--out"),
            std::ffi::OsString::from(&out),
        ]);
        let png = dir.join(format!("{m}.png"));
        let run = std::process::Command::new(exe)
            .arg("preview")
            .arg(out.join("box.baked.glb"))
            .args(["--headless", "--out"])
            .arg(&png)
            .args(["--size", "96x64", "--tone-map", "none", "--exposure=1"])
            .args(["--look-from=3,0.6,0.2", "--look-at=0,0,0"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        if !run.status.success() && stderr.contains("no graphics adapter") {
            eprintln!("SKIPPED (no GPU or software adapter on this machine): {stderr}");
            return;
        }
        assert!(run.status.success(), "preview failed: {stderr}");
        shots.push(image::open(&png).unwrap().to_rgba8());
    }
    let mean = |img: &image::RgbaImage| {
        img.pixels()
            .map(|p| common::srgb_to_linear(p[0]) as f64)
            .sum::<f64>()
            / (img.width() * img.height()) as f64
    };
    let (baked, masked) = (&shots[0], &shots[1]);
    let (cb, cm) = (
        common::centre_linear(baked).x,
        common::centre_linear(masked).x,
    );
    let (mb, mm) = (mean(baked), mean(masked));
    eprintln!("umbra (centre): baked {cb:.4}, shadowmask {cm:.4}; image mean: baked {mb:.4}, shadowmask {mm:.4}");
    assert!(
        cb > 0.0 && (cm / cb - 1.0).abs() < 0.05,
        "umbra {cm} vs {cb}"
    );
    assert!((mm / mb - 1.0).abs() < 0.02, "mean {mm} vs {mb}");
}
