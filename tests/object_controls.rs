//! Per-object lightmap controls under a node's `extras.radbake` (issue
//! #23): `texel_scale` multiplies the node's lightmap density, inside the
//! bake's texel budget.

mod common;

use common::{quad, temp_dir, GltfBuilder};
use radbake::{BakeConfig, Silent};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Two instances of one 1 × 1 m quad side by side under a sky, the first
/// with `extras` on its node.
fn two_quads(name: &str, extras: Value) -> PathBuf {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("fine", m);
    b.node("plain", m);
    let mut doc = b.json();
    doc["nodes"][0]["extras"] = extras;
    doc["nodes"][1]["translation"] = json!([2.0, 0.0, 0.0]);
    let path = temp_dir(name).join("quads.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// The instances' report lines of a bake of `path`.
fn bake(path: &Path, config: &BakeConfig) -> Vec<radbake::pipeline::report::InstanceReport> {
    let scene = radbake::scene::load(path, &Default::default()).unwrap();
    radbake::bake(&scene, config, &Silent)
        .unwrap()
        .instance_reports()
}

/// `texel_scale: 2` gives its instance 4 × the texels of the same mesh's
/// other instance (within the packing's rounding: the texels a quad's
/// edges touch), also when the budget lowers the bake's density; both
/// read the sky's exact irradiance; the report lists the scale.
#[test]
fn texel_scale_multiplies_the_density() {
    let path = two_quads("objects-scale", json!({"radbake": {"texel_scale": 2.0}}));
    let sky = 0.8;
    for (max_texels, density) in [(1 << 20, 20.0), (2000, 40.0)] {
        let config = BakeConfig {
            texels_per_meter: density,
            max_texels,
            sky: [sky; 3],
            probes: false,
            ..BakeConfig::default()
        };
        let r = bake(&path, &config);
        let (fine, plain) = (&r[0], &r[1]);
        assert_eq!((fine.node.as_str(), plain.node.as_str()), ("fine", "plain"));
        assert_eq!((fine.texel_scale, plain.texel_scale), (2.0, 1.0));
        let ratio = fine.texels as f64 / plain.texels as f64;
        eprintln!(
            "max_texels {max_texels}: {} vs {} texels, ratio {ratio:.3}",
            fine.texels, plain.texels
        );
        assert!((3.5..=4.5).contains(&ratio), "ratio {ratio}");
        if max_texels < 1 << 20 {
            // The budget held: both together within it.
            assert!(fine.texels + plain.texels <= max_texels);
        }
        for inst in [fine, plain] {
            for c in inst.mean {
                assert!((c - sky).abs() < 1e-4, "{}: {c}", inst.node);
            }
        }
    }
}

/// A `texel_scale` that is not a number in (0, 64] is a one-line error
/// naming the node's key and the file.
#[test]
fn bad_texel_scale_is_a_clear_error() {
    for (k, bad) in [json!(0.0), json!(-1.0), json!(100.0), json!("big")]
        .into_iter()
        .enumerate()
    {
        let path = two_quads(
            &format!("objects-bad{k}"),
            json!({"radbake": {"texel_scale": bad}}),
        );
        let err = radbake::scene::load(&path, &Default::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("nodes[0].extras.radbake.texel_scale") && err.contains("quads.gltf"),
            "{err}"
        );
        assert_eq!(err.lines().count(), 1);
    }
}

/// A mesh's `extras.radbake.texel_scale` is the density of every node that
/// uses the mesh and sets none of its own; a node's own wins; an unknown
/// key under a mesh's `radbake` is a named warning.
#[test]
fn mesh_texel_scale_and_node_override() {
    let path = two_quads("objects-mesh", json!({"radbake": {"texel_scale": 1.0}}));
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["meshes"][0]["extras"] = json!({"radbake": {"texel_scale": 2.0, "shiny": true}});
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let scales: Vec<f32> = scene.instances.iter().map(|i| i.texel_scale).collect();
    assert_eq!(
        scales,
        vec![1.0, 2.0],
        "node `fine` sets 1, `plain` takes the mesh's 2"
    );
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("meshes[0].extras.radbake") && w.contains("shiny")),
        "{:?}",
        scene.warnings
    );
    let config = BakeConfig {
        texels_per_meter: 20.0,
        probes: false,
        ..BakeConfig::default()
    };
    let r = bake(&path, &config);
    assert_eq!((r[0].texels * 4, r[1].texel_scale), (r[1].texels, 2.0));
}

