//! Live radiosity (`--live`, `live.bin`, `radbake relight`): exact where it
//! must be, the relit folder, bad input. The comparison with full bakes on
//! Sponza is `tools/live_accuracy.rs` (docs/live.md).

mod common;

use common::{run_ok, scene_path, temp_dir};
use glam::Vec3;
use radbake::config::LightMode;
use radbake::util::files::read_exr_rgb;
use radbake::{BakeConfig, Silent};
use radbake_live::{Live, Sun};
use std::path::Path;
use std::process::Command;

/// Puts the porch's light `sun` in `mode`, in `config` and on `scene`.
fn sun_mode(config: &mut BakeConfig, scene: &mut radbake::scene::Scene, mode: LightMode) {
    config.light_modes.lights.insert("sun".into(), mode);
    config.light_modes.apply(scene).unwrap();
}

/// The porch baked with its sun live (sun only), the sun turned to a
/// direction of the table's grid.
fn porch_at_node() -> (radbake::scene::Scene, BakeConfig, Vec3) {
    let mut scene = radbake::scene::load(&scene_path("porch.gltf"), &Default::default()).unwrap();
    let mut config = BakeConfig {
        texels_per_meter: 4.0,
        final_gather: 0,
        stitch_seams: false,
        ..BakeConfig::default()
    };
    sun_mode(&mut config, &mut scene, LightMode::Live);
    let towards = Vec3::from(radbake_live::directions::node_direction(
        config.live_grid,
        7,
        4,
    ));
    assert!(towards.y > 0.3, "{towards}");
    scene.lights[0].direction = -towards;
    (scene, config, towards)
}

#[test]
fn at_a_table_direction_the_live_solve_is_the_bakes() {
    let (scene, config, towards) = porch_at_node();
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let data = bake.live.clone().expect("live data");
    let baked = bake.transport.patch_light.as_ref().unwrap();
    let e = scene.lights[0].intensity;
    let mut live = Live::new(data);
    live.set_suns(&[Sun {
        direction: towards.to_array(),
        irradiance: e.to_array(),
    }])
    .unwrap();
    // The table's D is the bake's patch direct light, to the byte.
    let step = e.max_element() / (255.0 * std::f32::consts::PI);
    let mut worst = 0.0f32;
    for (d, b) in live.patch_direct().iter().zip(&baked.direct) {
        worst = worst.max((Vec3::from(*d) - *b).abs().max_element());
    }
    let lit = baked.direct.iter().filter(|d| d.x > 0.0).count();
    assert!(lit > baked.direct.len() / 4, "{lit} lit patches");
    assert!(
        worst <= 0.5 * step * 1.001 + 1e-6,
        "worst {worst} vs half a byte {}",
        0.5 * step
    );
    // From the bake's D, the solve is the bake's to the tolerance (and F's f16).
    let d: Vec<[f32; 3]> = baked.direct.iter().map(|v| v.to_array()).collect();
    live.set_direct(&d).unwrap();
    let s = live.solve(config.max_iterations);
    assert!(s.residual < config.tolerance, "{s:?}");
    let rel = |a: &[[f32; 3]], b: &[Vec3]| {
        let num: f32 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (Vec3::from(*x) - *y).abs().element_sum())
            .sum();
        num / b.iter().map(|y| y.abs().element_sum()).sum::<f32>()
    };
    let radiance = rel(live.patch_radiance(), &baked.solution.radiance);
    assert!(radiance < 2e-3, "patch radiance off by {radiance}");
    // The texels: the live layer's first pass, on the valid texels.
    let k = bake
        .layers
        .as_ref()
        .unwrap()
        .names
        .iter()
        .position(|n| n == "live")
        .unwrap();
    let valid = &bake.transport.valid;
    let texels = live.texels();
    let keep = |t: &usize| valid[*t];
    let a: Vec<[f32; 3]> = (0..texels.len()).filter(keep).map(|t| texels[t]).collect();
    let b: Vec<Vec3> = (0..texels.len())
        .filter(keep)
        .map(|t| bake.maps.layers[k].texel_values[t])
        .collect();
    let texel = rel(&a, &b);
    println!("porch at a grid direction: D worst {worst:.2e} (half a byte {:.2e}), L {radiance:.2e}, texels {texel:.2e}", 0.5 * step);
    assert!(texel < 3e-3, "texels off by {texel}");
}

