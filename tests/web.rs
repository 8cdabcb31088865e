//! radbake's outputs in a real browser: three.js r187 from npm in headless
//! Chromium (`tests/web/`). Needs `npm ci` in `tests/web` and a Chromium
//! (`CHROMIUM`, or `chromium` on PATH), so it is `#[ignore]`d in the plain
//! `cargo test`; CI installs both and runs
//! `cargo test --release --test web -- --ignored --test-threads 1`.

mod common;

use common::{scene_path, temp_dir};
use glam::Vec3;
use radbake::config::BakeConfig;
use radbake::pipeline::progress::Silent;
use radbake::probes::sh;
use std::path::Path;
use std::process::Command;

/// Runs `tests/web/probe_check.mjs` on probe `index` of the bake in `dir`:
/// (normal, rendered linear RGB) per sample pixel of the lit sphere.
fn three_sphere(dir: &Path, index: usize) -> Vec<(Vec3, Vec3)> {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web");
    assert!(
        web.join("node_modules/three").exists(),
        "run `npm ci` in tests/web first"
    );
    let out = Command::new("node")
        .arg(web.join("probe_check.mjs"))
        .arg(dir)
        .arg(index.to_string())
        .output()
        .expect("node runs");
    assert!(
        out.status.success(),
        "probe_check.mjs failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["three"], "187");
    let v3 = |v: &serde_json::Value| {
        Vec3::new(
            v[0].as_f64().unwrap() as f32,
            v[1].as_f64().unwrap() as f32,
            v[2].as_f64().unwrap() as f32,
        )
    };
    json["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (v3(&s["normal"]), v3(&s["rgb"])))
        .collect()
}

/// A white Lambert sphere lit by `new THREE.LightProbe(sh)` built from
/// `probes.json`/`probes.bin` renders, at each normal, the irradiance / π
/// that radbake's SH gives (what the preview shades its probe spheres
/// with): within 1 % of the sphere's brightest value.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn three_js_light_probe_matches_radbake() {
    let out = temp_dir("web-probes");
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let config = BakeConfig {
        probe_spacing: 0.2,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    radbake::output::write_engine_outputs(&out, "cornell", &bake).unwrap();
    let probes = bake.probes.as_ref().unwrap();
    let picks: Vec<usize> = (0..probes.len())
        .filter(|&i| probes.valid[i])
        .step_by(7)
        .take(3)
        .collect();
    assert_eq!(picks.len(), 3);
    for i in picks {
        let samples = three_sphere(&out, i);
        assert!(samples.len() > 100, "{} samples", samples.len());
        let ours: Vec<Vec3> = samples
            .iter()
            .map(|(n, _)| sh::irradiance_over_pi(&probes.sh[i], n.normalize()).max(Vec3::ZERO))
            .collect();
        let peak = ours.iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
        assert!(peak > 0.0);
        let worst = samples
            .iter()
            .zip(&ours)
            .map(|((_, three), ours)| (*three - *ours).abs().max_element())
            .fold(0.0f32, f32::max);
        eprintln!(
            "probe {i}: {} pixels, worst |three.js − radbake| {worst:.2e} of peak {peak:.4}",
            samples.len()
        );
        assert!(
            worst <= 0.01 * peak,
            "probe {i}: worst {worst}, peak {peak}"
        );
    }
}

/// Asserts that a finished command succeeded, showing its stderr if not.
fn succeeded(run: &std::process::Output) {
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// `radbake serve` on a free port, killed on drop.
struct Served {
    child: std::process::Child,
    port: u16,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Serves the bake in `dir`; returns once the server has printed its URL
/// (it prints after binding).
fn serve(dir: &Path) -> Served {
    use std::io::BufRead as _;
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(["serve", dir.to_str().unwrap(), "--port", &port.to_string()])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.contains("radbake viewer: http://127.0.0.1:"), "{line}");
    Served { child, port }
}

/// Opens the viewer page for `query` and writes its canvas to `out`;
/// `viewer_check.mjs`'s report (`three`, `cameras`, `probes`, `layers`,
/// `errors`).
fn open_viewer(port: u16, query: &str, out: &Path) -> serde_json::Value {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web");
    let url = format!("http://127.0.0.1:{port}/?{query}");
    let run = Command::new("node")
        .arg(web.join("viewer_check.mjs"))
        .arg(&url)
        .arg(out)
        .output()
        .unwrap();
    succeeded(&run);
    // A stalled first load that was retried says so here.
    eprint!("{}", String::from_utf8_lossy(&run.stderr));
    serde_json::from_slice(&run.stdout).unwrap()
}

/// The viewer page's canvas for `query`, as linear RGB; asserts the page
/// loaded with no console error.
fn viewer(port: u16, query: &str, out: &Path) -> Vec<Vec3> {
    let json = open_viewer(port, query, out);
    assert_eq!(
        json["errors"],
        serde_json::json!([]),
        "console errors on ?{query}"
    );
    linear_pixels(out)
}

/// `radbake preview --headless --tone-map none` of `glb` from `camera`,
/// with `extra` arguments.
fn preview(glb: &Path, camera: &str, size: &str, extra: &[&str], out: &Path) -> Vec<Vec3> {
    let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args([
            "preview",
            glb.to_str().unwrap(),
            "--headless",
            "--tone-map",
            "none",
        ])
        .args(extra)
        .args([
            "--camera",
            camera,
            "--size",
            size,
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    succeeded(&run);
    linear_pixels(out)
}

fn linear_pixels(png: &Path) -> Vec<Vec3> {
    let img = image::open(png).unwrap().to_rgb8();
    let lin = |c: u8| radbake::scene::texture::srgb_to_linear(c as f32 / 255.0);
    img.pixels()
        .map(|p| Vec3::new(lin(p[0]), lin(p[1]), lin(p[2])))
        .collect()
}

/// (mean of a / mean of b, 95th percentile of the per-pixel relative
/// difference |a − b| / max(b, 1 % of b's mean), on the RGB mean).
fn agreement(a: &[Vec3], b: &[Vec3]) -> (f64, f64) {
    let lum = |v: &Vec3| (v.element_sum() / 3.0) as f64;
    let (sa, sb): (f64, f64) = (a.iter().map(lum).sum(), b.iter().map(lum).sum());
    let floor = 0.01 * sb / b.len() as f64;
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| (lum(x) - lum(y)).abs() / lum(y).max(floor))
        .collect();
    d.sort_by(f64::total_cmp);
    (sa / sb, d[d.len() * 95 / 100])
}

/// A textured scene with what real levels use: a floor whose checker
/// texture has a `KHR_texture_transform` (offset, rotation, scale), and in
/// front of it an alpha-MASK fence (a checker of holes, double-sided), lit
/// by a point light and seen from a glTF camera `cam`.
fn masked_scene(dir: &Path) -> std::path::PathBuf {
    let mut b = common::GltfBuilder::default();
    let quad_uv = |b: &mut common::GltfBuilder, p: [[f32; 3]; 4], material: usize, name: &str| {
        let pos = b.vec3(&p);
        let uv = b.vec2(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
        b.meshes.push(serde_json::json!({"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx, "material": material}]}));
        let m = b.meshes.len() - 1;
        b.node(name, m);
    };
    b.materials.push(serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
        "extensions": {"KHR_texture_transform": {"offset": [0.1, 0.2], "rotation": 0.4, "scale": [3.0, 2.0]}}},
        "metallicFactor": 0.0}}));
    b.materials.push(
        serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 1},
        "baseColorFactor": [0.9, 0.6, 0.3, 1.0], "metallicFactor": 0.0},
        "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true}),
    );
    quad_uv(
        &mut b,
        [
            [-2.0, 0.0, 2.0],
            [2.0, 0.0, 2.0],
            [2.0, 0.0, -2.0],
            [-2.0, 0.0, -2.0],
        ],
        0,
        "floor",
    );
    quad_uv(
        &mut b,
        [
            [-1.0, 0.2, 0.5],
            [1.0, 0.2, 0.5],
            [1.0, 1.2, 0.5],
            [-1.0, 1.2, 0.5],
        ],
        1,
        "fence",
    );
    let mut doc = b.json();
    let checker = |x: u32, y: u32| (x / 8 + y / 8) % 2 == 0;
    let colours = image::RgbaImage::from_fn(64, 64, |x, y| {
        if checker(x, y) {
            image::Rgba([230, 220, 200, 255])
        } else {
            image::Rgba([60, 90, 140, 255])
        }
    });
    let holes = image::RgbaImage::from_fn(64, 64, |x, y| {
        image::Rgba([255, 255, 255, if checker(x, y) { 255 } else { 0 }])
    });
    for (name, img) in [("colours.png", colours), ("holes.png", holes)] {
        img.save(dir.join(name)).unwrap();
    }
    doc["images"] = serde_json::json!([{"uri": "colours.png"}, {"uri": "holes.png"}]);
    doc["textures"] = serde_json::json!([{"source": 0}, {"source": 1}]);
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual", "KHR_texture_transform"]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 4.0}]}});
    doc["cameras"] = serde_json::json!([{"name": "cam", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05, "zfar": 50.0}}]);
    let look = glam::Quat::from_rotation_x(-0.35);
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"name": "bulb", "translation": [0.3, 1.8, 1.2], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    nodes.push(serde_json::json!({"name": "cam", "camera": 0, "translation": [0.0, 1.4, 3.2], "rotation": look.to_array()}));
    let n = nodes.len();
    doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
    let path = dir.join("masked.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// The viewer page (three.js, radbake's plugin) and `radbake preview`
/// render the same bake from the same glTF camera, no tone mapping: mean
/// linear radiance within 2 %, 95th-percentile per-pixel difference within
/// 5 %. The Cornell box, the breakfast room (textured, from
/// `scenes/real`), and a masked, texture-transformed scene.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn viewer_page_matches_the_preview() {
    let cases = [
        (
            scene_path("cornell_box.gltf").to_str().unwrap().to_owned(),
            "cornell_box",
            "camera",
            "400x400",
            vec![],
        ),
        (
            masked_scene(&temp_dir("web-masked-src"))
                .to_str()
                .unwrap()
                .to_owned(),
            "masked",
            "cam",
            "400x300",
            vec!["--texels-per-meter", "32"],
        ),
        (
            scene_path("real/breakfast_room/BreakfastRoom.lit.gltf")
                .to_str()
                .unwrap()
                .to_owned(),
            "BreakfastRoom.lit",
            "CameraMain",
            "480x320",
            vec!["--preset", "preview"],
        ),
    ];
    for (scene, stem, camera, size, extra) in cases {
        let out = temp_dir(&format!("web-viewer-{stem}"));
        let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
            .args(["bake", &scene, "--out", out.to_str().unwrap(), "-q"])
            .args(extra)
            .output()
            .unwrap();
        succeeded(&run);
        let glb = out.join(format!("{stem}.baked.glb"));
        let server = serve(&out);
        let query = format!(
            "url=/bake/{stem}.baked.glb&camera={camera}&size={size}&tonemap=none&exposure=0"
        );
        let three = viewer(server.port, &query, &out.join("three.png"));
        let ours = preview(&glb, camera, size, &[], &out.join("preview.png"));
        let (mean, p95) = agreement(&three, &ours);
        eprintln!(
            "{stem}: three.js / preview mean {mean:.4}, 95th-percentile pixel difference {:.2} %",
            100.0 * p95
        );
        assert!((mean - 1.0).abs() <= 0.02, "{stem}: mean ratio {mean}");
        assert!(p95 <= 0.05, "{stem}: 95th percentile {p95}");
    }
}

/// Light layers in the viewer page: with `layer=lamp=W` it recombines the
/// layers' EXR pages (and probes) in three.js, and renders what
/// `radbake preview --layer lamp=W` does from the Cornell box's camera, no
/// tone mapping: for W = 0 and 2, mean linear radiance within 3 %,
/// 95th-percentile per-pixel difference within 5 %. Every weight at 1
/// renders as the glb's own sRGB lightmap does (`manifest=none`: mean
/// within 1 %, 95th percentile within 5 %), and an unknown layer in the
/// query is an error that names it.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn viewer_light_layers_match_the_preview() {
    let out = temp_dir("web-layers");
    let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .arg("bake")
        .arg(scene_path("cornell_layers.gltf"))
        .args(["--out", out.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    succeeded(&run);
    let glb = out.join("cornell_layers.baked.glb");
    let server = serve(&out);
    let query = "url=/bake/cornell_layers.baked.glb&probes=/bake/probes.json\
                 &camera=camera&size=400x400&tonemap=none&exposure=0";
    for w in ["0", "2"] {
        let png = out.join(format!("three_lamp{w}.png"));
        let three = viewer(server.port, &format!("{query}&layer=lamp={w}"), &png);
        let layer = format!("lamp={w}");
        let ours = preview(
            &glb,
            "camera",
            "400x400",
            &["--layer", &layer],
            &out.join(format!("preview_lamp{w}.png")),
        );
        let (mean, p95) = agreement(&three, &ours);
        eprintln!(
            "lamp = {w}: three.js / preview mean {mean:.4}, 95th-percentile pixel difference {:.2} %",
            100.0 * p95
        );
        assert!((mean - 1.0).abs() <= 0.03, "lamp = {w}: mean ratio {mean}");
        assert!(p95 <= 0.05, "lamp = {w}: 95th percentile {p95}");
    }
    let layered_png = out.join("three_layers.png");
    let report = open_viewer(server.port, query, &layered_png);
    assert_eq!(report["errors"], serde_json::json!([]));
    assert_eq!(report["layers"], serde_json::json!(["ceiling", "lamp"]));
    let layered = linear_pixels(&layered_png);
    let stock = viewer(
        server.port,
        &format!("{query}&manifest=none"),
        &out.join("three_stock.png"),
    );
    let (mean, p95) = agreement(&layered, &stock);
    eprintln!(
        "weights 1: layers / glb lightmap mean {mean:.4}, 95th-percentile pixel difference {:.2} %",
        100.0 * p95
    );
    assert!((mean - 1.0).abs() <= 0.01, "weights 1: mean ratio {mean}");
    assert!(p95 <= 0.05, "weights 1: 95th percentile {p95}");
    let report = open_viewer(
        server.port,
        &format!("{query}&layer=lantern=2"),
        &out.join("three_unknown.png"),
    );
    let errors = report["errors"].to_string();
    assert!(
        errors.contains(r#"unknown light layer \"lantern\""#),
        "{errors}"
    );
}

/// The stock Hubs-style semantics (bytes read as linear, intensity as is)
/// fail in exactly the documented way: in the lightmap view, where radbake's
/// plugin renders v, they render s · srgb(v / s) (s: the instance's
/// `png_scale`). A one-instance scene (a floor under a point light, seen
/// from above), so that s is one number.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn stock_hubs_semantics_fail_as_documented() {
    let mut b = common::GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = common::quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let mut doc = b.json();
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 3.0}]}});
    doc["cameras"] = serde_json::json!([{"name": "top", "type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.05, "zfar": 50.0}}]);
    let down = glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"name": "bulb", "translation": [0.6, 1.0, 0.3], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    nodes.push(serde_json::json!({"name": "top", "camera": 0, "translation": [0.0, 3.0, 0.0], "rotation": down.to_array()}));
    let n = nodes.len();
    doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
    let out = temp_dir("web-hubs");
    let path = out.join("floor.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let config = BakeConfig {
        texels_per_meter: 32.0,
        probes: false,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    radbake::output::write_engine_outputs(&out, "floor", &bake).unwrap();
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let s = manifest["instances"][0]["png_scale"].as_f64().unwrap() as f32;
    let server = serve(&out);
    let q = "url=/bake/floor.baked.glb&camera=top&size=256x256&tonemap=none&view=lightmap";
    let ours = viewer(server.port, q, &out.join("radbake.png"));
    let hubs = viewer(
        server.port,
        &format!("{q}&loader=hubs"),
        &out.join("hubs.png"),
    );
    let predicted: Vec<Vec3> = ours
        .iter()
        .map(|v| {
            (*v / s)
                .clamp(Vec3::ZERO, Vec3::ONE)
                .to_array()
                .map(radbake::scene::texture::linear_to_srgb)
        })
        .map(|c| Vec3::from(c) * s)
        .collect();
    let (mean_pred, p95) = agreement(&hubs, &predicted);
    let (too_bright, _) = agreement(&hubs, &ours);
    eprintln!("Hubs semantics: {too_bright:.2} × as bright as radbake's plugin; against s·srgb(v/s): mean {mean_pred:.4}, 95th percentile {:.2} %", 100.0 * p95);
    assert!(
        too_bright > 1.2,
        "the stock path should render too bright: {too_bright}"
    );
    assert!(
        (mean_pred - 1.0).abs() < 0.02 && p95 < 0.05,
        "{mean_pred}, {p95}"
    );
}

/// The porch (`scenes/porch.gltf`) with a glTF camera `cam` looking under
/// its roof from the open side, baked as tests/live.rs bakes it (4
/// texels/m) with its sun live and the sky 0.3, 0.4, 0.55 in a layer of
/// its own. Returns the bake folder.
fn live_porch(name: &str) -> std::path::PathBuf {
    let src = temp_dir(&format!("{name}-src"));
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(scene_path("porch.gltf")).unwrap()).unwrap();
    doc["cameras"] = serde_json::json!([{"name": "cam", "type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.05, "zfar": 60.0}}]);
    let look = glam::Quat::from_rotation_x(-0.14);
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"name": "cam", "camera": 0, "translation": [1.5, 2.6, 11.0], "rotation": look.to_array()}));
    let n = nodes.len();
    doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
    let gltf = src.join("porch.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
    let out = temp_dir(name);
    common::run_ok([
        "bake",
        gltf.to_str().unwrap(),
        "--live",
        "--sky",
        "0.3,0.4,0.55",
        "--texels-per-meter",
        "4",
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    out
}

/// The live bake's sun as baked, and a sun `degrees` away from it at the
/// same elevation (turned about y: a later hour), as `x,y,z`.
fn turned_sun(bake: &Path, degrees: f32) -> (Vec3, String) {
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(bake.join("manifest.json")).unwrap()).unwrap();
    let d = &manifest["live"]["lights"][0]["direction"];
    let baked = Vec3::new(
        d[0].as_f64().unwrap() as f32,
        d[1].as_f64().unwrap() as f32,
        d[2].as_f64().unwrap() as f32,
    )
    .normalize();
    // cos θ = y² + (1 − y²) cos φ for a turn φ about y.
    let y2 = baked.y * baked.y;
    let phi = ((degrees.to_radians().cos() - y2) / (1.0 - y2)).acos();
    let sun = glam::Quat::from_rotation_y(phi) * baked;
    let angle = baked.dot(sun).clamp(-1.0, 1.0).acos().to_degrees();
    assert!((angle - degrees).abs() < 0.01, "{angle}°");
    (sun, format!("{},{},{}", sun.x, sun.y, sun.z))
}

/// The three.js live runtime (web/radbake-live.js through
/// radbake-three.js's loadRadbakeLive, in headless Chromium, warm-started
/// from the baked sun) and `radbake relight` (the Rust run time, from
/// zero) at a sun 30° from the baked one and a new sky: lightmap page 0
/// with every layer, the JS page before its half-float conversion, within
/// 1e-3 of the relit page's sum (Σ|Δ| / Σ|relight|) and every pixel
/// within 1 % of the page's mean. Both solves stop at the bake's
/// tolerance (1e-4 relative change) from different starts; they agree to
/// a few 1e-5.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn three_js_live_runtime_matches_relight() {
    let bake = live_porch("web-live-numeric");
    let (_, sun) = turned_sun(&bake, 30.0);
    let sky = "0.6,0.5,0.4";
    let relit = temp_dir("web-live-relit");
    common::run_ok([
        "relight",
        bake.to_str().unwrap(),
        "--sun-direction",
        &sun,
        "--sky",
        sky,
        "-o",
        relit.to_str().unwrap(),
        "-q",
    ]);
    let server = serve(&bake);
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web");
    let dump = bake.join("three_live_page.f32");
    let run = Command::new("node")
        .arg(web.join("live_check.mjs"))
        .arg(format!("http://127.0.0.1:{}", server.port))
        .args([&sun, sky])
        .arg(&dump)
        .output()
        .unwrap();
    succeeded(&run);
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["errors"], serde_json::json!([]), "{report}");
    assert_eq!(report["light"], "sun");
    let (w, h, ours) =
        radbake::util::files::read_exr_rgb(&relit.join("lightmap_0.exr"), "page", 1 << 16, 1 << 30)
            .unwrap();
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(w as u64), Some(h as u64))
    );
    let bytes = std::fs::read(&dump).unwrap();
    let three: Vec<Vec3> = bytes
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f32::from_le_bytes(c[i..i + 4].try_into().unwrap());
            Vec3::new(f(0), f(4), f(8))
        })
        .collect();
    assert_eq!(three.len(), ours.len());
    // The pixels the page holds (texels and their padding): lit in either.
    let held: Vec<(Vec3, Vec3)> = three
        .iter()
        .zip(&ours)
        .filter(|(a, b)| a.max_element() > 0.0 || b.max_element() > 0.0)
        .map(|(a, b)| (*a, *b))
        .collect();
    assert!(held.len() > ours.len() / 4, "{} pixels held", held.len());
    let sum: f32 = held.iter().map(|(_, b)| b.element_sum()).sum();
    let diff: f32 = held
        .iter()
        .map(|(a, b)| (*a - *b).abs().element_sum())
        .sum();
    let worst = held
        .iter()
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0f32, f32::max);
    let mean = sum / (3 * held.len()) as f32;
    eprintln!(
        "three.js live / relight at a sun 30° away: Σ|Δ| / Σ|relight| {:.2e} over {} pixels, worst {:.2e} of the mean {mean:.4} ({} iterations from the baked sun, residual {:.2e}, {:.1} ms)",
        diff / sum,
        held.len(),
        worst / mean,
        report["iterations"],
        report["residual"].as_f64().unwrap(),
        report["ms"].as_f64().unwrap()
    );
    assert!(diff / sum <= 1e-3, "Σ|Δ| / Σ|relight| {}", diff / sum);
    assert!(worst <= 1e-2 * mean, "worst {worst} of the mean {mean}");
    // The probes: the live layer's moved by the JS probeDelta, against
    // relight's probes.bin (moved by the Rust one); both away from the
    // bake's, so the comparison can fail.
    let floats = |p: &Path| -> Vec<f32> {
        (std::fs::read(p).unwrap().chunks_exact(4))
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    let three = floats(&dump.with_extension("f32.probes"));
    let ours = floats(&relit.join("probes.bin"));
    let baked = floats(&bake.join("probes.bin"));
    assert_eq!(three.len(), ours.len());
    let l1 = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>();
    let size: f32 = ours.iter().map(|x| x.abs()).sum();
    let (off, moved) = (l1(&three, &ours) / size, l1(&baked, &ours) / size);
    eprintln!(
        "three.js probes / relight's: Σ|Δ| / Σ|relight| {off:.2e} over {} probes (relight's differ from the bake's by {moved:.2e}; the probe change took {:.1} ms)",
        ours.len() / 27,
        report["probes"].as_f64().unwrap_or(f64::NAN)
    );
    assert!(moved > 1e-2, "relight's probes did not move: {moved}");
    assert!(off <= 1e-3, "three.js probes off relight's by {off}");
}

