//! Closest-hit rays/s of `--device gpu`'s compute shader against the CPU
//! ray caster, on the same incoherent rays (random surface points, cosine
//! directions, as the form factors cast them) over a scene or the
//! generated level. The GPU figure is given whole (upload, kernel,
//! readback, each waited for apart) and for the kernel alone; the two
//! devices' answers are compared ray by ray.
//!
//!     cargo run --release --example gpu_rays -- [scene.glb] --triangles 1000000 --rays 1048576
//!
//! Needs the `gpu` feature (default) and an adapter (a software one,
//! lavapipe, will do, but only a real GPU's figures mean anything).

#[path = "../tests/benches/common/mod.rs"]
mod common;

use clap::Parser;
use glam::Vec3;
use radbake::raycast::gpu::GpuRayCaster;
use radbake::raycast::RayCaster;
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "Closest-hit rays/s: the GPU shader against the CPU ray caster")]
struct Args {
    /// The scene (.gltf/.glb); the generated level when left out.
    scene: Option<PathBuf>,
    /// Triangles of the generated level (without a scene).
    #[arg(long, default_value_t = 1_000_000)]
    triangles: u64,
    /// Rays (at most one GPU batch, 2^20).
    #[arg(long, default_value_t = 1 << 20)]
    rays: usize,
    /// Timed runs of each measurement (the best is reported).
    #[arg(long, default_value_t = 5)]
    repeat: u32,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let scene = match &args.scene {
        Some(path) => radbake::scene::load(path, &Default::default())?,
        None => common::level_scene(args.triangles),
    };
    let geometry = common::world_geometry(&scene);
    let r = common::surface_rays(&geometry, args.rays, common::SEED);
    let rays: Vec<(Vec3, Vec3)> = r
        .origin
        .iter()
        .copied()
        .zip(r.dir.iter().copied())
        .collect();
    let cpu = RayCaster::new(&scene, &geometry);
    let t = Instant::now();
    let gpu = GpuRayCaster::new(&geometry)?;
    let setup = t.elapsed().as_secs_f64();
    println!(
        "{} triangles, {} rays; GPU: {} (BVH build + upload + pipeline {setup:.3} s)",
        geometry.len(),
        rays.len(),
        gpu.adapter
    );
    let mut cpu_best = f64::INFINITY;
    let mut cpu_hits = Vec::new();
    for _ in 0..args.repeat.max(1) {
        let t = Instant::now();
        cpu_hits = rays
            .par_iter()
            .with_min_len(256)
            .map(|&(o, d)| cpu.closest_hit(o, d, f32::INFINITY))
            .collect::<Vec<_>>();
        cpu_best = cpu_best.min(t.elapsed().as_secs_f64());
    }
    let mut best = None::<radbake::raycast::gpu::CastTimes>;
    let mut gpu_hits = Vec::new();
    for _ in 0..args.repeat.max(1) {
        let (hits, times) = gpu.timed_cast(&rays)?;
        gpu_hits = hits;
        let total = |c: &radbake::raycast::gpu::CastTimes| c.upload + c.kernel + c.readback;
        if best.as_ref().is_none_or(|b| total(&times) < total(b)) {
            best = Some(times);
        }
    }
    let n = gpu_hits.len();
    let same = cpu_hits[..n]
        .iter()
        .zip(&gpu_hits)
        .filter(|(c, g)| c.map(|h| h.tri) == g.map(|h| h.tri))
        .count();
    let b = best.ok_or_else(|| anyhow::anyhow!("no GPU run"))?;
    let m = |s: f64| n as f64 / s / 1e6;
    println!(
        "CPU ({} threads): {:.3} s, {:.1} M rays/s",
        rayon::current_num_threads(),
        cpu_best,
        m(cpu_best)
    );
    println!(
        "GPU whole: {:.4} s, {:.1} M rays/s (upload {:.4} s, kernel {:.4} s, readback {:.4} s)",
        b.upload + b.kernel + b.readback,
        m(b.upload + b.kernel + b.readback),
        b.upload,
        b.kernel,
        b.readback
    );
    println!("GPU kernel: {:.1} M rays/s", m(b.kernel));
    println!(
        "same triangle as the CPU: {same} of {n} ({:.4} %)",
        100.0 * same as f64 / n.max(1) as f64
    );
    Ok(())
}
