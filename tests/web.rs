//! radbake's outputs in a real browser: three.js r187 from npm in headless
//! Chromium (`tests/web/`). Needs `npm ci` in `tests/web` and a Chromium
//! (`CHROMIUM`, or `chromium` on PATH), so it is `#[ignore]`d in the plain
//! `cargo test`; CI installs both and runs
//! `cargo test --release --test web -- --ignored`.

mod common;

use common::{scene_path, temp_dir};
use glam::Vec3;
use radbake::config::BakeConfig;
use radbake::probes::sh;
use radbake::progress::Silent;
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