/// The viewer page with `sun=` (and `sky=`, `sun_irradiance=`) solves a
/// live bake in three.js and renders what `radbake preview
/// --sun-direction` does (relight's pages) from the porch's camera, in
/// the lightmap view (the sun's direct light is the engine's: the
/// viewer draws none), no tone mapping: mean linear radiance within 3 %,
/// 95th-percentile per-pixel difference within 5 %; `window.radbake.live`
/// reports the light and the solve.
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn viewer_live_sun_matches_the_preview() {
    let out = live_porch("web-live");
    let glb = out.join("porch.baked.glb");
    let (_, later) = turned_sun(&out, 30.0);
    let (_, evening) = turned_sun(&out, 60.0);
    let server = serve(&out);
    let query =
        "url=/bake/porch.baked.glb&camera=cam&size=400x300&tonemap=none&exposure=0&view=lightmap";
    let cases = [
        (
            "30°, sky 0.6,0.5,0.4",
            format!("sun={later}&sky=0.6,0.5,0.4"),
            vec!["--sun-direction", later.as_str(), "--sky", "0.6,0.5,0.4"],
        ),
        (
            "60°, irradiance 9,8,6",
            format!("sun={evening}&sun_irradiance=9,8,6"),
            vec![
                "--sun-direction",
                evening.as_str(),
                "--sun-irradiance",
                "9,8,6",
            ],
        ),
    ];
    for (i, (what, params, flags)) in cases.iter().enumerate() {
        let png = out.join(format!("three_live{i}.png"));
        let report = open_viewer(server.port, &format!("{query}&{params}"), &png);
        assert_eq!(report["errors"], serde_json::json!([]), "{what}");
        assert_eq!(report["live"]["light"], "sun", "{report}");
        assert!(
            report["live"]["iterations"].as_u64().unwrap() >= 1,
            "{report}"
        );
        let three = linear_pixels(&png);
        let mut extra = vec!["--view", "lightmap"];
        extra.extend(flags.iter().copied());
        let ours = preview(
            &glb,
            "cam",
            "400x300",
            &extra,
            &out.join(format!("preview_live{i}.png")),
        );
        let (mean, p95) = agreement(&three, &ours);
        eprintln!(
            "live sun {what}: three.js / preview mean {mean:.4}, 95th-percentile pixel difference {:.2} % ({} iterations, {:.1} ms in the page)",
            100.0 * p95,
            report["live"]["iterations"],
            report["live"]["ms"].as_f64().unwrap()
        );
        assert!((mean - 1.0).abs() <= 0.03, "{what}: mean ratio {mean}");
        assert!(p95 <= 0.05, "{what}: 95th percentile {p95}");
    }
}

