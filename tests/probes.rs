//! Light probes against exact answers (furnace, open sky over a ground
//! square with a sun, a closed block), against the path tracer (Cornell),
//! and the written Bevy volume read back by an independent KTX2 reader and
//! sampled with Bevy 0.19's own formula.

mod common;

use common::{quad, scene_path, temp_dir, GltfBuilder};
use glam::Vec3;
use radbake::config::BakeConfig;
use radbake::pipeline::progress::Silent;
use radbake::probes::sh;
use radbake::util::sampling::Stream;
use std::f32::consts::PI;

/// Decodes RGB9E5 as the Vulkan specification defines it (written here
/// again, not taken from the encoder).
fn rgb9e5_decode(p: u32) -> Vec3 {
    let scale = 2f32.powi((p >> 27) as i32 - 15 - 9);
    Vec3::new(
        (p & 0x1ff) as f32,
        ((p >> 9) & 0x1ff) as f32,
        ((p >> 18) & 0x1ff) as f32,
    ) * scale
}

/// A volume file read back with the `ktx2` crate: (width, height, depth)
/// and the decoded texels.
fn read_volume(path: &std::path::Path) -> ([u32; 3], Vec<Vec3>) {
    let bytes = std::fs::read(path).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).expect("a valid KTX2 file");
    let h = reader.header();
    assert_eq!(h.format, Some(ktx2::Format::E5B9G9R9_UFLOAT_PACK32));
    assert_eq!(h.level_count, 1);
    let size = [h.pixel_width, h.pixel_height, h.pixel_depth];
    let level = reader.levels().next().unwrap();
    let texels = level
        .data
        .chunks_exact(4)
        .map(|c| rgb9e5_decode(u32::from_le_bytes(c.try_into().unwrap())))
        .collect();
    (size, texels)
}

fn bake_to(
    path: &std::path::Path,
    config: &BakeConfig,
    out: &std::path::Path,
) -> radbake::Bake<'static> {
    let scene = Box::leak(Box::new(
        radbake::scene::load(path, &Default::default()).unwrap(),
    ));
    let bake = radbake::bake(scene, config, &Silent).unwrap();
    radbake::output::write_engine_outputs(out, "scene", &bake).unwrap();
    bake
}

/// Inside the furnace box every direction sees radiance 2.0: every
/// ambient-cube face of the written volume is 2.0 within 1 %.
#[test]
fn furnace_volume_reads_two_everywhere() {
    let out = temp_dir("probes-furnace");
    let config = BakeConfig {
        probe_spacing: 0.25,
        ..BakeConfig::default()
    };
    let bake = bake_to(&scene_path("furnace_box.gltf"), &config, &out);
    let probes = bake.probes.as_ref().unwrap();
    assert!(probes.len() >= 27, "{} probes", probes.len());
    assert_eq!(probes.invalid(), 0);
    let (size, texels) = read_volume(&out.join("probes_0.ktx2"));
    let r = probes.volumes[0].resolution;
    assert_eq!(size, [r.x, 2 * r.y, 3 * r.z]);
    let worst = texels
        .iter()
        .map(|t| (*t - Vec3::splat(2.0)).abs().max_element())
        .fold(0.0f32, f32::max);
    eprintln!(
        "furnace: {} probes, worst face error {worst:.4}",
        probes.len()
    );
    assert!(worst < 0.02, "worst face {worst}");
    // probes.json and probes.bin read back as written.
    let back = radbake::probes::Probes::read(&out.join("probes.json")).unwrap();
    assert_eq!(back.volumes, probes.volumes);
    assert_eq!(back.sh, probes.sh);
    assert_eq!(back.valid, probes.valid);
}

use common::ground::{A, H, RHO, SKY, SUN};

/// The sunlit ground with its probe (see [`common::sunlit_ground`]).
fn sky_scene(to_sun: Vec3) -> std::path::PathBuf {
    common::sunlit_ground("probes-sky", to_sun, true, None)
}