fn radbake(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(args)
        .output()
        .unwrap()
}

/// The one-line error `args` fail with.
fn error_of(args: &[&str]) -> String {
    let out = radbake(args);
    assert!(!out.status.success(), "{args:?} succeeded");
    let e = String::from_utf8_lossy(&out.stderr).trim().to_owned();
    assert_eq!(e.lines().count(), 1, "not one line: {e}");
    e
}

fn exr(path: &Path) -> Vec<Vec3> {
    read_exr_rgb(path, "page", 1 << 16, 1 << 30).unwrap().2
}

#[test]
fn relight_writes_a_bake_folder_and_bad_input_is_named() {
    let dir = temp_dir("live-cli");
    let porch = scene_path("porch.gltf");
    let p = porch.to_str().unwrap();
    let bake = dir.join("bake");
    let b = bake.to_str().unwrap();
    let base = [
        "bake",
        p,
        "--live",
        "--sky",
        "0.3,0.4,0.55",
        "--texels-per-meter",
        "4",
        "--quiet",
    ];
    run_ok(base.iter().chain(&["-o", b]));
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(bake.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["live"]["layer"], "live");
    assert_eq!(manifest["live"]["sky"]["layer"], "sky");
    // The same bake on one thread: the same file, bit for bit.
    let one = dir.join("one");
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(base.iter().chain(&["-o", one.to_str().unwrap()]))
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(
        std::fs::read(bake.join("live.bin")).unwrap()
            == std::fs::read(one.join("live.bin")).unwrap(),
        "live.bin differs between 1 thread and the default"
    );

    // Relit: a bake folder; the sky doubled with the sun set is twice the sky's layer.
    let relit = dir.join("relit");
    let r = relit.to_str().unwrap();
    run_ok([
        "relight",
        b,
        "--sun-direction",
        "0,-1,0",
        "--sky",
        "0.6,0.8,1.1",
        "-o",
        r,
        "--quiet",
    ]);
    let sky = exr(&bake.join("lightmap_0_sky.exr"));
    let page = exr(&relit.join("lightmap_0.exr"));
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for (a, s) in page.iter().zip(&sky) {
        num += (*a - *s * 2.0).abs().element_sum();
        den += s.element_sum();
    }
    assert!(
        den > 0.0 && num / den < 1e-5,
        "relit sky off by {}",
        num / den
    );
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(relit.join("manifest.json")).unwrap()).unwrap();
    assert!(m["relit"]["iterations"].as_u64().is_some() && m.get("live").is_none());
    let sunny = dir.join("sunny");
    run_ok([
        "relight",
        b,
        "--sun-direction",
        "0.5,0.6,0.3",
        "-o",
        sunny.to_str().unwrap(),
        "--quiet",
    ]);
    let lit: f32 = exr(&sunny.join("lightmap_0.exr"))
        .iter()
        .map(|v| v.element_sum())
        .sum();
    let sky_only: f32 = sky.iter().map(|v| v.element_sum()).sum();
    assert!(
        lit > 1.05 * sky_only,
        "the sun's bounce adds light: {lit} vs {sky_only}"
    );

    // Bad input: one line each, naming the cause.
    let x = dir.join("x");
    let x = x.to_str().unwrap();
    let e = error_of(&["relight", b, "--sun-direction", "0,0,0", "-o", x]);
    assert!(e.contains("zero length"), "{e}");
    let e = error_of(&["relight", b, "--sun-direction", "nan,1,0", "-o", x]);
    assert!(e.contains("not finite"), "{e}");
    let broken = dir.join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    for f in std::fs::read_dir(&bake).unwrap().flatten() {
        std::fs::copy(f.path(), broken.join(f.file_name())).unwrap();
    }
    let live_bin = broken.join("live.bin");
    let mut bytes = std::fs::read(&live_bin).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 0x10;
    std::fs::write(&live_bin, &bytes).unwrap();
    let br = broken.to_str().unwrap();
    let e = error_of(&["relight", br, "--sun-direction", "0,1,0", "-o", x]);
    assert!(e.contains("live.bin") && e.contains("checksum"), "{e}");
    std::fs::write(&live_bin, &bytes[..n / 2]).unwrap();
    let e = error_of(&["relight", br, "--sun-direction", "0,1,0", "-o", x]);
    assert!(e.contains("live.bin") && e.contains("truncated"), "{e}");
    let e = error_of(&["bake", p, "--live", "--live-probe-rays", "5000", "-o", x]);
    assert!(e.contains("live_probe_rays"), "{e}");
    let e = error_of(&["bake", p, "--live", "--sun-path", "80,355", "-o", x]);
    assert!(e.contains("never rises"), "{e}");
    let e = error_of(&["bake", p, "--live", "--solver", "progressive", "-o", x]);
    assert!(
        e.contains("live lights need a stored form-factor matrix"),
        "{e}"
    );
    let cornell = scene_path("cornell_layers.gltf");
    let c = cornell.to_str().unwrap();
    let e = error_of(&["bake", c, "--light-mode", "bulb=live", "-o", x]);
    assert!(
        e.contains("bulb") && e.contains("directional lights only"),
        "{e}"
    );
    let e = error_of(&["bake", c, "--live", "-o", x]);
    assert!(e.contains("no directional light"), "{e}");
    let e = error_of(&["relight", x, "--sun-direction", "0,1,0", "-o", r]);
    assert!(e.contains("manifest.json"), "{e}");
}

