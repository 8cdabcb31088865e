//! Form factors of the Cornell box (medium preset: 4 × 4-texel patches)
//! by ray casting (1024 rays per patch) and by the hemicube (128 px);
//! throughput in patches (rows of F).
//!
//!     cargo bench --bench form_factors

mod common;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use radbake::radiosity::form_factors::{hemicube, raycast};
use radbake::raycast::RayCaster;

fn form_factors(c: &mut Criterion) {
    let scene = common::cornell();
    let bake = common::cornell_bake(&scene);
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let config = &bake.config;
    let mut group = c.benchmark_group("form_factors_cornell");
    group.throughput(Throughput::Elements(bake.patches.len() as u64));
    group.bench_function(format!("raycast_{}_rays", config.rays_per_patch), |b| {
        b.iter(|| raycast::compute(black_box(&s), config.rays_per_patch, config.seed, &|_| {}))
    });
    group.bench_function(format!("hemicube_{}px", config.hemicube_resolution), |b| {
        b.iter(|| hemicube::compute(black_box(&s), config.hemicube_resolution, &|_| {}))
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = form_factors
}
criterion_main!(benches);
