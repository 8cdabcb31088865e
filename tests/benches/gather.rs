//! Final gather of the Cornell box (medium preset: 128 rays per texel) from
//! its first-pass lightmap; throughput in texels.
//!
//!     cargo bench --bench gather

mod common;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use radbake::light::lights;
use radbake::maps::lightmap;
use radbake::radiosity::gather;
use radbake::raycast::RayCaster;

fn final_gather(c: &mut Criterion) {
    let scene = common::cornell();
    let bake = common::cornell_bake(&scene);
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let indirect: Vec<Vec3> = bake
        .patch_light()
        .expect("radiosity")
        .solution
        .irradiance
        .iter()
        .zip(&bake.patch_light().expect("radiosity").direct)
        .map(|(h, d)| *h - *d)
        .collect();
    let first = lightmap::first_pass(
        &bake.texels,
        &bake.patches,
        &bake.transport.direct,
        &indirect,
    );
    let sampled =
        radbake::light::lights::sampled_materials(&scene, &bake.geometry, bake.config.emitters);
    // As the bake does: the gather rays also estimate the direct light's
    // hemisphere part (sky, emitters by MIS).
    let lights = lights::Lights::new(
        &scene,
        &bake.geometry,
        &sampled,
        Vec3::from(bake.config.sky),
    );
    let mis = lights::Mis {
        light: bake.config.direct_samples,
        hemisphere: bake.config.final_gather,
    };
    let extras = gather::Extras {
        directional: false,
        sky: Vec3::from(bake.config.sky).into(),
        ao_distance: 0.0,
        backface_tolerance: bake.config.backface_tolerance,
        threshold: 0.0,
    };
    let config = &bake.config;
    let mut group = c.benchmark_group("final_gather_cornell");
    group.throughput(Throughput::Elements(bake.texels.len() as u64));
    group.bench_function(format!("{}_rays_per_texel", config.final_gather), |b| {
        b.iter(|| {
            gather::gather(
                black_box(&s),
                &first,
                &sampled,
                config.final_gather,
                config.seed,
                extras.clone(),
                Some((&lights, mis)),
                &|_| {},
            )
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = final_gather
}
criterion_main!(benches);
