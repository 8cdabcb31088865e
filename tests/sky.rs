//! HDRI skies (issue #23): `--sky-map` replaces the uniform sky, and is
//! importance-sampled by luminance with MIS against the cosine rays in the
//! direct pass, the final gather, the probes and the path tracer.
//!
//! - A constant map bakes as the uniform sky of that radiance (lightmap and
//!   probe).
//! - A map black but for a small bright patch, over an open plane: every
//!   texel's irradiance / π against the exact integral over the patch's
//!   pixels (radiosity and the path tracer).
//! - A closed box ignores the sky map, bit for bit.
//! - At equal rays, importance sampling beats the cosine rays alone.
//! - Bad maps and settings are one-line errors naming the file or key.

mod common;

use common::{ground, scene_path, sunlit_ground, temp_dir};
use glam::Vec3;
use radbake::light::direct;
use radbake::light::lights::{Lights, Mis};
use radbake::{BakeConfig, Silent};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// Map size (2:1) and the bright patch: rows `ROWS`, columns `COLS`.
const W: u32 = 64;
const H: u32 = 32;
const ROWS: std::ops::Range<u32> = 8..10;
const COLS: std::ops::Range<u32> = 20..23;
const PATCH: f32 = 50.0;

/// Writes a `W` × `H` EXR whose pixel (x, y) is `f(x, y)`.
fn write_map(name: &str, f: impl Fn(u32, u32) -> f32) -> PathBuf {
    let path = temp_dir(name).join("sky.exr");
    let px: Vec<Vec3> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .map(|(x, y)| Vec3::splat(f(x, y)))
        .collect();
    radbake::output::write_exr_rgb(&path, W, H, &px).unwrap();
    path
}

fn patch_map(name: &str) -> PathBuf {
    write_map(name, |x, y| {
        if ROWS.contains(&y) && COLS.contains(&x) {
            PATCH
        } else {
            0.0
        }
    })
}

