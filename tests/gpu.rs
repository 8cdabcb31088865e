//! `--device gpu`: form-factor rays cast by a wgpu compute shader
//! (`shaders/raycast.wgsl`) must agree with the CPU ray caster.
//!
//! Needs an adapter; Mesa's lavapipe (software Vulkan, installed by
//! `.ci/run`) is enough. Where none exists the GPU tests print why and
//! return; the shader is validated by naga everywhere.
#![cfg(feature = "gpu")]

mod common;

use common::scene_path;
use glam::Vec3;
use radbake::config::{Device, FormFactorMethod, Solver};
use radbake::layout::geometry::Geometry;
use radbake::raycast::gpu::{GpuRayCaster, SHADER};
use radbake::raycast::RayCaster;
use radbake::scene::Scene;
use radbake::util::sampling::Stream;
use radbake::{BakeConfig, Silent};

fn load(name: &str) -> Scene {
    radbake::scene::load(&scene_path(name), &Default::default()).expect("scene loads")
}

/// The GPU caster, or None (after printing why) on a machine without any adapter.
fn gpu(geometry: &Geometry) -> Option<GpuRayCaster> {
    match GpuRayCaster::new(geometry) {
        Ok(g) => Some(g),
        Err(e) if format!("{e:#}").contains("no graphics adapter") => {
            eprintln!("SKIPPED (no GPU or software adapter on this machine): {e:#}");
            None
        }
        Err(e) => panic!("GPU ray caster: {e:#}"),
    }
}

#[test]
fn raycast_shader_validates() {
    let module = naga::front::wgsl::parse_str(SHADER).expect("raycast.wgsl parses");
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .expect("raycast.wgsl validates");
    assert!(
        module.entry_points.iter().any(|e| e.name == "cast_rays"),
        "entry point cast_rays"
    );
}