/// The closed form: the probe sees the ground square (solid angle Ω,
/// projected solid angle πF) at radiance L_g = ρ (L_sky + E_sun s_y / π),
/// the sky everywhere else, and the sun as a delta of irradiance E_sun.
/// So L₀₀ = Y₀₀ (L_sky (4π − Ω) + L_g Ω + E_sun),
/// L₁₋₁ = 0.488603 ((L_sky − L_g) πF + E_sun s_y), L₁₁ = 0.488603 E_sun s_x.
#[test]
fn probe_over_sunlit_ground_under_sky_has_the_closed_form() {
    let to_sun = Vec3::new(0.4, 1.0, 0.25).normalize();
    let out = temp_dir("probes-sky-out");
    let config = BakeConfig {
        texels_per_meter: 2.0,
        sky: [SKY; 3],
        probe_rays: 4096,
        ..BakeConfig::default()
    };
    let bake = bake_to(&sky_scene(to_sun), &config, &out);
    let probes = bake.probes.as_ref().unwrap();
    assert_eq!(probes.len(), 1);
    assert!((probes.position(0) - Vec3::Y * H).length() < 1e-5);
    let c = probes.sh[0];

    let omega = 4.0 * (A * A / (A * A + H * H)).asin();
    let corner = |x: f32, y: f32| {
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
    };
    let f = 4.0 * corner(A / H, A / H);
    let lg = RHO * (SKY + SUN * to_sun.y / PI);
    let want0 = 0.282_095 * (SKY * (4.0 * PI - omega) + lg * omega + SUN);
    let want_y = 0.488_603 * ((SKY - lg) * PI * f + SUN * to_sun.y);
    let want_x = 0.488_603 * SUN * to_sun.x;
    eprintln!(
        "L00 {} vs {want0}, L1-1 {} vs {want_y}, L11 {} vs {want_x}",
        c[0].x, c[1].x, c[3].x
    );
    assert!((c[0].x / want0 - 1.0).abs() < 0.01);
    assert!((c[1].x / want_y - 1.0).abs() < 0.01);
    assert!((c[3].x / want_x - 1.0).abs() < 0.01);
    // The sun alone: a probe with the sun straight ahead; three.js's
    // irradiance for the normal facing it is E/π of the sun plus the rest.
    assert!(c[0].x > 0.0 && probes.invalid() == 0);
}

