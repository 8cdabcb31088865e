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

use common::{quad, temp_dir, GltfBuilder};
use radbake::{BakeConfig, Silent};
use serde_json::{json, Value};
use std::f64::consts::PI;
use std::path::PathBuf;

/// Plate height, sun irradiance (W/m²), texel density.
const H: f32 = 20.0;
const SUN: f32 = 2.0;
const DENSITY: f32 = 50.0;

/// A black 4 × 4 m ground at y = 0 and a black plate at height `H` over
/// x < 0 (edge along z at x = 0), under a sun straight down whose node
/// has `extras`.
fn edge_scene(name: &str, extras: Option<Value>) -> PathBuf {
    let mut b = GltfBuilder::default();
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("ground", m);
    let (p, i) = quad([-2.5, H, -2.5], [0.0, 0.0, 5.0], [2.5, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("plate", m);
    let mut doc = b.json();
    common::add_vertical_sun(&mut doc, SUN);
    if let Some(e) = extras {
        let nodes = doc["nodes"].as_array_mut().unwrap();
        let sun = nodes.len() - 1;
        nodes[sun]["extras"] = e;
    }
    let path = temp_dir(name).join("edge.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

fn config() -> BakeConfig {
    BakeConfig {
        texels_per_meter: DENSITY,
        probes: false,
        ..BakeConfig::default()
    }
}

/// Fraction of the unit disk with coordinate below `a` (clamped).
fn disk_below(a: f64) -> f64 {
    let a = a.clamp(-1.0, 1.0);
    (a * (1.0 - a * a).sqrt() + a.asin() + PI / 2.0) / PI
}

/// Checks the penumbra on the ground below the plate's edge: per column
/// of ground texels (the mean over the 150 texels along the edge, so the
/// per-texel sampling noise averages out), the lightmap over the
/// unshadowed value `e(x)` is the analytic visible fraction F(x / r)
/// averaged over the texel's width within 0.03, and the 10–90 % width of
/// the penumbra is within 10 % of the analytic one. Returns the two widths.
fn check_penumbra(bake: &radbake::Bake, e: impl Fn(f64) -> f64, r: f64) -> (f64, f64) {
    let tx = &bake.texels;
    let width = 1.0 / DENSITY as f64;
    let mut cols: std::collections::BTreeMap<i64, (f64, f64, u32)> = Default::default();
    for t in 0..tx.len() {
        let p = tx.p_ws[t];
        if tx.instance[t] != 0 || p.z.abs() > 1.5 || (p.x as f64).abs() > 2.5 * r {
            continue;
        }
        if (tx.area[t] as f64) < 0.99 * width * width {
            continue; // a partly covered texel at the ground's edge
        }
        let key = (p.x as f64 / width).floor() as i64;
        let c = cols.entry(key).or_insert((0.0, 0.0, 0));
        c.0 += bake.transport.values[t].x as f64;
        c.1 += p.x as f64;
        c.2 += 1;
    }
    assert!(cols.len() >= 8, "{} columns", cols.len());
    let mut worst = 0.0f64;
    let mut profile = Vec::new();
    for (sum, xs, n) in cols.values() {
        let x = xs / *n as f64;
        let got = sum / *n as f64 / e(x);
        // F averaged over the texel's width.
        let k = 64;
        let want: f64 = (0..k)
            .map(|j| disk_below((x + width * ((j as f64 + 0.5) / k as f64 - 0.5)) / r))
            .sum::<f64>()
            / k as f64;
        eprintln!("x {x:+.4}: {got:.4} (analytic {want:.4}, {n} texels)");
        worst = worst.max((got - want).abs());
        profile.push((x, got));
    }
    assert!(worst < 0.03, "worst column {worst}");
    // The 10–90 % width, by linear interpolation of the column profile.
    let cross = |level: f64| {
        profile
            .windows(2)
            .find(|w| w[0].1 < level && w[1].1 >= level)
            .map(|w| w[0].0 + (level - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0))
            .expect("the profile crosses the level")
    };
    let measured = cross(0.9) - cross(0.1);
    let solve = |level: f64| {
        let (mut lo, mut hi) = (-1.0, 1.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if disk_below(mid) < level {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo * r
    };
    let analytic = solve(0.9) - solve(0.1);
    eprintln!("10–90 % width: {measured:.4} m, analytic {analytic:.4} m (r = {r:.4} m)");
    assert!((measured / analytic - 1.0).abs() < 0.10);
    (measured, analytic)
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
    check_penumbra(&bake, |_| SUN as f64 / PI, r);
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
    check_penumbra(&bake, e, r);
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