/// The viewer's lit view of a live bake draws the sun in real time, with
/// shadow maps, turned with its bounce light: the porch's sun turned 30°;
/// without the real-time sun (`realtime=0`) the image is far darker, and
/// the sun's share matches `radbake preview --sun-direction` on what the
/// roof does not shade (the preview draws it unshadowed without a
/// distance field, so the images are not compared pixel by pixel).
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn viewer_draws_the_live_sun() {
    let out = live_porch("web-live-lit");
    let glb = out.join("porch.baked.glb");
    let (_, later) = turned_sun(&out, 30.0);
    let server = serve(&out);
    let query = format!(
        "url=/bake/porch.baked.glb&camera=cam&size=400x300&tonemap=none&exposure=0&sun={later}"
    );
    let png = out.join("three_lit.png");
    let report = open_viewer(server.port, &query, &png);
    assert_eq!(report["errors"], serde_json::json!([]));
    assert_eq!(report["realtime"], serde_json::json!(["sun"]), "{report}");
    let three = linear_pixels(&png);
    let dark = out.join("three_no_sun.png");
    let report = open_viewer(server.port, &format!("{query}&realtime=0"), &dark);
    assert_eq!(report["errors"], serde_json::json!([]));
    let (without, _) = agreement(&linear_pixels(&dark), &three);
    let ours = preview(
        &glb,
        "cam",
        "400x300",
        &["--sun-direction", later.as_str()],
        &out.join("preview_lit.png"),
    );
    let (mean, _) = agreement(&three, &ours);
    eprintln!(
        "live sun drawn, 30°: without the real-time sun the image is {without:.4} of it; three.js (shadowed) / preview (unshadowed) mean {mean:.4}"
    );
    assert!(
        without < 0.6,
        "the sun's direct light is {without} of the image"
    );
    assert!(mean < 1.0 && mean > 0.6, "three.js / preview {mean}");
}