/// Probes inside a closed block are invalid, counted, and filled from
/// their neighbours (none stays black).
#[test]
fn probes_inside_a_closed_block_are_flagged_and_filled() {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([-5.0, 0.0, -5.0], [0.0, 0.0, 10.0], [10.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("ground", m);
    // A closed 2 m cube on the ground, faces outward.
    let faces = [
        quad([-1.0, 0.0, 1.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
        quad([1.0, 0.0, -1.0], [-2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
        quad([1.0, 0.0, 1.0], [0.0, 0.0, -2.0], [0.0, 2.0, 0.0]),
        quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [0.0, 2.0, 0.0]),
        quad([-1.0, 2.0, 1.0], [2.0, 0.0, 0.0], [0.0, 0.0, -2.0]),
        quad([-1.0, 0.0, -1.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]),
    ];
    for (k, (p, i)) in faces.iter().enumerate() {
        let m = b.mesh(p, i, Some(grey));
        b.node(&format!("block{k}"), m);
    }
    let mut doc = b.json();
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({
            "name": "probe_box", "translation": [0.0, 1.5, 0.0], "scale": [4.0, 3.0, 4.0],
            "extras": {"radbake": {"probe_volume": {"spacing": 0.5}}}
        }));
    let n = doc["nodes"].as_array().unwrap().len();
    doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
    let path = temp_dir("probes-block").join("block.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let config = BakeConfig {
        texels_per_meter: 8.0,
        sky: [1.0; 3],
        ..BakeConfig::default()
    };
    let out = temp_dir("probes-block-out");
    let bake = bake_to(&path, &config, &out);
    let probes = bake.probes.as_ref().unwrap();
    let inside: Vec<bool> = (0..probes.len())
        .map(|i| {
            let p = probes.position(i);
            p.x.abs() < 1.0 && p.z.abs() < 1.0 && p.y < 2.0
        })
        .collect();
    let n_inside = inside.iter().filter(|x| **x).count();
    assert!(n_inside >= 8, "{n_inside}");
    for (i, ins) in inside.iter().enumerate() {
        assert_eq!(
            !probes.valid[i],
            *ins,
            "probe {i} at {}",
            probes.position(i)
        );
        // Filled: every probe sees some light.
        assert!(probes.sh[i][0].x > 0.1, "probe {i} black");
    }
    let report = bake.report("block.gltf");
    assert_eq!(report.counts.invalid_probes, n_inside as u64);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("probes.json")).unwrap()).unwrap();
    assert_eq!(json["invalid_probes"].as_array().unwrap().len(), n_inside);
}

/// Cornell: the probes' E/π for the six axis normals against the path
/// tracer's at the probe position, from the same L2 projection of
/// radiance sampled by uniform random directions (so both carry the same
/// L2 truncation): within 3 standard errors of the path tracer plus 2 %
/// for the bake's own discretisation.
#[test]
fn cornell_probes_agree_with_the_path_tracer() {
    let path = scene_path("cornell_box.gltf");
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let config = BakeConfig {
        probe_spacing: 0.2,
        probe_budget: 64,
        probe_rays: 2048,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let probes = bake.probes.as_ref().unwrap();
    let geometry = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &geometry);
    let tracer = radbake::trace::Tracer::new(&scene, &geometry, &rays, Vec3::ZERO);
    let axes = sh::AXES;
    // A few valid probes spread over the grid.
    let picks: Vec<usize> = (0..probes.len())
        .filter(|&i| probes.valid[i])
        .step_by(probes.len() / 5)
        .take(4)
        .collect();
    assert!(picks.len() >= 3);
    let samples = 40_000;
    for &i in &picks {
        let p = probes.position(i);
        let mut rng = Stream::new(9, 77, i as u64);
        // Per sample: 4π L(d) Σ (Âₗ/π) Yₗₘ(n) Yₗₘ(d) for each axis n.
        let mut sum = [Vec3::ZERO; 6];
        let mut sq = [Vec3::ZERO; 6];
        for _ in 0..samples {
            let u = rng.next_vec2();
            let z = 1.0 - 2.0 * u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = Vec3::new(r * (2.0 * PI * u.y).cos(), r * (2.0 * PI * u.y).sin(), z);
            let l = tracer.radiance(p, d, &mut rng);
            let mut one = [Vec3::ZERO; 9];
            sh::add(&mut one, d, l, 4.0 * PI);
            for (k, n) in axes.iter().enumerate() {
                let v = sh::irradiance_over_pi(&one, *n);
                sum[k] += v;
                sq[k] += v * v;
            }
        }
        for (k, n) in axes.iter().enumerate() {
            let mean = sum[k] / samples as f32;
            let se =
                ((sq[k] / samples as f32 - mean * mean).max(Vec3::ZERO) / samples as f32).powf(0.5);
            let got = sh::irradiance_over_pi(&probes.sh[i], *n);
            let diff = (got - mean).abs();
            let allowed = se * 3.0 + mean * 0.02;
            eprintln!("probe {i} at {p}, n {n}: probe {got}, path tracer {mean} ± {se}");
            assert!(
                diff.cmple(allowed).all(),
                "probe {i}, n {n}: {got} vs {mean} ± {se}"
            );
        }
    }
}

/// The written volume sampled with Bevy 0.19's formula
/// (`irradiance_volume.wgsl`: stp = clamp((p + ½)·R, ½, R − ½), three
/// trilinear fetches at uvw = stp / size + the face's offset, weighted by
/// N²) at 1,000 random points and normals agrees with the probes' own SH
/// irradiance interpolated trilinearly, within RGB9E5's quantisation.
#[test]
fn bevy_reads_the_volume_as_the_probes_say() {
    let out = temp_dir("probes-bevy");
    let config = BakeConfig {
        probe_spacing: 0.15,
        probe_rays: 128,
        ..BakeConfig::default()
    };
    let bake = bake_to(&scene_path("cornell_box.gltf"), &config, &out);
    let probes = bake.probes.as_ref().unwrap();
    let v = &probes.volumes[0];
    let (size, texels) = read_volume(&out.join("probes_0.ktx2"));
    let at =
        |x: i32, y: i32, z: i32| texels[(x + size[0] as i32 * (y + size[1] as i32 * z)) as usize];
    // A linear-filtered, clamp-to-edge fetch at normalised `uvw`.
    let sample = |uvw: Vec3| {
        let s = Vec3::new(size[0] as f32, size[1] as f32, size[2] as f32);
        let q = uvw * s - 0.5;
        let b = q.floor();
        let f = q - b;
        let mut acc = Vec3::ZERO;
        for c in 0..8 {
            let o = glam::IVec3::new(c & 1, (c >> 1) & 1, c >> 2);
            let i = (b.as_ivec3() + o).clamp(glam::IVec3::ZERO, s.as_ivec3() - 1);
            let w = Vec3::select(o.cmpeq(glam::IVec3::ONE), f, 1.0 - f);
            acc += at(i.x, i.y, i.z) * (w.x * w.y * w.z);
        }
        acc
    };
    let r = v.resolution.as_vec3();
    let box_from_world = v.world_from_box.inverse();
    let mut rng = Stream::new(5, 5, 5);
    let mut worst = 0.0f32;
    for _ in 0..1000 {
        let local = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
        let p = v.world_from_box.transform_point3(local);
        let n = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5).normalize();
        // Bevy.
        let unit = box_from_world.transform_point3(p);
        let stp = ((unit + 0.5) * r).clamp(Vec3::splat(0.5), r - 0.5);
        let atlas = Vec3::new(size[0] as f32, size[1] as f32, size[2] as f32);
        let uvw = stp / atlas;
        let neg = Vec3::select(n.cmplt(Vec3::ZERO), Vec3::splat(0.5), Vec3::ZERO);
        let rgb_x = sample(uvw + Vec3::new(0.0, neg.x, 0.0));
        let rgb_y = sample(uvw + Vec3::new(0.0, neg.y, 1.0 / 3.0));
        let rgb_z = sample(uvw + Vec3::new(0.0, neg.z, 2.0 / 3.0));
        let bevy = rgb_x * n.x * n.x + rgb_y * n.y * n.y + rgb_z * n.z * n.z;
        // The probes: each axis's E/π interpolated trilinearly.
        let face = |axis: Vec3| {
            let mut acc = Vec3::ZERO;
            let q = stp - 0.5;
            let b = q.floor();
            let f = q - b;
            for c in 0..8u32 {
                let o = glam::UVec3::new(c & 1, (c >> 1) & 1, c >> 2);
                let g = (b.as_uvec3() + o).min(v.resolution - 1);
                let w = Vec3::select(o.cmpeq(glam::UVec3::ONE), f, 1.0 - f);
                let e =
                    sh::irradiance_over_pi(&probes.sh[v.first + v.index(g)], axis).max(Vec3::ZERO);
                acc += e * (w.x * w.y * w.z);
            }
            acc
        };
        let sx = if n.x < 0.0 { -1.0 } else { 1.0 };
        let sy = if n.y < 0.0 { -1.0 } else { 1.0 };
        let sz = if n.z < 0.0 { -1.0 } else { 1.0 };
        let want = face(Vec3::X * sx) * n.x * n.x
            + face(Vec3::Y * sy) * n.y * n.y
            + face(Vec3::Z * sz) * n.z * n.z;
        // RGB9E5 keeps 9 bits under a shared exponent: at most half a step
        // of the largest channel, 2⁻⁹ of it, per fetched texel.
        let err = (bevy - want).abs().max_element() / want.max_element().max(1e-6);
        worst = worst.max(err);
    }
    eprintln!("Bevy formula vs probes: worst relative difference {worst:.5}");
    assert!(worst < 2.0 / 512.0, "{worst}");
}

/// `--probes off` (config `probes = false`) bakes and writes no probes;
/// a malformed `probe_volume` is an error naming the node.
#[test]
fn probes_off_and_bad_volumes() {
    let out = temp_dir("probes-off");
    let config = BakeConfig {
        probes: false,
        ..BakeConfig::default()
    };
    let bake = bake_to(&scene_path("cornell_box.gltf"), &config, &out);
    assert!(bake.probes.is_none());
    assert!(!out.join("probes.json").exists() && !out.join("probes_0.ktx2").exists());

    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0; 3], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("ground", m);
    let mut doc = b.json();
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({
            "name": "vol", "extras": {"radbake": {"probe_volume": {"spacing": -1.0}}}
        }));
    doc["scenes"][0]["nodes"] = serde_json::json!([0, 1]);
    let path = temp_dir("probes-bad").join("bad.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let err = radbake::scene::load(&path, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("bad.gltf") && err.contains("nodes[1]") && err.contains("spacing"),
        "{err}"
    );
}