/// Irradiance / π on an open plane facing +Y under the patch: each pixel
/// spans Δφ = 2π/W and θ ∈ [θ₀, θ₁] (row/H · π), and
/// ∫ cos θ dω = Δφ (sin² θ₁ − sin² θ₀) / 2 over it.
fn patch_irradiance() -> f64 {
    let dphi = 2.0 * PI / W as f64;
    let mut e = 0.0;
    for row in ROWS {
        let (t0, t1) = (row as f64 / H as f64 * PI, (row + 1) as f64 / H as f64 * PI);
        e += COLS.len() as f64 * PATCH as f64 * dphi * (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
    }
    e / PI
}

fn config(map: Option<&Path>) -> BakeConfig {
    BakeConfig {
        texels_per_meter: 1.0,
        sky_map: map.map(Path::to_path_buf),
        ..BakeConfig::default()
    }
}

/// Area-weighted mean and worst relative deviation from `want` of the
/// ground's wholly covered texels.
fn ground_stats(bake: &radbake::Bake, values: &[Vec3], want: f64) -> (f64, f64) {
    let (mut sum, mut area, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    for (v, &a) in values.iter().zip(&bake.texels.area) {
        let a = a as f64;
        if a < 0.99 {
            continue;
        }
        let v = v.x as f64;
        sum += v * a;
        area += a;
        worst = worst.max((v / want - 1.0).abs());
    }
    (sum / area, worst)
}

/// A constant map of radiance 0.8 bakes as `sky = 0.8`: every ground
/// texel (open to the sky) within 2 %, their mean within 0.3 %, and the
/// probe's L₀₀ within 1 %.
#[test]
fn constant_map_equals_the_uniform_sky() {
    let c = ground::SKY;
    let scene_file = sunlit_ground("sky-constant", Vec3::Y, false, None);
    let scene = radbake::scene::load(&scene_file, &Default::default()).unwrap();
    let uniform = BakeConfig {
        sky: [c; 3],
        ..config(None)
    };
    let a = radbake::bake(&scene, &uniform, &Silent).unwrap();
    let map = write_map("sky-constant-map", |_, _| c);
    let b = radbake::bake(&scene, &config(Some(&map)), &Silent).unwrap();
    let (ma, _) = ground_stats(&a, &a.transport.values, c as f64);
    let (mb, worst) = ground_stats(&b, &b.transport.values, c as f64);
    let (pa, pb) = (a.probes.unwrap().sh[0][0].x, b.probes.unwrap().sh[0][0].x);
    eprintln!("ground mean: uniform {ma:.5}, map {mb:.5} (worst texel {worst:.4}); probe L00 {pa:.5} vs {pb:.5}");
    assert!((ma / c as f64 - 1.0).abs() < 1e-5);
    assert!((mb / c as f64 - 1.0).abs() < 3e-3);
    assert!(worst < 0.02);
    assert!((pb / pa - 1.0).abs() < 0.01);
}

/// The bright patch over the open ground: every texel's irradiance / π
/// within 3 % of the exact integral and their mean within 0.5 %, with
/// the radiosity bake (sky samples + gather rays by MIS) and the path
/// tracer (one sky sample per vertex, balance heuristic).
#[test]
fn bright_patch_matches_its_exact_irradiance() {
    let want = patch_irradiance();
    let scene_file = sunlit_ground("sky-patch", Vec3::Y, false, None);
    let scene = radbake::scene::load(&scene_file, &Default::default()).unwrap();
    let map = patch_map("sky-patch-map");
    let b = radbake::bake(&scene, &config(Some(&map)), &Silent).unwrap();
    let (mean, worst) = ground_stats(&b, &b.transport.values, want);
    eprintln!("radiosity: mean {mean:.5} vs exact {want:.5}, worst texel {worst:.4}");
    assert!((mean / want - 1.0).abs() < 0.005);
    assert!(worst < 0.03);

    let traced = BakeConfig {
        method: radbake::config::Method::Pathtrace,
        path_samples: 256,
        probes: false,
        ..config(Some(&map))
    };
    let p = radbake::bake(&scene, &traced, &Silent).unwrap();
    let (mean, worst) = ground_stats(&p, &p.transport.values, want);
    eprintln!("path tracer: mean {mean:.5}, worst texel {worst:.4}");
    assert!((mean / want - 1.0).abs() < 0.01);
    assert!(worst < 0.05);
}

/// The furnace box (closed, emissive walls) with a bright sky map bakes
/// bit for bit as without it: no ray leaves the box.
#[test]
fn closed_box_ignores_the_sky_map() {
    let scene = radbake::scene::load(&scene_path("furnace_box.gltf"), &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 8.0,
        probes: false,
        ..BakeConfig::default()
    };
    let a = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let map = write_map("sky-furnace-map", |x, _| 100.0 + x as f32);
    let with = BakeConfig {
        sky_map: Some(map),
        ..cfg
    };
    let b = radbake::bake(&scene, &with, &Silent).unwrap();
    assert_eq!(a.maps.lightmaps.texel_values, b.maps.lightmaps.texel_values);
    assert!(
        b.transport.rays.direct > a.transport.rays.direct,
        "sky samples were cast"
    );
}

/// Noise at equal rays (64 per texel, direct pass only): importance
/// sampling (32 sky samples + 32 cosine rays, MIS) against 64 cosine rays
/// alone (no sky samples, so the escaped rays' MIS weight is 1), as the RMS relative error of the ground's texels against the
/// exact value.
#[test]
fn importance_sampling_beats_cosine_rays_at_equal_cost() {
    let want = patch_irradiance();
    let scene_file = sunlit_ground("sky-noise", Vec3::Y, false, None);
    let scene = radbake::scene::load(&scene_file, &Default::default()).unwrap();
    let map = patch_map("sky-noise-map");
    let cfg = BakeConfig {
        probes: false,
        final_gather: 0,
        ..config(Some(&map))
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let rays = radbake::raycast::RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let sampled = vec![false; scene.materials.len()];
    let rms = |samples: u32, hemisphere: u32| {
        let mut lights = Lights::new(&scene, &bake.geometry, &sampled, cfg.load_sky().unwrap());
        lights.sky_samples = samples;
        let mis = Mis {
            light: samples,
            hemisphere,
        };
        let d = direct::texels(&s, &lights, samples, hemisphere, mis, 1, 7, &|_| {});
        let (mut sq, mut n) = (0.0f64, 0);
        for t in 0..bake.texels.len() {
            if bake.texels.area[t] < 0.99 {
                continue;
            }
            let v = (d.light[t] + d.hemisphere[t]).x as f64;
            sq += (v / want - 1.0).powi(2);
            n += 1;
        }
        (sq / n as f64).sqrt()
    };
    let (is, cosine) = (rms(32, 32), rms(0, 64));
    eprintln!("RMS relative error at 64 rays per texel: importance sampling {is:.4}, cosine rays {cosine:.4}");
    assert!(is < 0.25 * cosine);
}

/// A missing map, a map that is not 2:1 and a bad intensity are one-line
/// errors of `radbake bake` naming the file or key; a sky map with photon
/// mapping is refused.
#[test]
fn bad_sky_maps_are_one_line_errors() {
    let scene = sunlit_ground("sky-bad", Vec3::Y, false, None);
    let out = temp_dir("sky-bad-out");
    let square = temp_dir("sky-bad-square").join("square.exr");
    radbake::output::write_exr_rgb(&square, 8, 8, &[Vec3::ONE; 64]).unwrap();
    let map = write_map("sky-bad-map", |_, _| 1.0);
    let cases: [(Vec<String>, &str); 4] = [
        (
            vec!["--sky-map".into(), "/nonexistent/sky.exr".into()],
            "sky.exr",
        ),
        (
            vec!["--sky-map".into(), square.display().to_string()],
            "2:1",
        ),
        (
            vec![
                "--sky-map".into(),
                map.display().to_string(),
                "--sky-intensity=-1".into(),
            ],
            "sky_intensity",
        ),
        (
            vec![
                "--sky-map".into(),
                map.display().to_string(),
                "--method".into(),
                "photon".into(),
            ],
            "sky_map",
        ),
    ];
    for (args, needle) in cases {
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_radbake"))
            .args([
                "bake",
                "-q",
                "--force",
                "--probes",
                "off",
                "--texels-per-meter",
                "1",
            ])
            .arg(&scene)
            .arg("--out")
            .arg(&out)
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
}