/// Along a sun path the table traces every fourth sample and the ones
/// between only where a texel's ends differ (`sun_table::PATH_STRIDE`):
/// on the porch over a day (256 samples), against tracing every sample,
/// the bytes that differ are few and small.
#[test]
fn the_path_stride_keeps_the_table() {
    let (scene, config, _) = porch_at_node();
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let rays = radbake::raycast::RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let path = radbake::scene::sun_path::SunPath::Day {
        latitude: 40.0,
        day: 172.0,
        samples: 256,
    }
    .directions()
    .unwrap();
    let light = &scene.lights[0];
    let strided =
        radbake::light::sun_table::sun_table_along(&s, light, &path, config.seed, &|_| {});
    let every = radbake::light::sun_table::patch_direct(&s, light, &path, config.seed, &|_| {});
    let p = every.len();
    let (mut differ, mut worst) = (0usize, 0i32);
    for (i, row) in every.iter().enumerate() {
        for (k, v) in row.iter().enumerate() {
            let q = (v * 255.0 * std::f32::consts::PI).round().clamp(0.0, 255.0) as i32;
            let d = (q - strided[k * p + i] as i32).abs();
            differ += (d > 0) as usize;
            worst = worst.max(d);
        }
    }
    let share = differ as f64 / strided.len() as f64;
    eprintln!(
        "path stride: {differ} of {} bytes differ ({:.4} %), worst by {worst}",
        strided.len(),
        100.0 * share
    );
    assert!(strided.iter().any(|&b| b > 0), "the table is lit");
    assert!(share <= 0.005, "{:.4} % of the bytes differ", 100.0 * share);
}

/// Irradiance / π at each probe for the six axis normals, over the valid
/// probes.
fn probe_cubes(sh: &[radbake::probes::Sh9], valid: &[bool]) -> Vec<Vec3> {
    (sh.iter().zip(valid))
        .filter(|(_, v)| **v)
        .flat_map(|(s, _)| {
            radbake::probes::sh::AXES.map(|n| radbake::probes::sh::irradiance_over_pi(s, n))
        })
        .collect()
}

/// Σ|a − b| / Σ|b|.
fn rel_error(a: &[Vec3], b: &[Vec3]) -> f32 {
    let num: f32 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).abs().element_sum())
        .sum();
    num / b.iter().map(|y| y.abs().element_sum()).sum::<f32>()
}

