//! Lights with a size (issue #23): a sun disk's `angle` and a point or
//! spot light's `radius` under the node's `extras.radbake` give soft
//! shadows, sampled over the light's extent and stratified per texel.
//!
//! - A 0.53° sun (the real sun's angular diameter), and a 5 cm sphere
//!   light, straight above a plate edge 20 m up: the penumbra on the
//!   ground below against the analytic one (the visible part of a disk past
//!   a straight edge).
//! - Size 0 is a delta light exactly as without the key; bad values are
//!   one-line errors naming the node.

mod common;

use common::{check_penumbra, edge_scene, DENSITY, H, SUN};
use radbake::{BakeConfig, Silent};
use serde_json::{json, Value};
use std::f64::consts::PI;

fn config() -> BakeConfig {
    BakeConfig {
        texels_per_meter: DENSITY,
        probes: false,
        ..BakeConfig::default()
    }
}

/// A 0.53° sun straight above the plate's edge 20 m up: on the ground, the
/// visible fraction at distance x past the edge is the part of the sun's
/// disk (radius r = H tan(α/2) projected on the ground) past the edge,
/// F(x / r).
#[test]
fn sun_disk_gives_the_analytic_penumbra() {
    let angle_deg = 0.53f64;
    let path = edge_scene("size-sun", Some(json!({"radbake": {"angle": angle_deg}})));
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    assert!(scene.lights[0].has_extent());
    let bake = radbake::bake(&scene, &config(), &Silent).unwrap();
    let r = H as f64 * (0.5 * angle_deg.to_radians()).tan();
    let v = &bake.transport.values;
    check_penumbra(&bake, |t| v[t].x as f64 / (SUN as f64 / PI), r);
}

/// A sphere light of radius R = 5 cm at height 30 m above the plate's edge
/// (the sun of the scene swapped for a point light there): the ground
/// point at x sees the light's centre through the plate's plane at
/// x (1 − H/30), and the sphere's cone (sin θ = R/d) as a disk of radius
/// H tan θ there, so F(x / r) with r = H tan θ / (1 − H/30) (d varies by
/// under 0.01 % over the penumbra). Unshadowed: I cos φ / (π d²).
#[test]
fn sphere_light_gives_the_analytic_penumbra() {
    let (height, radius, intensity) = (30.0f64, 0.05f64, 1000.0f64);
    let path = edge_scene("size-sphere", Some(json!({"radbake": {"radius": radius}})));
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["extensions"]["KHR_lights_punctual"]["lights"][0] =
        json!({"type": "point", "intensity": intensity});
    let nodes = doc["nodes"].as_array_mut().unwrap();
    let light = nodes.len() - 1;
    nodes[light]["translation"] = json!([0.0, height, 0.0]);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    assert!(scene.lights[0].has_extent());
    let bake = radbake::bake(&scene, &config(), &Silent).unwrap();
    let h = H as f64;
    let tan = (radius / height).asin().tan();
    let r = h * tan / (1.0 - h / height);
    let e = |x: f64| {
        let d2 = height * height + x * x;
        intensity * (height / d2.sqrt()) / (PI * d2)
    };
    let (v, p) = (&bake.transport.values, &bake.texels.p_ws);
    check_penumbra(&bake, |t| v[t].x as f64 / e(p[t].x as f64), r);
}

/// `angle: 0` and `radius: 0` are the delta lights of today, bit for bit;
/// a negative radius or an angle of 90° is a one-line error naming the
/// node; `radius` on a sun is a named warning.
#[test]
fn zero_size_is_a_delta_light_and_bad_sizes_fail() {
    let plain = edge_scene("size-plain", None);
    let zero = edge_scene("size-zero", Some(json!({"radbake": {"angle": 0.0}})));
    let cfg = BakeConfig {
        texels_per_meter: 10.0,
        ..config()
    };
    let a = radbake::scene::load(&plain, &Default::default()).unwrap();
    let b = radbake::scene::load(&zero, &Default::default()).unwrap();
    assert!(!b.lights[0].has_extent());
    let (ba, bb) = (
        radbake::bake(&a, &cfg, &Silent).unwrap(),
        radbake::bake(&b, &cfg, &Silent).unwrap(),
    );
    assert_eq!(ba.transport.values, bb.transport.values);

    for (name, extras, key) in [
        ("size-neg", json!({"radbake": {"angle": -1.0}}), "angle"),
        ("size-90", json!({"radbake": {"angle": 90.0}}), "angle"),
        ("size-str", json!({"radbake": {"radius": "big"}}), "radius"),
    ] {
        let path = edge_scene(name, Some(extras));
        let err = radbake::scene::load(&path, &Default::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains(&format!("extras.radbake.{key}")) && err.contains("edge.gltf"),
            "{err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    let path = edge_scene("size-warn", Some(json!({"radbake": {"radius": 0.5}})));
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    assert!(!scene.lights[0].has_extent());
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("radius") && w.contains("nodes[")),
        "{:?}",
        scene.warnings
    );
}
