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
fn bake(path: &Path, config: &BakeConfig) -> Vec<radbake::report::InstanceReport> {
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
    let settings = radbake::measure::MeterSettings {
        samples: 20_000,
        normal: Default::default(),
        sky: glam::Vec3::ZERO,
        seed: 3,
    };
    let reading = &radbake::measure::Meter::new(&scene)
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