/// The live layer's probes follow the sun: the porch baked with its sun
/// live, the runtime's probes for the sun turned 30° about +Y against a
/// full bake with the sun there (mode `indirect`: the probes hold its
/// bounce light alone, as the live layer's do). With the baked probes
/// exactly as baked at the baked sun (`probe_delta` 0 there: the unit
/// test in `live/src/solve.rs`).
#[test]
fn the_live_probes_follow_the_sun() {
    let mut scene = radbake::scene::load(&scene_path("porch.gltf"), &Default::default()).unwrap();
    let config = BakeConfig {
        texels_per_meter: 4.0,
        ..BakeConfig::default()
    };
    let mode = |scene: &mut radbake::scene::Scene, m: LightMode| {
        let mut c = config.clone();
        c.light_modes.lights.insert("sun".into(), m);
        c.light_modes.apply(scene).unwrap();
        c
    };
    let live_config = mode(&mut scene, LightMode::Live);
    let bake = radbake::bake(&scene, &live_config, &Silent).unwrap();
    let probes = bake.probes.as_ref().expect("probes");
    let k = (bake.layers.as_ref().unwrap().names.iter())
        .position(|n| n == "live")
        .unwrap();
    let baked = &probes.layers[k];
    let to_sun = -scene.lights[0].direction;
    let turned = glam::Quat::from_rotation_y(30f32.to_radians()) * to_sun;
    let mut live = Live::new(bake.live.clone().unwrap());
    live.update(&[Sun {
        direction: turned.to_array(),
        irradiance: scene.lights[0].intensity.to_array(),
    }])
    .unwrap();
    let delta = live.probe_delta().expect("the probes' rays are kept");
    let relit: Vec<radbake::probes::Sh9> = (baked.iter().zip(&delta))
        .map(|(b, d)| std::array::from_fn(|i| b[i] + Vec3::from(d[i])))
        .collect();

    let mut full_scene = scene.clone();
    let full_config = mode(&mut full_scene, LightMode::Indirect);
    full_scene.lights[0].direction = -turned;
    let full = radbake::bake(&full_scene, &full_config, &Silent).unwrap();
    let fp = full.probes.as_ref().unwrap();
    assert_eq!(fp.valid, probes.valid);
    let want = probe_cubes(&fp.sh, &fp.valid);
    let moved = rel_error(&probe_cubes(baked, &probes.valid), &want);
    let error = rel_error(&probe_cubes(&relit, &probes.valid), &want);
    println!(
        "porch probes, sun turned 30°: as baked {:.2} % off the full bake, relit {:.2} % ({} valid probes)",
        100.0 * moved,
        100.0 * error,
        want.len() / 6
    );
    // The live layer's texels against the full bake's, for scale: the
    // probes can be no closer than the surfaces they see.
    let texels: Vec<Vec3> = live.texels().into_iter().map(Vec3::from).collect();
    let valid = &full.transport.valid;
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { (0..v.len()).filter(|t| valid[*t]).map(|t| v[t]).collect() };
    let surfaces = rel_error(&pick(&texels), &pick(&full.maps.lightmaps.texel_values));
    println!(
        "  the live layer's texels {:.2} % off the full bake's",
        100.0 * surfaces
    );
    assert!(moved > 0.05, "the turn changes the probes by {moved}");
    assert!(
        error < 0.4 * moved && error < 2.0 * surfaces,
        "relit {error}, as baked {moved}, texels {surfaces}"
    );
}

