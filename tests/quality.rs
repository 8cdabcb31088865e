//! Lightmap quality at the texel level: the final gather against Howell's
//! point form factors, and light leaking through a shared wall.

mod common;

use common::*;
use radbake::radiosity::form_factors::analytic;
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
        let got = bake.maps.lightmaps.texel_values[t].x as f64;
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
        let v = bake.maps.lightmaps.texel_values[t].max_element();
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
        bake.maps.invalid_texels > 0,
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
    let [before, after] = bake.maps.seam_mismatch;
    eprintln!(
        "{} seam samples: mismatch {before:.5} before, {after:.5} after",
        bake.maps.seam_samples
    );
    assert!(bake.maps.seam_samples > 100);
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
    assert_eq!(unstitched.maps.seam_samples, 0);
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
            .maps
            .lightmaps
            .texel_values
            .iter()
            .zip(&reference.maps.lightmaps.texel_values)
            .map(|(a, r)| ((*a - *r).length_squared() / 3.0) as f64)
            .sum();
        (se / b.maps.lightmaps.texel_values.len() as f64).sqrt()
    };
    let (noisy, denoised) = (rmse(false), rmse(true));
    eprintln!("RMSE: {noisy:.5} noisy, {denoised:.5} denoised");
    assert!(denoised < 0.8 * noisy, "noisy {noisy}, denoised {denoised}");
}

/// The denoiser covers the direct light that the gather's rays estimate:
/// a plate 0.4 m over a floor under a uniform sky, no other light, so the
/// floor's soft sky shadow is the cosine rays' (and the sky's light
/// samples'). At 32 gather rays (16 direct samples, so the gather's rays
/// are the direct light's hemisphere samples), the lightmap's RMSE
/// against a 2048-ray reference drops below 0.6 × the unfiltered one, and
/// every instance's texel mean stays within 0.5 % of the reference's.
#[test]
fn denoising_covers_the_sky_light() {
    let scene = plate_over_floor("denoise-sky");
    let base = BakeConfig {
        sky: [0.4, 0.5, 0.7],
        texels_per_meter: 32.0,
        direct_samples: 16,
        ..BakeConfig::default()
    };
    let bake = |final_gather, denoise| {
        let config = BakeConfig {
            final_gather,
            denoise,
            ..base.clone()
        };
        radbake::bake(&scene, &config, &Silent).unwrap()
    };
    let reference = bake(2048, false);
    let rmse = |b: &radbake::Bake| {
        let (mut se, mut n) = (0.0f64, 0usize);
        for (t, (a, r)) in b
            .maps
            .lightmaps
            .texel_values
            .iter()
            .zip(&reference.maps.lightmaps.texel_values)
            .enumerate()
        {
            if b.transport.valid[t] && reference.transport.valid[t] {
                se += ((*a - *r).length_squared() / 3.0) as f64;
                n += 1;
            }
        }
        (se / n as f64).sqrt()
    };
    let (noisy, denoised) = (bake(32, false), bake(32, true));
    let (e_noisy, e_denoised) = (rmse(&noisy), rmse(&denoised));
    eprintln!("sky: RMSE {e_noisy:.5} noisy, {e_denoised:.5} denoised");
    assert!(
        e_denoised < 0.6 * e_noisy,
        "noisy {e_noisy}, denoised {e_denoised}"
    );
    let want = texel_means(&reference, &reference.maps.lightmaps.texel_values);
    let got = texel_means(&denoised, &denoised.maps.lightmaps.texel_values);
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let node = &scene.instances[i].node;
        eprintln!("{node}: {g:.5} against {w:.5}");
        assert!((g - w).abs() / w < 0.005, "{node}: {g} vs {w}");
    }
}

