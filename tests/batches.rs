//! The batched ray-casting path of the form factors and the final gather
//! (the path `--device gpu` takes, through [`BatchCaster`]) against their
//! CPU path, with the batches cast on the CPU ([`CpuBatches`]): no GPU is
//! needed, and the results must be bit-identical, batch boundaries falling
//! anywhere.

mod common;

use common::scene_path;
use glam::Vec3;
use radbake::radiosity::form_factors::raycast;
use radbake::radiosity::gather::{Extras, Gatherer};
use radbake::raycast::batch::CpuBatches;
use radbake::raycast::RayCaster;
use radbake::scene::Scene;
use radbake::surface::Landing;
use radbake::surface::Surfaces;
use radbake::{Bake, BakeConfig, Silent};

/// Runs `check` on the Cornell box baked at 24 texels/m without a final
/// gather (its scene, settings, bake, and surfaces over a CPU caster).
fn on_cornell(check: impl FnOnce(&Scene, &BakeConfig, &Bake, &Surfaces, &RayCaster)) {
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
    check(&scene, &config, &bake, &s, &rays);
}

#[test]
fn batched_form_factors_and_gather_equal_the_cpu_path() {
    on_cornell(|scene, config, bake, s, rays| {
        // Batches of 13 items: neither patches nor texels divide evenly.
        let batches = CpuBatches { rays, batch: 13 };

        let cpu = raycast::compute(s, 64, 7, &|_| {});
        let batched = raycast::compute_batched(s, &batches, 64, 7, &|_| {}).expect("batched F");
        assert!(
            bake.patches.len() > 13 * 3 && bake.patches.len() % 13 != 0,
            "several batches, the last one short ({} patches)",
            bake.patches.len()
        );
        assert_eq!(cpu.matrix, batched.matrix);
        assert_eq!(cpu.stats.rays, batched.stats.rays);
        assert!(cpu.nnz() > 0);

        // Any first pass will do: the bake's lightmap.
        let first = &bake.maps.lightmaps.texel_values;
        let sampled =
            radbake::light::lights::sampled_materials(scene, &bake.geometry, config.emitters);
        let extras = Extras {
            directional: true,
            sky: Vec3::new(0.2, 0.3, 0.4).into(),
            ao_distance: 0.3,
            ..Extras::default()
        };
        let gatherer = Gatherer::new(s, first, &sampled, 32, 7, extras, None);
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
    });
}

/// [`Surfaces::land_many`](radbake::surface::Surfaces::land_many)
/// gives every hit the landing that landing it alone gives: rays from
/// random points in the Cornell box in random directions, so that they
/// meet fronts, backs (the blocks' insides), unmapped and split texels.
#[test]
fn landing_hits_together_equals_landing_each() {
    on_cornell(|_, _, bake, s, rays| {
        let (lo, hi) = bake.geometry.p_ws.iter().flatten().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let mut rng = radbake::util::sampling::Stream::new(5, 0, 0);
        let cast: Vec<(Vec3, Option<radbake::raycast::Hit>)> = (0..20_000)
            .map(|_| {
                let o = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let d = d.normalize_or(Vec3::Z);
                (d, rays.closest_hit(o, d, f32::INFINITY))
            })
            .collect();
        let hits: Vec<_> = cast.iter().map(|c| c.1).collect();
        // 20,000 is not a multiple of the passes' 16: the last pass is short.
        let mut together = vec![Landing::Escaped; hits.len()];
        s.land_many(&hits, |i| cast[i].0, &mut together);
        let alone: Vec<Landing> = cast
            .iter()
            .map(|&(d, h)| h.map_or(Landing::Escaped, |h| s.land(h.tri, h.u, h.v, d)))
            .collect();
        assert_eq!(together, alone);
        let count = |f: &dyn Fn(&Landing) -> bool| alone.iter().filter(|l| f(l)).count();
        assert!(count(&|l| matches!(l, Landing::BackFace)) > 0);
        assert!(count(&|l| matches!(l, Landing::Escaped)) > 0);
        let split = count(&|l| matches!(l, Landing::Texel(t) if bake.burial.split(*t as usize)));
        assert!(split > 0, "some hits land on split texels");
    });
}

/// Where nothing is sampled (no lights, no sampled emitters, a black
/// sky), `direct::texel_range` skips every texel's sample points: each
/// texel must get what sampling would give, nothing and no rays.
#[test]
fn nothing_to_sample_gives_what_sampling_nothing_gives() {
    use radbake::light::direct::{self, TexelDirect, TexelSettings};
    use radbake::light::lights::{Lights, Mis};
    use radbake::util::sampling::Stream;
    on_cornell(|scene, config, bake, s, _| {
        let lights = Lights::new(
            scene,
            &bake.geometry,
            &vec![false; scene.materials.len()],
            Vec3::ZERO,
        );
        assert!(lights.is_empty() && scene.lights.is_empty());
        let mis = Mis {
            light: 16,
            hemisphere: 16,
        };
        let settings = TexelSettings {
            samples: 16,
            hemisphere: 16,
            mis,
            supersample: 1,
            seed: config.seed,
        };
        let n = s.texels.len();
        let skipped = direct::texel_range(s, &lights, &settings, 0..n, &|_| {});
        assert_eq!(skipped.len(), n);
        let zero = |d: &TexelDirect| {
            d.light == Vec3::ZERO
                && d.mixed == Vec3::ZERO
                && d.hemisphere == Vec3::ZERO
                && d.local == Vec3::ZERO
                && d.directional == [Vec3::ZERO; 3]
                && d.rays == 0
        };
        for t in (0..n).step_by(7) {
            assert!(zero(&skipped[t]), "texel {t}");
            let sampler = s.texel_sampler(t as u32);
            let mut rng = Stream::new(config.seed, 1, t as u64);
            let points: Vec<_> = (0..16).map(|_| sampler.sample(rng.next_vec2())).collect();
            let sampled = direct::direct_at(s, &lights, mis, &points, &points, &points, &mut rng);
            assert!(zero(&sampled), "texel {t}: {sampled:?}");
            let pieces = direct::pieces_direct(s, &lights, t, config.seed);
            assert!(zero(&pieces), "texel {t}: {pieces:?}");
        }
    });
}
