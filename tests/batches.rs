//! The batched ray-casting path of the form factors and the final gather
//! (the path `--device gpu` takes, through [`BatchCaster`]) against their
//! CPU path, with the batches cast on the CPU ([`CpuBatches`]): no GPU is
//! needed, and the results must be bit-identical, batch boundaries falling
//! anywhere.

mod common;

use common::scene_path;
use glam::Vec3;
use radbake::form_factors::raycast;
use radbake::gather::{Extras, Gatherer};
use radbake::raycast::batch::CpuBatches;
use radbake::raycast::RayCaster;
use radbake::{BakeConfig, Silent};

#[test]
fn batched_form_factors_and_gather_equal_the_cpu_path() {
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default())
        .expect("scene loads");
    let config = BakeConfig {
        texels_per_meter: 24.0,
        final_gather: 0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).expect("bake");
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    // Batches of 13 items: neither patches nor texels divide evenly.
    let batches = CpuBatches {
        rays: &rays,
        batch: 13,
    };

    let cpu = raycast::compute(&s, 64, 7, &|_| {});
    let batched = raycast::compute_batched(&s, &batches, 64, 7, &|_| {}).expect("batched F");
    assert!(
        bake.patches.len() > 13 * 3 && bake.patches.len() % 13 != 0,
        "several batches, the last one short ({} patches)",
        bake.patches.len()
    );
    assert_eq!(cpu.matrix.row_offsets(), batched.matrix.row_offsets());
    assert_eq!(cpu.matrix.col_indices(), batched.matrix.col_indices());
    assert_eq!(cpu.matrix.values(), batched.matrix.values());
    assert_eq!(cpu.stats.rays, batched.stats.rays);
    assert!(cpu.nnz() > 0);

    // Any first pass will do: the bake's lightmap.
    let first = &bake.maps.lightmaps.texel_values;
    let sampled = radbake::direct::sampled_materials(&scene, &bake.geometry, config.emitters);
    let extras = Extras {
        directional: true,
        sky: Vec3::new(0.2, 0.3, 0.4).into(),
        ao_distance: 0.3,
        ..Extras::default()
    };
    let gatherer = Gatherer::new(&s, first, &sampled, 32, 7, extras, None);
    let a = gatherer.gather_cpu(&|_| {});
    let b = gatherer
        .gather_batched(&batches, &|_| {})
        .expect("batched gather");
    assert_eq!(a.rays, b.rays);
    assert_eq!(a.indirect, b.indirect);
    assert_eq!(a.valid, b.valid);
    assert_eq!(a.variance, b.variance);
    assert_eq!(a.directional, b.directional);
    assert_eq!(a.ao, b.ao);
    assert!(a.indirect.iter().any(|v| v.max_element() > 0.0));
    assert!(!a.directional.is_empty() && !a.ao.is_empty());
}