/// 20,000 random rays inside the Cornell box (and some from outside, which
/// miss or hit the outer faces): the GPU finds the same triangle as the CPU
/// for all but a couple (ties at shared edges), at the same distance.
#[test]
fn gpu_closest_hits_match_cpu() {
    let scene = load("cornell_box.gltf");
    let geometry = Geometry::unmapped(&scene);
    let cpu = RayCaster::new(&scene, &geometry);
    let Some(gpu) = gpu(&geometry) else { return };
    let corners = geometry.p_ws.iter().flatten();
    let lo = corners.clone().fold(Vec3::INFINITY, |a, &p| a.min(p));
    let hi = corners.fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
    let mut rng = Stream::new(7, 1, 0);
    let rays: Vec<(Vec3, Vec3)> = (0..20_000)
        .map(|k| {
            // A quarter start outside the box, 1 m beyond its bounds.
            let margin = if k % 4 == 0 { 1.0 } else { -0.01 };
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let o = (lo - Vec3::splat(margin)) + u * (hi - lo + Vec3::splat(2.0 * margin));
            let z = 2.0 * rng.next_f32() - 1.0;
            let phi = std::f32::consts::TAU * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            (o, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect();
    let got = gpu.closest_hits(&rays).expect("GPU cast");
    assert_eq!(got.len(), rays.len());
    let (mut same, mut hits, mut worst_t) = (0usize, 0usize, 0f32);
    for (&(o, d), g) in rays.iter().zip(&got) {
        let c = cpu.closest_hit(o, d, f32::INFINITY);
        hits += c.is_some() as usize;
        match (c, g) {
            (None, None) => same += 1,
            (Some(c), Some(g)) if c.tri == g.tri => {
                same += 1;
                worst_t = worst_t.max((c.t - g.t).abs() / c.t.max(1.0));
                assert!((c.u - g.u).abs() < 1e-3 && (c.v - g.v).abs() < 1e-3);
            }
            _ => {}
        }
    }
    assert!(hits > 10_000, "most rays hit the box ({hits})");
    let mismatch = rays.len() - same;
    assert!(mismatch <= 2, "{mismatch} of {} rays disagree", rays.len());
    assert!(worst_t < 1e-4, "hit distance differs by {worst_t}");
}

/// The whole bake with `device = gpu`: the same rays are cast, so every
/// instance's mean lightmap value agrees with the CPU bake within 0.01 %
/// (on lavapipe the lightmaps come out bit-identical; another GPU may round
/// the triangle test differently at shared edges).
fn assert_gpu_bake_matches_cpu(config: BakeConfig, min_rays: u64, ran: &str) {
    let scene = load("cornell_box.gltf");
    if gpu(&Geometry::unmapped(&scene)).is_none() {
        return;
    }
    let cpu = radbake::bake(&scene, &config, &Silent).unwrap();
    let gpu = radbake::bake(
        &scene,
        &BakeConfig {
            device: Device::Gpu,
            ..config
        },
        &Silent,
    )
    .unwrap();
    assert!(
        gpu.warnings.iter().any(|w| w.contains(ran)),
        "the GPU path ran: {:?}",
        gpu.warnings
    );
    assert_eq!(cpu.transport.rays, gpu.transport.rays);
    assert!(
        gpu.transport.rays.form_factors >= min_rays,
        "{} rays, wanted at least {min_rays}",
        gpu.transport.rays.form_factors
    );
    let row_sums = |b: &radbake::Bake| b.patch_light().unwrap().row_sums.clone();
    let (cpu_rows, gpu_rows) = (row_sums(&cpu), row_sums(&gpu));
    assert_eq!(cpu_rows.len(), gpu_rows.len());
    for (i, (c, g)) in cpu_rows.iter().zip(&gpu_rows).enumerate() {
        assert!((c - g).abs() < 1e-3, "row {i}: Σ F CPU {c} GPU {g}");
    }
    for (c, g) in cpu.instance_reports().iter().zip(gpu.instance_reports()) {
        assert_eq!(c.node, g.node);
        for k in 0..3 {
            let e = (c.mean[k] - g.mean[k]).abs() / c.mean[k].max(1e-3);
            assert!(
                e < 1e-4,
                "{} channel {k}: CPU {} GPU {} ({:.3} %)",
                c.node,
                c.mean[k],
                g.mean[k],
                e * 100.0
            );
        }
    }
}

#[test]
fn gpu_bake_matches_cpu_bake() {
    assert_gpu_bake_matches_cpu(
        BakeConfig {
            texels_per_meter: 24.0,
            final_gather: 0,
            ..BakeConfig::default()
        },
        0,
        "cast on the GPU",
    );
}

/// `--device gpu --form-factors hemicube`: the hemicubes rasterised by the
/// GPU (`shaders/hemicube.wgsl`, 80 per pass) give the CPU's rows: every
/// row's Σ F within 10⁻³ and every instance's mean within 10⁻⁴, with a
/// stored matrix (Jacobi) and with rows on demand (progressive refinement,
/// a pass per step's shooters and per chunk of the gathering sweeps).
#[test]
fn gpu_hemicubes_match_cpu_hemicubes() {
    for solver in [Solver::Jacobi, Solver::Progressive] {
        assert_gpu_bake_matches_cpu(
            BakeConfig {
                texels_per_meter: 24.0,
                final_gather: 0,
                form_factors: FormFactorMethod::Hemicube,
                solver,
                ..BakeConfig::default()
            },
            1_000_000,
            "hemicubes rendered on the GPU",
        );
    }
}

#[test]
fn hemicube_shader_validates() {
    let module =
        naga::front::wgsl::parse_str(radbake::radiosity::form_factors::gpu_hemicube::SHADER)
            .expect("hemicube.wgsl parses");
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .expect("hemicube.wgsl validates");
}

/// Over 2²⁰ rays a stage goes to the GPU in batches, each generated while
/// the one before is cast (two buffer slots): the form factors' 1.7 M rays
/// in two batches, the final gather's 3.4 M in four. Rows and texels must
/// still come out in order, the same as the CPU's, and the gather's texels
/// cast the same rays (the GPU casts all of an invalid texel's rays, the
/// gather reads only those the CPU would have cast).
#[test]
fn gpu_bake_with_final_gather_over_several_batches_matches_cpu_bake() {
    assert_gpu_bake_matches_cpu(
        BakeConfig {
            rays_per_patch: 1024,
            ..BakeConfig::default()
        },
        1 << 20,
        "cast on the GPU",
    );
}
