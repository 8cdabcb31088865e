//! BVH build (`RayCaster::new`: obvhs PLOC, medium preset, collapsed into radbake's BVH4) over the
//! generated level at ~25 k and ~1 M triangles; throughput in triangles.
//!
//!     cargo bench --bench bvh

mod common;

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use radbake::raycast::RayCaster;

fn bvh_build(c: &mut Criterion) {
    let mut group = c.benchmark_group("bvh_build");
    for target in [25_000u64, 1_000_000] {
        let scene = common::level_scene(target);
        let geometry = common::world_geometry(&scene);
        group.throughput(Throughput::Elements(geometry.len() as u64));
        group.bench_with_input(
            BenchmarkId::new("level", geometry.len()),
            &geometry,
            |b, g| b.iter(|| RayCaster::new(&scene, black_box(g))),
        );
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bvh_build
}
criterion_main!(benches);