/// Independent of the bake: the porch baked with its sun live and a sky,
/// relit by the runtime for the sun turned 30° about +Y, each instance's
/// mean (what it receives: every layer, the live one relit, over its
/// exposed texels, as `report.json`'s `mean`) against the meter
/// (`radbake measure`: path traced from the scene's triangles, no atlas,
/// texels, patches or form factors) on the scene with the sun there in
/// mode `indirect` (its direct light left out, its bounces kept, as the
/// live layer's). Within 3 % or 3 standard errors, the target
/// for a full bake: the live solution has no final gather.
#[test]
fn the_relit_porch_matches_the_meter() {
    use radbake::trace::measure::{Meter, MeterSettings};
    let sky = Vec3::new(0.3, 0.4, 0.55);
    let mut scene = radbake::scene::load(&scene_path("porch.gltf"), &Default::default()).unwrap();
    let mut config = BakeConfig {
        texels_per_meter: 8.0,
        sky: sky.into(),
        probes: false,
        ..BakeConfig::default()
    };
    sun_mode(&mut config, &mut scene, LightMode::Live);
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let to_sun = -scene.lights[0].direction;
    let turned = glam::Quat::from_rotation_y(30f32.to_radians()) * to_sun;
    let mut live = Live::new(bake.live.clone().unwrap());
    live.update(&[Sun {
        direction: turned.to_array(),
        irradiance: scene.lights[0].intensity.to_array(),
    }])
    .unwrap();
    let relit_live = live.texels();
    let k = (bake.layers.as_ref().unwrap().names.iter())
        .position(|n| n == "live")
        .unwrap();
    let n = scene.instances.len();
    // Per instance: Σ a, Σ a·exposed·value (relit), the same as baked.
    let mut sums = vec![[0.0f64; 3]; n];
    for t in 0..bake.texels.len() {
        let exposed = if bake.transport.valid[t] {
            bake.burial.exposed(t) as f64
        } else {
            0.0
        };
        let others: Vec3 = (bake.maps.layers.iter().enumerate())
            .filter(|(j, _)| *j != k)
            .map(|(_, lm)| lm.texel_values[t])
            .sum();
        let relit = others + Vec3::from(relit_live[t]);
        let baked = others + bake.maps.layers[k].texel_values[t];
        let a = bake.texels.area[t] as f64;
        let s = &mut sums[bake.texels.instance[t] as usize];
        s[0] += a;
        s[1] += a * exposed * relit.element_sum() as f64 / 3.0;
        s[2] += a * exposed * baked.element_sum() as f64 / 3.0;
    }

    let mut metered = scene.clone();
    sun_mode(&mut config.clone(), &mut metered, LightMode::Indirect);
    metered.lights[0].direction = -turned;
    let settings = MeterSettings {
        samples: 200_000,
        normal: Default::default(),
        sky,
        seed: 11,
    };
    let readings = Meter::new(&metered).measure(&[], &settings).unwrap();
    let mut moved = 0.0f64;
    for (i, m) in readings.iter().enumerate() {
        assert_eq!(scene.instances[i].node, m.node);
        let want = m.mean.iter().sum::<f64>() / 3.0;
        let se = m.std_error.iter().map(|s| s * s).sum::<f64>().sqrt() / 3.0;
        let (got, before) = (sums[i][1] / sums[i][0], sums[i][2] / sums[i][0]);
        println!(
            "porch, sun turned 30°: {} relit {got:.5}, as baked {before:.5}, meter {want:.5} ± {se:.5} ({:+.2} %; as baked {:+.2} %)",
            m.node,
            100.0 * (got / want - 1.0),
            100.0 * (before / want - 1.0)
        );
        moved = moved.max((before / want - 1.0).abs());
        assert!(
            (got - want).abs() <= (0.03 * want).max(3.0 * se),
            "{}: relit {got:.5}, meter {want:.5} ± {se:.5}",
            m.node
        );
    }
    // The turn matters: as baked, some instance is off by more than the tolerance.
    assert!(moved > 0.03, "the turn moves the means by at most {moved}");
}