/// A ground plane (albedo 0) under a uniform sky L: irradiance / π on a
/// plane tilted by θ is L (1 + cos θ) / 2, which the L1 model a + n · b
/// holds exactly: a = L/2, b = (0, L/2, 0). Checked per texel within 3 %
/// (b_x, b_z within 3 % of L).
#[test]
fn directional_lightmaps_under_a_sky() {
    let dir = temp_dir("sh");
    let mut b = GltfBuilder::default();
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("ground", m);
    let path = dir.join("ground.gltf");
    b.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let sky = 0.8f32;
    let cfg = BakeConfig {
        texels_per_meter: 16.0,
        sky: [sky; 3],
        final_gather: 1024,
        directional: radbake::config::DirectionalMode::Sh,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let sh = bake.maps.sh.as_ref().expect("directional maps");
    let mut checked = 0;
    for t in 0..bake.texels.len() {
        let [x, y] = bake.texels.xy[t];
        let at =
            |lm: &radbake::maps::lightmap::Lightmaps| lm.pages[0][(y * lm.width + x) as usize].x;
        let (a, bx, by, bz) = (at(&sh[0]), at(&sh[1]), at(&sh[2]), at(&sh[3]));
        assert!((a - sky / 2.0).abs() < 0.03 * sky, "a = {a}");
        assert!((by - sky / 2.0).abs() < 0.03 * sky, "b_y = {by}");
        assert!(
            bx.abs() < 0.03 * sky && bz.abs() < 0.03 * sky,
            "b_x = {bx}, b_z = {bz}"
        );
        // A normal tilted 60° towards +x: L (1 + cos 60°) / 2.
        let n = glam::Vec3::new(60f32.to_radians().sin(), 60f32.to_radians().cos(), 0.0);
        let h = a + n.x * bx + n.y * by + n.z * bz;
        assert!((h - sky * 0.75).abs() < 0.03 * sky, "H(60°) = {h}");
        checked += 1;
    }
    assert!(checked > 500);
}

/// AO: a floor under a wider plate 0.5 m above it is open (1) for an AO
/// distance of 0.25 m and mostly occluded for 2 m.
#[test]
fn ambient_occlusion() {
    let dir = temp_dir("ao");
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([-0.5, 0.0, -0.5], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([-3.0, 0.5, -3.0], [6.0, 0.0, 0.0], [0.0, 0.0, 6.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("roof", m);
    let path = dir.join("ao.gltf");
    b.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let floor = 0u32;
    let mean_ao = |distance: f32| {
        let cfg = BakeConfig {
            texels_per_meter: 16.0,
            ao_distance: distance,
            ..BakeConfig::default()
        };
        let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
        let ao = bake.maps.ao.as_ref().expect("AO pages");
        let ids: Vec<usize> = (0..bake.texels.len())
            .filter(|&t| bake.texels.instance[t] == floor)
            .collect();
        ids.iter()
            .map(|&t| {
                let [x, y] = bake.texels.xy[t];
                ao.pages[0][(y * ao.width + x) as usize].x
            })
            .sum::<f32>()
            / ids.len() as f32
    };
    let near = mean_ao(0.25);
    let far = mean_ao(2.0);
    assert!(near > 0.999, "nothing within 0.25 m: {near}");
    // Open fraction within 2 m under a 6 m roof at 0.5 m: the cosine-weighted
    // share of directions below ~14° elevation that miss the roof edge, a few %.
    assert!(far < 0.1, "roof within 2 m: {far}");
}

/// Supersampling antialiases punctual shadow edges: a directional light and
/// a half-plane occluder give binary texels at 1 sample (but where the
/// quad's diagonal crosses the edge) and a band of partly lit texels at
/// 4 × 4.
#[test]
fn supersampling_antialiases_shadow_edges() {
    let dir = temp_dir("supersample");
    let mut b = GltfBuilder::default();
    let grey = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    // Occluder over x < 0.03 (not aligned with texel edges), facing down.
    let (p, i) = quad([-3.0, 1.0, -3.0], [3.03, 0.0, 0.0], [0.0, 0.0, 6.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("blocker", m);
    let mut doc = b.json();
    add_vertical_sun(&mut doc, 3.0);
    let path = dir.join("edge.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let partial = |s: u32| {
        let cfg = BakeConfig {
            texels_per_meter: 20.0,
            supersample: s,
            ..BakeConfig::default()
        };
        let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
        let lit = 3.0 / std::f32::consts::PI;
        (0..bake.texels.len())
            .filter(|&t| bake.texels.instance[t] == 0)
            .filter(|&t| {
                let f = bake.maps.lightmaps.texel_values[t].x / lit;
                f > 0.05 && f < 0.95
            })
            .count()
    };
    let (one, four) = (partial(1), partial(4));
    // One sample: one shadow ray per piece, so only a texel whose two
    // triangles (the quad's diagonal) fall on both sides of the edge is
    // partly lit.
    assert!(
        one <= 2,
        "{one} partly lit texels with one sample per piece"
    );
    assert!(
        four >= 30,
        "only {four} partly lit texels along a 2 m edge at 20 texels/m"
    );
}

/// A 0.2 m emitter 10 cm under a receiver facing it (regression: shadow
/// rays offset at their origin only hit the emitter's own triangle at
/// distances under ~15 cm, and close lamps lit nothing). Texels within 3 cm
/// of the centre read E × the point-to-rectangle view factor (before the
/// fix they read 0), for the radiosity bake and the path-traced reference.
#[test]
fn close_emitter_lights_its_neighbour() {
    let mut b = GltfBuilder::default();
    let lamp = b.material([0.0; 3], [1.0; 3]);
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 0.2], [0.2, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(lamp));
    b.node("lamp", m);
    let (p, i) = quad([-0.2, 0.1, -0.2], [0.6, 0.0, 0.0], [0.0, 0.0, 0.6]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("receiver", m);
    let dir = temp_dir("close-emitter");
    let path = dir.join("close.gltf");
    b.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let recv = scene
        .instances
        .iter()
        .position(|i| i.node == "receiver")
        .unwrap() as u32;
    for method in [
        radbake::config::Method::Radiosity,
        radbake::config::Method::Pathtrace,
    ] {
        let cfg = BakeConfig {
            texels_per_meter: 100.0,
            method,
            path_samples: 1024,
            direct_samples: 1024,
            // Sampled as a light (it is 10 % of the surface: `auto` would
            // send it through the solve).
            emitters: radbake::config::EmitterSampling::Direct,
            ..BakeConfig::default()
        };
        let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
        // Per texel: 2 % for radiosity; 6 % for the path tracer, whose
        // texels have a 1.5 % standard error at 1024 paths (its mean over
        // the checked texels must still be within 1.5 %).
        let tolerance = if method == radbake::config::Method::Radiosity {
            0.02
        } else {
            0.06
        };
        let (mut checked, mut ratio) = (0, 0.0f64);
        for t in 0..bake.texels.len() {
            if bake.texels.instance[t] != recv {
                continue;
            }
            let p = bake.texels.p_ws[t];
            if (p.x - 0.1).abs() > 0.03 || (p.z - 0.1).abs() > 0.03 {
                continue;
            }
            let want = analytic::point_to_rectangle(p.x as f64, p.z as f64, 0.2, 0.2, 0.1);
            let got = bake.maps.lightmaps.texel_values[t].x as f64;
            ratio += got / want;
            assert!(
                (got - want).abs() / want < tolerance,
                "{method:?}: texel at ({:.3}, {:.3}): {got} vs {want}",
                p.x,
                p.z
            );
            checked += 1;
        }
        assert!(checked > 10, "{checked} texels checked");
        let ratio = ratio / checked as f64;
        assert!(
            (ratio - 1.0).abs() < 0.015,
            "{method:?}: mean ratio {ratio}"
        );
    }
}

/// A 2 m floor and a 0.6 m plate 0.4 m over its centre (albedo 0.5),
/// written to a fresh folder `name` and loaded.
fn plate_over_floor(name: &str) -> radbake::scene::Scene {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([-0.3, 0.4, -0.3], [0.6, 0.0, 0.0], [0.0, 0.0, 0.6]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("plate", m);
    let path = temp_dir(name).join("sky.gltf");
    b.write(&path);
    radbake::scene::load(&path, &Default::default()).unwrap()
}

/// Per instance, the texel mean of the direct light (valid texels only).
fn direct_means(bake: &radbake::Bake) -> Vec<f64> {
    texel_means(bake, &bake.transport.direct)
}

/// Per instance, the texel mean of `values` over its valid texels.
fn texel_means(bake: &radbake::Bake, values: &[glam::Vec3]) -> Vec<f64> {
    let n = bake.scene.instances.len();
    let (mut sum, mut count) = (vec![0.0f64; n], vec![0u32; n]);
    for (t, v) in values.iter().enumerate() {
        if bake.transport.valid[t] {
            let i = bake.texels.instance[t] as usize;
            sum[i] += v.element_sum() as f64 / 3.0;
            count[i] += 1;
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| s / c.max(1) as f64)
        .collect()
}

/// The final gather's rays double as the direct light's hemisphere samples
/// (sky, and emitters by MIS) when the gather casts at least as many rays
/// as there are light samples. Its direct light must be the direct pass's
/// own: per instance, means within 1 % of a bake that gathers fewer rays
/// (so the direct pass casts all its hemisphere rays itself), on the
/// Cornell box (its lamp sampled) and on a plate shading a floor from a sky;
/// and the plate's sky light within 1 % of the analytic value in both.
/// (Regression: the direct pass paired texel positions with direction
/// strata in reverse order, which is biased: the plate read 4.7 % low.)
#[test]
fn gather_rays_give_the_same_direct_light() {
    let sky = plate_over_floor("shared-direct");
    let cornell =
        radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    for (scene, sky_radiance) in [(&cornell, [0.0; 3]), (&sky, [0.4, 0.5, 0.7])] {
        let shared = BakeConfig {
            sky: sky_radiance,
            texels_per_meter: 32.0,
            direct_samples: 64,
            final_gather: 256,
            ..BakeConfig::default()
        };
        let own = BakeConfig {
            final_gather: 32,
            ..shared.clone()
        };
        let a = radbake::bake(scene, &shared, &Silent).unwrap();
        let b = radbake::bake(scene, &own, &Silent).unwrap();
        assert!(
            a.transport.rays.direct < b.transport.rays.direct,
            "the direct pass cast as many rays"
        );
        for (i, (x, y)) in direct_means(&a).iter().zip(direct_means(&b)).enumerate() {
            let node = &scene.instances[i].node;
            if y > 1e-3 {
                assert!((x - y).abs() / y < 0.01, "{node}: {x} vs {y}");
            }
        }
        if sky_radiance[0] > 0.0 {
            // The plate sees the sky past the floor: D = L_sky (1 − F), F its
            // point form factor to the floor (B-3; the floor is [−1, 1]² at
            // 0.4 m), texel by texel.
            let plate = scene
                .instances
                .iter()
                .position(|i| i.node == "plate")
                .unwrap();
            let l_sky = sky_radiance.iter().sum::<f32>() as f64 / 3.0;
            for bake in [&a, &b] {
                let (mut got, mut want, mut count) = (0.0, 0.0, 0);
                for t in 0..bake.texels.len() {
                    if bake.texels.instance[t] as usize == plate && bake.transport.valid[t] {
                        let p = bake.texels.p_ws[t];
                        let f = analytic::point_to_rectangle(
                            p.x as f64 + 1.0,
                            p.z as f64 + 1.0,
                            2.0,
                            2.0,
                            0.4,
                        );
                        want += l_sky * (1.0 - f);
                        got += bake.transport.direct[t].element_sum() as f64 / 3.0;
                        count += 1;
                    }
                }
                let (got, want) = (got / count as f64, want / count as f64);
                assert!((got - want).abs() / want < 0.01, "plate: {got} vs {want}");
            }
        }
    }
}

/// Texels far from the atlas origin are placed where their surface is
/// (regression: the clip's shoelace ran on absolute atlas coordinates in
/// f32, and at coordinates in the hundreds its rounding error was a good
/// part of a texel's area: Sponza's texels got centroids up to 150 m off
/// their surfaces, lit by the sun there, and areas that no longer summed to
/// the surface's). A 30 m × 30 m floor in 200 triangles at 25 texels/m is
/// one 750-texel-wide chart: every texel centroid must lie on the floor,
/// within its texel's reach of the triangle it came from, no texel may hold
/// more than a texel's area, its pieces must add up to it and lie on their
/// triangles, and the areas must sum to 900 m².
#[test]
fn texels_far_from_the_atlas_origin() {
    let dir = temp_dir("far-texels");
    let mut b = GltfBuilder::default();
    let (cells, size) = (10u32, 30.0f32);
    let mut p = Vec::new();
    let mut i = Vec::new();
    for z in 0..=cells {
        for x in 0..=cells {
            let s = size / cells as f32;
            p.push([x as f32 * s - size / 2.0, 0.0, z as f32 * s - size / 2.0]);
        }
    }
    for z in 0..cells {
        for x in 0..cells {
            let k = z * (cells + 1) + x;
            i.extend([k, k + cells + 1, k + 1, k + 1, k + cells + 1, k + cells + 2]);
        }
    }
    let grey = b.material([0.5; 3], [0.0; 3]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let path = dir.join("floor.gltf");
    b.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let density = 25.0;
    let config = BakeConfig {
        texels_per_meter: density,
        ..BakeConfig::default()
    };
    let atlas = radbake::layout::atlas::unwrap(&scene, &config).unwrap();
    assert!(
        atlas.width.max(atlas.height) >= 700,
        "{}×{}",
        atlas.width,
        atlas.height
    );
    let geometry = radbake::layout::geometry::Geometry::new(&scene, &atlas);
    let texels = radbake::layout::texels::rasterize(&scene, &atlas, &geometry);
    let full = 1.0 / (density * density);
    let reach = 1.5 / density;
    let mut total = 0.0f64;
    for t in 0..texels.len() {
        let q = texels.p_ws[t];
        assert!(
            q.y.abs() < 1e-4 && q.x.abs() <= 15.0 + 1e-3 && q.z.abs() <= 15.0 + 1e-3,
            "texel {t} at {q}"
        );
        let tri = geometry.p_ws[texels.triangle[t] as usize];
        let c = (tri[0] + tri[1] + tri[2]) / 3.0;
        let r = tri.iter().map(|v| v.distance(c)).fold(0.0f32, f32::max);
        assert!(
            q.distance(c) <= r + reach,
            "texel {t} at {q}, its triangle around {c}"
        );
        assert!(
            texels.area[t] <= full * 1.001,
            "texel {t}: area {} > {full}",
            texels.area[t]
        );
        // Its pieces (one per covering triangle) add up to it and lie on
        // their triangles.
        let pieces = texels.pieces_of(t);
        let sum: f32 = pieces.iter().map(|p| p.area).sum();
        assert!(
            (sum - texels.area[t]).abs() <= 1e-5 * texels.area[t],
            "texel {t}: pieces {sum}"
        );
        for piece in pieces {
            assert!(piece.u >= -1e-4 && piece.v >= -1e-4 && piece.u + piece.v <= 1.0 + 1e-4);
            assert!(geometry.point(piece.tri, piece.u, piece.v).y.abs() < 1e-4);
        }
        total += texels.area[t] as f64;
    }
    assert!(
        (total - 900.0).abs() < 0.01,
        "texel areas sum to {total} m²"
    );
}

/// A corrugated sheet under a vertical sun, its waves (sine profile, 10 cm
/// apart, 2.5 cm deep, 8 facets each) finer than its 25 cm texels and one
/// chart: the sun's irradiance / π over the sheet is E × (projected area /
/// surface area) / π. Regression: the sun was sampled at a texel's world
/// centroid, which for a texel spanning a wave lies off the sheet, under a
/// crest in the sheet's own shadow (Sponza's tiled roof read 5 % dark
/// against the path tracer), and then at one facet's point and normal,
/// which favours the longer, steeper facets (7 % dark). Measured: summing
/// over the texel's pieces gives the answer to 10⁻⁶; tolerance 0.5 %.
#[test]
fn sun_on_a_corrugated_sheet() {
    let dir = temp_dir("corrugated");
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (period, depth, length, waves, facets) = (0.1f32, 0.025f32, 2.0f32, 20u32, 8u32);
    let mut p = Vec::new();
    let mut i = Vec::new();
    let n = waves * facets;
    for k in 0..=n {
        let x = k as f32 * period / facets as f32 - 1.0;
        let phase = 2.0 * std::f32::consts::PI * (k % facets) as f32 / facets as f32;
        let y = 0.5 * depth * (1.0 - phase.cos());
        p.push([x, y, -length / 2.0]);
        p.push([x, y, length / 2.0]);
    }
    for k in 0..n {
        let a = 2 * k;
        i.extend([a, a + 1, a + 2, a + 2, a + 1, a + 3]);
    }
    // Surface area over projected area (2 m × 2 m).
    let surface: f32 = (0..n as usize)
        .map(|k| {
            let (a, c) = (p[2 * k], p[2 * k + 2]);
            (c[0] - a[0]).hypot(c[1] - a[1]) * length
        })
        .sum();
    let m = b.mesh(&p, &i, Some(grey));
    b.node("sheet", m);
    let mut doc = b.json();
    let e = 2.0f32;
    add_vertical_sun(&mut doc, e);
    let path = dir.join("sheet.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 4.0,
        final_gather: 0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let want = e * (length * length / surface) / std::f32::consts::PI;
    let d = &bake.transport.direct;
    let area: f32 = bake.texels.area.iter().sum();
    let mean = d
        .iter()
        .zip(&bake.texels.area)
        .map(|(v, a)| v.x * a)
        .sum::<f32>()
        / area;
    eprintln!(
        "charts {}, texels {}, mean {mean}, want {want}",
        bake.atlas.chart_count,
        d.len()
    );
    assert!(
        (mean - want).abs() / want < 0.005,
        "mean direct {mean} vs E (projected / surface area) / π = {want}"
    );
}

/// The final gather with light samples towards the solved patches (NEE,
/// MIS with the cosine rays, `gather_nee`) and without agree in
/// expectation: every instance's mean within 1 %, on the Cornell box and
/// on a floor shadowed by a plate under a sky (its light under the plate
/// is bounced). Both bakes cast the same cosine rays; the NEE bake must
/// also have cast its light samples.
#[test]
fn light_samples_leave_the_gather_unbiased() {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.7; 3], [0.0; 3]);
    let (p, i) = quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    // Facing down: the floor under it is lit by the plate's underside,
    // which the sky-lit floor lights.
    let (p, i) = quad([-0.5, 0.3, -0.5], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("plate", m);
    let dir = temp_dir("nee-unbiased");
    let path = dir.join("plate.gltf");
    b.write(&path);
    let plate = radbake::scene::load(&path, &Default::default()).unwrap();
    let cornell =
        radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    for (scene, sky, density) in [(&cornell, [0.0; 3], 116.0), (&plate, [0.4, 0.5, 0.7], 32.0)] {
        let plain = BakeConfig {
            sky,
            texels_per_meter: density,
            final_gather: 512,
            gather_threshold: 0.0,
            denoise: false,
            ..BakeConfig::default()
        };
        let nee = BakeConfig {
            gather_nee: true,
            ..plain.clone()
        };
        let a = radbake::bake(scene, &plain, &Silent).unwrap();
        let b = radbake::bake(scene, &nee, &Silent).unwrap();
        assert!(
            b.transport.rays.gather > a.transport.rays.gather,
            "{}: no light samples were cast",
            scene.instances[0].node
        );
        let (mb, ma) = (
            texel_means(&b, &b.transport.values),
            texel_means(&a, &a.transport.values),
        );
        for (i, (x, y)) in mb.iter().zip(ma).enumerate() {
            let node = &scene.instances[i].node;
            if y > 1e-3 {
                assert!((x - y).abs() / y < 0.01, "{node}: NEE {x} vs plain {y}");
            }
        }
    }
}

/// The gather's own variance estimate (`TexelLight::variance`) predicts
/// how far an instance's mean may be from a bake with 8 × the rays: the
/// Cornell box with the same seed (so every stage before the gather is
/// the same), every ray cast, no denoising. Each instance's difference
/// over its standard error √(Σ a² (var₆₄ + var₅₁₂)) / Σ a stays within 4
/// and the z-scores' RMS within 2: a variance estimate that was too
/// small, or a gather whose mean moved with its ray count, fails it.
/// (On Sponza the RMS is 0.64; the stratified nets beat the independent
/// rays the estimate assumes.)
#[test]
fn gather_variance_predicts_the_instances_spread() {
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let cfg = |rays: u32| BakeConfig {
        final_gather: rays,
        gather_threshold: 0.0,
        denoise: false,
        ..BakeConfig::default()
    };
    let (a, b) = (
        radbake::bake(&scene, &cfg(64), &Silent).unwrap(),
        radbake::bake(&scene, &cfg(512), &Silent).unwrap(),
    );
    let n = a.texels.len();
    assert_eq!(a.transport.variance.len(), n);
    assert!(a.transport.variance.iter().any(|&v| v > 0.0));
    let lum = |v: glam::Vec3| v.element_sum() as f64 / 3.0;
    // Per instance: Σ a·x, Σ a·y, Σ a, Σ a² (var_x + var_y).
    let mut sums = vec![[0.0f64; 4]; scene.instances.len()];
    for t in (0..n).filter(|&t| a.transport.valid[t] && b.transport.valid[t]) {
        let s = &mut sums[a.texels.instance[t] as usize];
        let w = a.texels.area[t] as f64;
        s[0] += w * lum(a.transport.values[t]);
        s[1] += w * lum(b.transport.values[t]);
        s[2] += w;
        s[3] += w * w * (a.transport.variance[t] + b.transport.variance[t]) as f64;
    }
    let mut z_sq = Vec::new();
    for (k, [x, y, area, var]) in sums.into_iter().enumerate() {
        if area <= 0.0 || y <= 0.0 {
            continue;
        }
        let z = (x - y) / var.sqrt();
        let node = &scene.instances[k].node;
        assert!(
            z.abs() < 4.0,
            "{node}: 64 rays {:.5}, 512 rays {:.5}: {z:.2} standard errors",
            x / area,
            y / area
        );
        z_sq.push(z * z);
    }
    let rms = (z_sq.iter().sum::<f64>() / z_sq.len() as f64).sqrt();
    assert!(z_sq.len() >= 6, "{} instances compared", z_sq.len());
    assert!(rms < 2.0, "RMS of the z-scores {rms:.2}");
    println!("{} instances, RMS z {rms:.2}", z_sq.len());
}