/// Bad live input in the viewer is an error naming it, never a wrong
/// image: a `live.bin` with a byte of its body flipped (its checksum), one
/// cut short, a sun of zero length, and a weight for the live layer
/// (re-solved, not weighted).
#[test]
#[ignore = "needs tests/web/node_modules and Chromium (CI runs it)"]
fn viewer_live_bad_input_is_named() {
    let out = live_porch("web-live-bad");
    let query = "url=/bake/porch.baked.glb&camera=cam&size=160x120";
    let errors_of = |dir: &Path, extra: &str| {
        let server = serve(dir);
        let report = open_viewer(
            server.port,
            &format!("{query}{extra}"),
            &dir.join("three_bad.png"),
        );
        report["errors"].to_string()
    };
    let e = errors_of(&out, "&sun=0,0,0");
    assert!(
        e.contains("sun direction") && e.contains("zero length"),
        "{e}"
    );
    let e = errors_of(&out, "&layer=live=2");
    assert!(
        e.contains("light layer live") && e.contains("re-solved"),
        "{e}"
    );
    let broken = temp_dir("web-live-broken");
    for f in std::fs::read_dir(&out).unwrap().flatten() {
        std::fs::copy(f.path(), broken.join(f.file_name())).unwrap();
    }
    let live_bin = broken.join("live.bin");
    let bytes = std::fs::read(&live_bin).unwrap();
    let mut flipped = bytes.clone();
    let n = flipped.len();
    flipped[n - 100] ^= 0x10;
    std::fs::write(&live_bin, &flipped).unwrap();
    let e = errors_of(&broken, "");
    assert!(e.contains("live.bin") && e.contains("checksum"), "{e}");
    std::fs::write(&live_bin, &bytes[..n / 2]).unwrap();
    let e = errors_of(&broken, "");
    assert!(e.contains("live.bin") && e.contains("truncated"), "{e}");
    eprintln!("bad live input: {e}");
}