/// `radbake preview --live` moves the probes as `radbake relight` does: a
/// porch with a dynamic node (a small copy of the floor, lit by the
/// probes per vertex), opened at the baked sun and turned 30°: the
/// model's probes are relight's at that sun, and the dynamic node's
/// vertices are lit from them (no GPU: the solve and the probes, not the
/// upload).
#[test]
fn the_preview_moves_the_probes_with_the_sun() {
    use radbake::preview::live::{angles, baked_direction, LiveView};
    use radbake::preview::model::Model;
    let dir = temp_dir("live-preview-probes");
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(scene_path("porch.gltf")).unwrap()).unwrap();
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(
        serde_json::json!({"name": "crate", "mesh": 0, "translation": [0.0, 0.8, 0.0],
        "scale": [0.2, 0.2, 0.2], "extras": {"radbake": {"dynamic": true}}}),
    );
    let n = nodes.len() - 1;
    doc["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(n.into());
    let scene = dir.join("porch_crate.gltf");
    std::fs::write(&scene, serde_json::to_vec(&doc).unwrap()).unwrap();
    let bake = dir.join("bake");
    let (s, b) = (scene.to_str().unwrap(), bake.to_str().unwrap());
    run_ok(
        [
            "bake",
            s,
            "--live",
            "--sky",
            "0.3,0.4,0.55",
            "--texels-per-meter",
            "4",
        ]
        .iter()
        .chain(&["--quiet", "-o", b]),
    );
    let glb = bake.join("porch_crate.baked.glb");
    let to_sun = baked_direction(&glb).unwrap();
    let turned = glam::Quat::from_rotation_y(30f32.to_radians()) * to_sun;
    let relit = dir.join("relit");
    let t = turned.to_array().map(|c| c.to_string()).join(",");
    run_ok([
        "relight",
        b,
        "--sun-direction",
        &t,
        "--quiet",
        "-o",
        relit.to_str().unwrap(),
    ]);
    let want = radbake::probes::Probes::read(&relit.join("probes.json")).unwrap();

    let start = radbake::output::relight::Relight {
        sun_direction: to_sun,
        sun_irradiance: None,
        sky: None,
        weights: Vec::new(),
    };
    let mut model = Model::load_relit(&glb, &[], Some(&start)).unwrap();
    let lit: Vec<usize> = (0..model.vertices.len())
        .filter(|&i| model.vertices[i].probe[3] == radbake::preview::gpu::PROBE_LIT)
        .collect();
    assert!(!lit.is_empty(), "the dynamic node is lit by the probes");
    let before: Vec<[f32; 4]> = lit.iter().map(|&i| model.vertices[i].probe).collect();
    let mut view = LiveView::open(&glb, &[], Some(&start)).unwrap();
    let (e0, a0) = (view.elevation, view.azimuth);
    let (e1, a1) = angles(turned);
    view.turn(e1 - e0, a1 - a0);
    let (_, _, moved) = view.relight(&mut model).unwrap();
    assert!(moved, "the probes moved");
    let got = model.probes.as_ref().unwrap();
    let cubes = |p: &radbake::probes::Probes| probe_cubes(&p.sh, &p.valid);
    let error = rel_error(&cubes(got), &cubes(&want));
    let baked = radbake::probes::Probes::read(&bake.join("probes.json")).unwrap();
    let change = rel_error(&cubes(&baked), &cubes(&want));
    // The vertices: lit from the new probes.
    let mut worst = 0.0f32;
    let mut changed = 0.0f32;
    for (&i, b) in lit.iter().zip(&before) {
        let v = &model.vertices[i];
        let w = radbake::preview::probe_light::vertex_light(
            Some(&want),
            Vec3::from(v.position),
            Vec3::from(v.normal),
        );
        let scale = Vec3::from_slice(&w[..3]).max_element().max(1e-6);
        worst = worst.max(
            (Vec3::from_slice(&v.probe[..3]) - Vec3::from_slice(&w[..3]))
                .abs()
                .max_element()
                / scale,
        );
        changed = changed.max(
            (Vec3::from_slice(&v.probe[..3]) - Vec3::from_slice(&b[..3]))
                .abs()
                .max_element()
                / scale,
        );
    }
    println!(
        "preview --live, sun turned 30°: probes {error:.2e} off relight's (relight's differ from the bake's by {change:.2e}); {} probe-lit vertices, worst {worst:.2e} off, changed by up to {changed:.2e}",
        lit.len()
    );
    assert!(change > 0.01, "the turn moves the probes by {change}");
    assert!(error < 1e-3, "probes {error} off relight's");
    assert!(worst < 1e-3, "a vertex {worst} off relight's probes");
    assert!(changed > 0.01, "the vertices' light changed by {changed}");
}
