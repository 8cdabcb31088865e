//! Lightmap quality at the texel level: the final gather against Howell's
//! point form factors, and light leaking through a shared wall.

mod common;

use common::*;
use radbake::form_factors::analytic;
use radbake::{BakeConfig, Silent};

/// Parallel plates, final gather on: every receiver texel within 4 cm of the
/// centre or of a corner reads Howell B-3 at its own position within 2 %
/// (0.23946 at the exact centre, 0.13853 at the exact corner).
#[test]
fn final_gather_matches_point_form_factors() {
    let scene =
        radbake::scene::load(&scene_path("parallel_plates.gltf"), &Default::default()).unwrap();
    // The final gather alone: the denoiser (tested below) trades a little
    // corner sharpness for noise, which is not what this measures.
    let cfg = BakeConfig {
        texels_per_meter: 58.0,
        final_gather: 4096,
        denoise: false,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let recv = scene
        .instances
        .iter()
        .position(|i| i.node == "receiver")
        .unwrap() as u32;
    let ids: Vec<usize> = (0..bake.texels.len())
        .filter(|&t| bake.texels.instance[t] == recv)
        .collect();
    // The plate's own corner, from its triangles.
    let min = (0..bake.geometry.len())
        .filter(|&g| bake.geometry.instance[g] == recv)
        .flat_map(|g| bake.geometry.p_ws[g])
        .fold(glam::Vec3::splat(f32::INFINITY), |a, b| a.min(b));
    let (mut centre, mut corner, mut worst) = (0, 0, 0.0f64);
    for &t in &ids {
        // Full texels only: a partly covered edge texel's value is its covered part's mean.
        if bake.texels.area[t] < 0.99 / (58.0 * 58.0) {
            continue;
        }
        let p = bake.texels.p_ws[t] - min;
        let (x, z) = (p.x as f64, p.z as f64);
        let want = analytic::point_to_rectangle(x, z, 1.0, 1.0, 1.0);
        let got = bake.lightmaps.texel_values[t].x as f64;
        let near_centre = (x - 0.5).abs() < 0.04 && (z - 0.5).abs() < 0.04;
        let near_corner = x < 0.04 && z < 0.04;
        if near_centre || near_corner {
            assert!(
                (got - want).abs() / want < 0.02,
                "texel at ({x:.3}, {z:.3}): {got} vs Howell {want}"
            );
            worst = worst.max((got - want).abs() / want);
            if near_centre {
                centre += 1;
            } else {
                corner += 1;
            }
        }
    }
    eprintln!(
        "{centre} centre and {corner} corner texels, worst error {:.3} %",
        100.0 * worst
    );
    assert!(
        centre > 10 && corner > 3,
        "{centre} centre and {corner} corner texels checked"
    );
}

/// Two closed rooms side by side sharing a 0.2 m wall; one floor quad and
/// one ceiling quad run under/over the wall through both rooms (the case
/// that leaks in naive bakers). A lamp lights room A only. Room B is sealed,
/// so physics gives exactly 0 there: every room-B floor texel, including the
/// row along the shared wall, must read 0 (we assert < 1e-6 of room A's mean).
#[test]
fn no_light_leaks_through_a_shared_wall() {
    let dir = temp_dir("leak");
    let mut b = GltfBuilder::default();
    let white = b.material([0.8; 3], [0.0; 3]);
    let lamp = b.material([0.8; 3], [20.0; 3]);
    let (w, h, d) = (4.2f32, 2.0f32, 2.0f32);
    let mut add = |name: &str, o: [f32; 3], u: [f32; 3], v: [f32; 3], m: usize| {
        let (p, i) = quad(o, u, v);
        let mesh = b.mesh(&p, &i, Some(m));
        b.node(name, mesh);
    };
    add(
        "floor",
        [0.0, 0.0, 0.0],
        [0.0, 0.0, d],
        [w, 0.0, 0.0],
        white,
    ); // +y
    add(
        "ceiling",
        [0.0, h, 0.0],
        [w, 0.0, 0.0],
        [0.0, 0.0, d],
        white,
    ); // −y
    add("back", [0.0, 0.0, 0.0], [w, 0.0, 0.0], [0.0, h, 0.0], white); // +z
    add("front", [0.0, 0.0, d], [0.0, h, 0.0], [w, 0.0, 0.0], white); // −z
    add("left", [0.0, 0.0, 0.0], [0.0, h, 0.0], [0.0, 0.0, d], white); // +x
    add("right", [w, 0.0, 0.0], [0.0, 0.0, d], [0.0, h, 0.0], white); // −x
    add(
        "wall_a",
        [2.0, 0.0, 0.0],
        [0.0, 0.0, d],
        [0.0, h, 0.0],
        white,
    ); // −x, faces room A
    add(
        "wall_b",
        [2.2, 0.0, 0.0],
        [0.0, h, 0.0],
        [0.0, 0.0, d],
        white,
    ); // +x, faces room B
    add(
        "lamp",
        [0.8, h - 0.001, 0.8],
        [0.4, 0.0, 0.0],
        [0.0, 0.0, 0.4],
        lamp,
    ); // −y, room A
    let path = dir.join("rooms.gltf");
    b.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 40.0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let floor = scene
        .instances
        .iter()
        .position(|i| i.node == "floor")
        .unwrap() as u32;
    let (mut a_sum, mut a_n, mut b_max, mut b_n, mut fringe) = (0.0f64, 0, 0.0f32, 0, 0);
    for t in 0..bake.texels.len() {
        if bake.texels.instance[t] != floor {
            continue;
        }
        let x = bake.texels.p_ws[t].x;
        let v = bake.lightmaps.texel_values[t].max_element();
        if x < 2.0 {
            a_sum += v as f64;
            a_n += 1;
        } else if x > 2.2 {
            b_max = b_max.max(v);
            b_n += 1;
            if x < 2.3 {
                fringe += 1;
            }
        }
    }
    let a_mean = a_sum / a_n as f64;
    assert!(a_mean > 0.1, "room A is lit: {a_mean}");
    assert!(b_n > 1000 && fringe > 50);
    eprintln!("room A floor mean {a_mean:.4}, room B floor max {b_max:e}");
    assert!(
        (b_max as f64) < 1e-6 * a_mean,
        "light leaks into room B: max {b_max} (room A mean {a_mean})"
    );
    assert!(
        bake.invalid_texels > 0,
        "the floor under the wall should be found invalid"
    );
}

/// UV seams on continuous surfaces: a UV sphere (seams inside one mesh) and
/// two floor tiles meeting edge to edge (a seam between meshes), lit by a
/// point light. Stitching must cut the mean difference of bilinear samples
/// across the seams to a fifth or less.
#[test]
fn seams_are_stitched() {
    let dir = temp_dir("seams");
    let mut b = GltfBuilder::default();
    let white = b.material([0.7; 3], [0.0; 3]);
    let (p, i) = sphere(0.5, 16, 32, false);
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0], v[1] + 1.0, v[2]]).collect();
    let m = b.mesh(&p, &i, Some(white));
    b.node("sphere", m);
    let (p, i) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(white));
    b.node("tile_a", m);
    let (p, i) = quad([0.0, 0.0, -2.0], [0.0, 0.0, 4.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(white));
    b.node("tile_b", m);
    let mut doc = b.json();
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 30.0}]}});
    doc["nodes"].as_array_mut().unwrap().push(serde_json::json!({"name": "lamp", "translation": [0.7, 2.5, 0.4], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    doc["scenes"][0]["nodes"] = serde_json::json!([0, 1, 2, 3]);
    let path = dir.join("seams.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 32.0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let [before, after] = bake.seam_mismatch;
    eprintln!(
        "{} seam samples: mismatch {before:.5} before, {after:.5} after",
        bake.seam_samples
    );
    assert!(bake.seam_samples > 100);
    assert!(
        before > 0.0 && after < 0.2 * before,
        "before {before}, after {after}"
    );
    let unstitched = radbake::bake(
        &scene,
        &BakeConfig {
            stitch_seams: false,
            ..cfg
        },
        &Silent,
    )
    .unwrap();
    assert_eq!(unstitched.seam_samples, 0);
}

/// The denoiser lowers the error of a noisy (32-ray) final gather against a
/// high-sample reference on the Cornell box (RMSE over every texel).
#[test]
fn denoising_reduces_error() {
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let base = BakeConfig {
        texels_per_meter: 40.0,
        ..BakeConfig::default()
    };
    let reference = radbake::bake(
        &scene,
        &BakeConfig {
            final_gather: 2048,
            direct_samples: 512,
            denoise: false,
            ..base.clone()
        },
        &Silent,
    )
    .unwrap();
    let rmse = |denoise: bool| {
        let b = radbake::bake(
            &scene,
            &BakeConfig {
                final_gather: 32,
                denoise,
                ..base.clone()
            },
            &Silent,
        )
        .unwrap();
        let se: f64 = b
            .lightmaps
            .texel_values
            .iter()
            .zip(&reference.lightmaps.texel_values)
            .map(|(a, r)| ((*a - *r).length_squared() / 3.0) as f64)
            .sum();
        (se / b.lightmaps.texel_values.len() as f64).sqrt()
    };
    let (noisy, denoised) = (rmse(false), rmse(true));
    eprintln!("RMSE: {noisy:.5} noisy, {denoised:.5} denoised");
    assert!(denoised < 0.8 * noisy, "noisy {noisy}, denoised {denoised}");
}
