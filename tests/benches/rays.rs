//! Ray casting throughput on incoherent rays over the ~1 M-triangle
//! generated level: closest hits (cosine-distributed rays from random
//! surface points, as the form factors and the final gather cast them) and
//! occlusion (segments between random surface points, as shadow rays),
//! on one thread and on all of rayon's threads; throughput in rays.
//!
//!     cargo bench --bench rays

mod common;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use radbake::raycast::RayCaster;
use rayon::prelude::*;

/// Rays per iteration.
const RAYS: usize = 1 << 16;

/// Closest hits found (one thread).
fn closest_serial(caster: &RayCaster, r: &common::Rays) -> u64 {
    (0..r.len())
        .filter(|&i| {
            caster
                .closest_hit(r.origin[i], r.dir[i], r.tmax[i])
                .is_some()
        })
        .count() as u64
}

/// Closest hits found (all threads).
fn closest_parallel(caster: &RayCaster, r: &common::Rays) -> u64 {
    (0..r.len())
        .into_par_iter()
        .with_min_len(256)
        .filter(|&i| {
            caster
                .closest_hit(r.origin[i], r.dir[i], r.tmax[i])
                .is_some()
        })
        .count() as u64
}

/// Unoccluded rays (one thread).
fn occlusion_serial(caster: &RayCaster, r: &common::Rays) -> u64 {
    (0..r.len())
        .filter(|&i| caster.unoccluded(r.origin[i], r.dir[i], r.tmax[i]))
        .count() as u64
}

/// Unoccluded rays (all threads).
fn occlusion_parallel(caster: &RayCaster, r: &common::Rays) -> u64 {
    (0..r.len())
        .into_par_iter()
        .with_min_len(256)
        .filter(|&i| caster.unoccluded(r.origin[i], r.dir[i], r.tmax[i]))
        .count() as u64
}

fn rays(c: &mut Criterion) {
    let scene = common::level_scene(1_000_000);
    let geometry = common::world_geometry(&scene);
    let caster = RayCaster::new(&scene, &geometry);
    let closest = common::surface_rays(&geometry, RAYS, common::SEED);
    let shadow = common::shadow_rays(&geometry, RAYS, common::SEED);
    let mut group = c.benchmark_group(format!("rays_level_{}_tris", geometry.len()));
    group.throughput(Throughput::Elements(RAYS as u64));
    group.bench_function("closest_hit/1_thread", |b| {
        b.iter(|| closest_serial(&caster, black_box(&closest)))
    });
    group.bench_function(
        format!("closest_hit/{}_threads", rayon::current_num_threads()),
        |b| b.iter(|| closest_parallel(&caster, black_box(&closest))),
    );
    group.bench_function("occlusion/1_thread", |b| {
        b.iter(|| occlusion_serial(&caster, black_box(&shadow)))
    });
    group.bench_function(
        format!("occlusion/{}_threads", rayon::current_num_threads()),
        |b| b.iter(|| occlusion_parallel(&caster, black_box(&shadow))),
    );
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = rays
}
criterion_main!(benches);