/// A black ground under a sun straight down, and a black plate 1 m up over
/// its x < 0 half, the plate's node with `extras`.
fn shaded_ground(name: &str, extras: Value) -> PathBuf {
    let mut b = GltfBuilder::default();
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("ground", m);
    let (p, i) = quad([-3.0, 1.0, -3.0], [0.0, 0.0, 6.0], [3.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("plate", m);
    let mut doc = b.json();
    doc["nodes"][1]["extras"] = extras;
    common::add_vertical_sun(&mut doc, 2.0);
    let path = temp_dir(name).join("shade.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// `cast_shadows: false`: the plate no longer shades the ground (every
/// ground texel reads the sun's exact E/π, on the CPU and through
/// `--device gpu` alike, and so does the meter), while the plate's own
/// texels are still lit; with the default the ground under it is dark.
#[test]
fn cast_shadows_false_leaves_a_node_out_of_the_rays() {
    let e = 2.0 / std::f32::consts::PI;
    let config = BakeConfig {
        texels_per_meter: 8.0,
        probes: false,
        ..BakeConfig::default()
    };
    let shaded = bake(&shaded_ground("objects-shade", json!({})), &config);
    let ground = shaded[0].mean[0];
    assert!(
        ground < 0.6 * e,
        "the plate shades half the ground: {ground}"
    );

    let path = shaded_ground(
        "objects-noshade",
        json!({"radbake": {"cast_shadows": false}}),
    );
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    assert!(!scene.instances[1].cast_shadows);
    for device in [radbake::config::Device::Cpu, radbake::config::Device::Gpu] {
        let config = BakeConfig {
            device,
            ..config.clone()
        };
        let bake = radbake::bake(&scene, &config, &Silent).unwrap();
        eprintln!("{device:?}: {:?}", bake.warnings);
        let ground: Vec<f32> = (0..bake.texels.len())
            .filter(|&t| bake.texels.instance[t] == 0 && bake.transport.valid[t])
            .map(|t| bake.transport.values[t].x)
            .collect();
        assert!(!ground.is_empty());
        for v in &ground {
            assert!(
                (v - e).abs() < 1e-4 * e,
                "{device:?}: ground texel {v}, sun {e}"
            );
        }
        let plate = &bake.instance_reports()[1];
        assert!(!plate.cast_shadows);
        assert!(
            (plate.mean[0] - e).abs() < 1e-3 * e,
            "plate {}",
            plate.mean[0]
        );
    }
    let settings = radbake::trace::measure::MeterSettings {
        samples: 20_000,
        normal: Default::default(),
        sky: glam::Vec3::ZERO,
        seed: 3,
    };
    let reading = &radbake::trace::measure::Meter::new(&scene)
        .measure(&["ground".to_owned()], &settings)
        .unwrap()[0];
    assert!((reading.mean[0] as f32 - e).abs() < 1e-4 * e, "{reading:?}");

    // Bad values, and a scene where nothing would be left to meet.
    let bad = shaded_ground(
        "objects-noshade-bad",
        json!({"radbake": {"cast_shadows": "no"}}),
    );
    let err = radbake::scene::load(&bad, &Default::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("nodes[1].extras.radbake.cast_shadows"),
        "{err}"
    );
}

/// A grey ground and a white wall (x = 0.5, facing −X) under a sun from
/// 45° over −X: the wall shades the ground behind it and bounces light
/// onto the ground in front, the wall's node with `extras`.
fn walled_ground(name: &str, extras: Value) -> PathBuf {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let white = b.material([0.8; 3], [0.0; 3]);
    let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("ground", m);
    let (p, i) = quad([0.5, 0.0, -2.0], [0.0, 0.0, 4.0], [0.0, 2.0, 0.0]);
    let m = b.mesh(&p, &i, Some(white));
    b.node("wall", m);
    let mut doc = b.json();
    doc["nodes"][1]["extras"] = extras;
    let to_sun = glam::Vec3::new(-1.0, 1.0, 0.0).normalize();
    let rot = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, -to_sun);
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"name": "sun", "rotation": rot.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    doc["scenes"][0]["nodes"] = json!([0, 1, 2]);
    doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc["extensions"] =
        json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.0}]}});
    let path = temp_dir(name).join("wall.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// `lightmap: false` on the wall: it still shades the ground behind it
/// and bounces light onto the ground in front as the lightmapped wall
/// does (the ground's bounced light within 3 %; without the wall's
/// rays, `cast_shadows: false`, there is none), with a sixteenth of
/// the texels (a quarter of the density); the baked `.glb` gives it no
/// `MOZ_lightmap`, and the manifest and report say `lightmap: false`.
#[test]
fn lightmap_false_still_shades_and_bounces() {
    let cfg = BakeConfig {
        texels_per_meter: 16.0,
        probes: false,
        ..BakeConfig::default()
    };
    let direct = 2.0 * std::f32::consts::FRAC_1_SQRT_2 / std::f32::consts::PI;
    // Ground texels' mean in front of the wall (x < 0.4) less the sun's
    // direct light, and behind it (x > 0.6).
    let ground = |extras: Value, name: &str| {
        let path = walled_ground(name, extras);
        let scene = radbake::scene::load(&path, &Default::default()).unwrap();
        let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
        let (mut front, mut nf, mut behind, mut nb) = (0.0f64, 0, 0.0f64, 0);
        for t in 0..bake.texels.len() {
            let p = bake.texels.p_ws[t];
            if bake.texels.instance[t] != 0 {
                continue;
            }
            let v = bake.transport.values[t].x as f64;
            if p.x < 0.4 {
                front += v - direct as f64;
                nf += 1;
            } else if p.x > 0.6 {
                behind += v;
                nb += 1;
            }
        }
        let texels = bake.instance_reports()[1].texels;
        (front / nf as f64, behind / nb as f64, texels)
    };
    let (bounce_on, behind_on, texels_on) = ground(json!(null), "lm-on");
    let (bounce_off, behind_off, texels_off) =
        ground(json!({"radbake": {"lightmap": false}}), "lm-off");
    let (bounce_none, _, _) = ground(json!({"radbake": {"cast_shadows": false}}), "lm-none");
    eprintln!(
        "bounce in front: lightmapped {bounce_on:.5}, lightmap false {bounce_off:.5}, no wall {bounce_none:.5}; \
         behind: {behind_on:.5}, {behind_off:.5}; wall texels {texels_on} vs {texels_off}"
    );
    assert!(bounce_on > 0.02 && bounce_none.abs() < 1e-4);
    assert!((bounce_off / bounce_on - 1.0).abs() < 0.03);
    assert!(behind_off < 0.1 * direct as f64 && behind_on < 0.1 * direct as f64);
    let ratio = texels_on as f64 / texels_off as f64;
    assert!((12.0..=20.0).contains(&ratio), "texel ratio {ratio}");

    // The files.
    let path = walled_ground("lm-cli", json!({"radbake": {"lightmap": false}}));
    let out = temp_dir("lm-cli-out");
    common::run_ok::<_, std::ffi::OsString>([
        "bake".into(),
        "-q".into(),
        "--force".into(),
        "--texels-per-meter".into(),
        "8".into(),
        "--probes".into(),
        "off".into(),
        std::ffi::OsString::from(&path),
        std::ffi::OsString::from("--out"),
        std::ffi::OsString::from(&out),
    ]);
    let read = |f: &str| -> Value {
        serde_json::from_slice(&std::fs::read(out.join(f)).unwrap()).unwrap()
    };
    let manifest = read("manifest.json");
    assert_eq!(manifest["instances"][0]["lightmap"], true);
    assert_eq!(manifest["instances"][1]["lightmap"], false);
    assert_eq!(read("report.json")["instances"][1]["lightmap"], false);
    let doc = common::glb_json(&out.join("wall.baked.glb"));
    let lightmapped = |node: usize| {
        let mesh = doc["nodes"][node]["mesh"].as_u64().unwrap() as usize;
        doc["meshes"][mesh]["primitives"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| {
                let m = p["material"].as_u64().unwrap() as usize;
                doc["materials"][m]["extensions"]
                    .get("MOZ_lightmap")
                    .is_some()
            })
    };
    assert!(lightmapped(0));
    assert!(!lightmapped(1));
    assert_eq!(doc["nodes"][1]["extras"]["radbake"]["lightmap"], false);
}
