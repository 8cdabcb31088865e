//! The final gather's near field ([`radbake::radiosity::gather::NearField`]): a gather
//! ray that lands closer than a texel reads the local lights' direct light
//! at its hit point, not the hit texel's mean.
//!
//! Checked against independent answers: Howell's point-to-rectangle form
//! factor for the point estimate, and the irradiance meter
//! ([`radbake::trace::measure`], no atlas, texels or gather) for a lamp on a
//! wall, whose 5 cm side faces see the strip of wall they light.

mod common;

use common::{quad, scene_path, temp_dir, GltfBuilder};
use glam::Vec3;
use radbake::config::EmitterSampling;
use radbake::light::direct::local_light_at;
use radbake::light::lights::{sampled_materials, Lights};
use radbake::raycast::RayCaster;
use radbake::trace::measure::{Meter, MeterSettings};
use radbake::util::sampling::Stream;
use radbake::{BakeConfig, Silent};

/// `local_light_at`'s estimate (one emitter sample and one cosine ray, MIS)
/// averaged over many draws is the emitter's irradiance / π at the point:
/// on the parallel plates, L × F(point → 1 m square 1 m above), Howell B-3
/// (`scenes/README.md`): 0.239456 under the centre, 0.138532 under a
/// corner.
#[test]
fn local_light_at_a_point_is_the_form_factor() {
    let scene = radbake::scene::load(&scene_path("parallel_plates.gltf"), &Default::default())
        .expect("scene loads");
    let config = BakeConfig {
        texels_per_meter: 8.0,
        final_gather: 0,
        emitters: EmitterSampling::Direct,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).expect("bake");
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let sampled = sampled_materials(&scene, &bake.geometry, config.emitters);
    let lights = Lights::new(&scene, &bake.geometry, &sampled, Vec3::ZERO);
    assert!(lights.has_local(), "the emitter plate is a local light");
    for (k, (p, want)) in [
        (Vec3::new(0.0, 0.0, 0.0), 0.239456),
        (Vec3::new(-0.5, 0.0, -0.5), 0.138532),
    ]
    .into_iter()
    .enumerate()
    {
        let mut rng = Stream::new(5, 0, k as u64);
        let n = 100_000;
        let (mut sum, mut sq) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let (h, cast) = local_light_at(&s, &lights, (p, Vec3::Y), &mut rng);
            assert!(cast <= 2, "a light sample and a cosine ray");
            let v = h.x as f64;
            sum += v;
            sq += v * v;
        }
        let mean = sum / n as f64;
        let se = ((sq / n as f64 - mean * mean) / (n as f64 - 1.0)).sqrt();
        assert!(
            (mean - want).abs() <= 4.0 * se && (mean / want - 1.0).abs() < 0.01,
            "at {p}: {mean:.6} ± {se:.6}, Howell {want}"
        );
    }
}

/// A grey wall and floor with a thin emissive box (3 × 1 m, 5 cm deep, open at the
/// back) against it, its front and its four side faces two nodes.
fn lamp_on_wall(name: &str) -> std::path::PathBuf {
    let mut g = GltfBuilder::default();
    let grey = g.material([0.7, 0.7, 0.7], [0.0; 3]);
    let lamp = g.material([0.8, 0.8, 0.8], [20.0, 16.0, 12.0]);
    let (wall, wi) = quad([-3.0, 0.0, 0.0], [6.0, 0.0, 0.0], [0.0, 4.0, 0.0]);
    let m = g.mesh(&wall, &wi, Some(grey));
    g.node("wall", m);
    let (floor, fli) = quad([-3.0, 0.0, 0.0], [0.0, 0.0, 4.0], [6.0, 0.0, 0.0]);
    let m = g.mesh(&floor, &fli, Some(grey));
    g.node("floor", m);
    let (x0, x1, y0, y1, d) = (-1.5, 1.5, 1.5, 2.5, 0.05);
    let (front, fi) = quad([x0, y0, d], [x1 - x0, 0.0, 0.0], [0.0, y1 - y0, 0.0]);
    let m = g.mesh(&front, &fi, Some(lamp));
    g.node("lamp_front", m);
    let sides = [
        quad([x0, y1, 0.0], [0.0, 0.0, d], [x1 - x0, 0.0, 0.0]), // top, +y
        quad([x0, y0, 0.0], [x1 - x0, 0.0, 0.0], [0.0, 0.0, d]), // bottom, −y
        quad([x1, y0, 0.0], [0.0, y1 - y0, 0.0], [0.0, 0.0, d]), // right, +x
        quad([x0, y0, 0.0], [0.0, 0.0, d], [0.0, y1 - y0, 0.0]), // left, −x
    ];
    let (mut p, mut idx) = (Vec::new(), Vec::new());
    for (qp, qi) in &sides {
        let base = p.len() as u32;
        p.extend_from_slice(qp);
        idx.extend(qi.iter().map(|i| i + base));
    }
    let m = g.mesh(&p, &idx, Some(lamp));
    g.node("lamp_sides", m);
    let path = temp_dir(name).join("lamp_on_wall.gltf");
    g.write(&path);
    path
}

/// The lamp's side faces against the meter, near field on (the default)
/// and off: on, within 5 %; off, more than 20 % low (their light comes
/// from the wall strip beside them, which a 25 cm texel's mean spreads
/// out).
#[test]
fn lamp_sides_match_the_meter_with_the_near_field() {
    let path = lamp_on_wall("near_field_lamp");
    let scene = radbake::scene::load(&path, &Default::default()).expect("scene loads");
    let reading = |node: &str| {
        let settings = MeterSettings {
            samples: 200_000,
            normal: Default::default(),
            sky: Vec3::ZERO,
            seed: 9,
        };
        let r = &Meter::new(&scene)
            .measure(&[node.to_string()], &settings)
            .unwrap()[0];
        (
            r.mean.iter().sum::<f64>() / 3.0,
            r.std_error.iter().sum::<f64>() / 3.0,
        )
    };
    let mean_of = |near_field: f32, node: &str| {
        // The lamp is 7 % of the surface: `auto` would send its light
        // through the radiosity solve (a level's lamps are far under 2 %).
        let config = BakeConfig {
            texels_per_meter: 4.0,
            gather_near_field: near_field,
            emitters: EmitterSampling::Direct,
            ..BakeConfig::default()
        };
        let bake = radbake::bake(&scene, &config, &Silent).expect("bake");
        let r = bake.instance_reports();
        let r = r.iter().find(|r| r.node == node).expect("node reported");
        r.mean.iter().sum::<f32>() as f64 / 3.0
    };
    let (want, se) = reading("lamp_sides");
    assert!(want > 0.1, "the side faces are lit by the wall ({want})");
    let on = mean_of(BakeConfig::default().gather_near_field, "lamp_sides");
    let off = mean_of(0.0, "lamp_sides");
    let err = |got: f64| got / want - 1.0;
    println!(
        "lamp sides: meter {want:.4} ± {se:.4}; near field on {on:.4} ({:+.1} %), off {off:.4} ({:+.1} %)",
        100.0 * err(on),
        100.0 * err(off)
    );
    assert!(err(on).abs() <= 0.05, "near field on: {on} vs {want}");
    assert!(err(off) < -0.2, "near field off reads low: {off} vs {want}");
    // The front faces the open half-space: no close hits, as before.
    let (front, front_se) = reading("lamp_front");
    let got = mean_of(1.0, "lamp_front");
    assert!(
        (got / front - 1.0).abs() <= 0.05 || (got - front).abs() <= 3.0 * front_se,
        "lamp front {got} vs meter {front} ± {front_se}"
    );
}
