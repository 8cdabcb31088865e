//! The whole Cornell box bake, import to lightmaps in memory (nothing
//! written), with the medium preset.
//!
//!     cargo bench --bench bake

mod common;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use radbake::BakeConfig;

fn bake(c: &mut Criterion) {
    let path = common::scene_path("cornell_box.gltf");
    let config = BakeConfig::medium();
    c.bench_function("bake_cornell_medium", |b| {
        b.iter(|| {
            let scene = radbake::scene::load(black_box(&path), &Default::default())
                .expect("the Cornell box loads");
            let bake = radbake::bake(&scene, &config, &radbake::Silent).expect("it bakes");
            black_box(bake.maps.lightmaps.texel_values.len())
        })
    });
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bake
}
criterion_main!(benches);
