//! Whole bakes of scenes with exact answers: the reference scenes shipped in
//! `scenes/` (from `../shared/scenes`, answers in `scenes/expected.json`) and
//! analytic cases made here. Tolerances are stated per test; the errors
//! actually reached are in docs/accuracy.md.

mod common;

use common::*;
use radbake::radiosity::form_factors::analytic;
use radbake::{BakeConfig, Silent};

fn load(path: &std::path::Path) -> radbake::scene::Scene {
    radbake::scene::load(path, &Default::default()).expect("scene loads")
}

fn instance_mean(bake: &radbake::Bake, node: &str) -> f32 {
    let r = bake.instance_reports();
    let i = r
        .iter()
        .find(|i| i.node == node)
        .unwrap_or_else(|| panic!("no instance {node}"));
    assert!(i.texels > 0, "{node} has no texels");
    // Grey scenes: all channels equal.
    assert!((i.mean[0] - i.mean[1]).abs() < 1e-6 && (i.mean[1] - i.mean[2]).abs() < 1e-6);
    i.mean[0]
}

fn rel_err(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}

/// Furnace: a closed box, ρ = 0.5, E = 1 everywhere: B = E/(1−ρ) = 2 at every
/// texel. Tolerance: every texel within 1 %.
#[test]
fn furnace_box_every_texel_is_two() {
    let scene = load(&scene_path("furnace_box.gltf"));
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    let want = expected()["furnace_box.gltf"]["lightmap_everywhere"]
        .as_f64()
        .unwrap() as f32;
    let mut worst = 0.0f32;
    for v in &bake.maps.lightmaps.texel_values {
        for c in 0..3 {
            worst = worst.max((v[c] - want).abs() / want);
        }
    }
    assert!(worst < 0.01, "worst texel off by {:.3} %", worst * 100.0);
    // A closed cube: every ray lands on a patch, every row of F sums to 1.
    for (i, s) in bake
        .patch_light()
        .expect("radiosity")
        .row_sums
        .iter()
        .enumerate()
    {
        assert!((s - 1.0).abs() < 1e-4, "row {i} sums to {s}");
    }
    assert_eq!(
        bake.patch_light().expect("radiosity").stats.escaped
            + bake.patch_light().expect("radiosity").stats.unmapped,
        0
    );
}

/// Howell C-11: receiver mean = F = 0.199825 within 2 %.
#[test]
fn parallel_plates_receiver_mean() {
    let scene = load(&scene_path("parallel_plates.gltf"));
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    let want = expected()["parallel_plates.gltf"]["receiver_area_mean"]
        .as_f64()
        .unwrap();
    let got = instance_mean(&bake, "receiver") as f64;
    assert!(
        rel_err(got, want) < 0.02,
        "receiver mean {got}, Howell {want}"
    );
    assert!((want - analytic::parallel_rectangles(1.0, 1.0, 1.0)).abs() < 1e-9);
    // CSR rows sum to at most 1 (+ rounding).
    assert!(bake
        .patch_light()
        .expect("radiosity")
        .row_sums
        .iter()
        .all(|&s| s <= 1.0 + 1e-5));
}

/// Howell C-14: receiver mean = F = 0.200044 within 2 %.
#[test]
fn perpendicular_plates_receiver_mean() {
    let scene = load(&scene_path("perpendicular_plates.gltf"));
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    let want = expected()["perpendicular_plates.gltf"]["receiver_area_mean"]
        .as_f64()
        .unwrap();
    let got = instance_mean(&bake, "receiver") as f64;
    assert!(
        rel_err(got, want) < 0.02,
        "receiver mean {got}, Howell {want}"
    );
    assert!((want - analytic::perpendicular_rectangles(1.0, 1.0, 1.0)).abs() < 1e-9);
}

/// Unequal geometry, our own case: a 2 × 1 m emitter 0.5 m above a 2 × 1 m
/// receiver (Howell C-11 with X = 4, Y = 2), and a 1 × 0.5 m wall meeting a
/// 1 × 1.5 m floor (C-14 with W ≠ H). Within 1 %.
#[test]
fn unequal_rectangles() {
    let dir = temp_dir("unequal");
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let black = b.material([0.0; 3], [0.0; 3]);
    // Parallel pair, facing each other (receiver faces +y, emitter −y).
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [2.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("receiver", m);
    let (p, i) = quad([0.0, 0.5, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("emitter", m);
    // Perpendicular pair far away: floor 1 (x, common edge) × 1.5 (z), wall 1 × 0.5 (y) at z = 0 facing +z.
    let (p, i) = quad([10.0, 0.0, 0.0], [0.0, 0.0, 1.5], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(black));
    b.node("floor", m);
    let (p, i) = quad([10.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.5, 0.0]);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("wall", m);
    let path = dir.join("unequal.gltf");
    b.write(&path);
    let scene = load(&path);
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();

    let parallel = analytic::parallel_rectangles(2.0, 1.0, 0.5);
    let got = instance_mean(&bake, "receiver") as f64;
    assert!(
        rel_err(got, parallel) < 0.01,
        "parallel receiver {got}, Howell {parallel}"
    );
    // F(floor → wall): the floor is `w` = 1.5 wide, the wall `h` = 0.5, common edge 1.
    let perpendicular = analytic::perpendicular_rectangles(1.0, 1.5, 0.5);
    let got = instance_mean(&bake, "floor") as f64;
    assert!(
        rel_err(got, perpendicular) < 0.01,
        "floor {got}, Howell {perpendicular}"
    );
}

/// Coaxial disks (Howell C-41): emitter r = 0.5 m at 1 m above a receiver of
/// r = 0.75 m: receiver mean = F(receiver → emitter) within 1 %.
#[test]
fn coaxial_disks() {
    let dir = temp_dir("disks");
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let black = b.material([0.0; 3], [0.0; 3]);
    let (p, i) = disk(0.5, 1.0, false, 96);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("emitter", m);
    let (p, i) = disk(0.75, 0.0, true, 96);
    let m = b.mesh(&p, &i, Some(black));
    b.node("receiver", m);
    let path = dir.join("disks.gltf");
    b.write(&path);
    let scene = load(&path);
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    // Polygonal disks: use their true area-equivalent radii.
    let polygon_radius = |r: f64| {
        r * ((96.0 / (2.0 * std::f64::consts::PI)) * (2.0 * std::f64::consts::PI / 96.0).sin())
            .sqrt()
    };
    let want = analytic::coaxial_disks(polygon_radius(0.75), polygon_radius(0.5), 1.0);
    let got = instance_mean(&bake, "receiver") as f64;
    assert!(rel_err(got, want) < 0.01, "receiver {got}, Howell {want}");
}

/// A furnace with curved, seamed charts: the inside of a UV sphere, ρ = 0.5,
/// E = 1 → every texel 2.0 within 1 %.
#[test]
fn sphere_furnace() {
    let dir = temp_dir("sphere");
    let mut b = GltfBuilder::default();
    let m = b.material([0.5; 3], [1.0; 3]);
    let (p, i) = sphere(1.0, 24, 48, true);
    let mesh = b.mesh(&p, &i, Some(m));
    b.node("sphere", mesh);
    let path = dir.join("sphere.gltf");
    b.write(&path);
    let scene = load(&path);
    assert!(
        scene.stats.degenerate_triangles > 0,
        "pole triangles are degenerate and dropped"
    );
    let config = BakeConfig {
        texels_per_meter: 40.0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let worst = bake
        .maps
        .lightmaps
        .texel_values
        .iter()
        .map(|v| (v.x - 2.0).abs() / 2.0)
        .fold(0.0f32, f32::max);
    assert!(worst < 0.01, "worst texel off by {:.3} %", worst * 100.0);
    assert_eq!(bake.texels.chart_overlaps, 0);
}

/// Cornell box: no closed form. Checked: every instance gets texels; no
/// texel is shared by two charts and every triangle is mapped; every value is
/// finite and non-negative; the light is the only emitter and its patches
/// carry its radiance (17, 12, 4); the power balance closes (light arriving
/// = absorbed + reflected light escaping through the open front) within 1 %;
/// the light's power landing on surfaces estimated by shooting (its form
/// factors) and by gathering (per-texel direct sampling) agree within 1 %;
/// reciprocity A_I F_IJ = A_J F_JI holds between instances.
#[test]
fn cornell_box_sane() {
    let scene = load(&scene_path("cornell_box.gltf"));
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    let reports = bake.instance_reports();
    assert_eq!(reports.len(), 8);
    for r in &reports {
        assert!(r.texels > 100, "{} has {} texels", r.node, r.texels);
        assert!(
            r.mean.iter().all(|&m| m.is_finite() && m > 0.0),
            "{}: {:?}",
            r.node,
            r.mean
        );
    }
    assert_eq!(bake.texels.chart_overlaps, 0);
    assert_eq!(bake.texels.unmapped_triangles, 0);
    assert_eq!(bake.patch_light().expect("radiosity").stats.unmapped, 0);
    assert!(bake.maps.lightmaps.pages[0]
        .iter()
        .all(|v| v.is_finite() && v.min_element() >= 0.0));
    let emitters: Vec<_> = bake
        .patches
        .emission
        .iter()
        .filter(|e| e.max_element() > 0.0)
        .collect();
    assert!(!emitters.is_empty());
    for e in emitters {
        assert!(
            (e.x - 17.0).abs() < 1e-3 && (e.y - 12.0).abs() < 1e-3 && (e.z - 4.0).abs() < 1e-3,
            "{e}"
        );
    }
    let energy = bake.energy();
    for c in 0..3 {
        // Reflected light is absorbed or escapes.
        assert!(energy.relative_imbalance[c].abs() < 0.01, "{energy:?}");
        // Two independent estimates of the light's power that lands on
        // surfaces: shooting (the light's form-factor rows) and gathering
        // (per-texel direct sampling) agree within 1 %.
        let (shot, gathered) = (energy.emitted_landing[c], energy.direct_received[c]);
        assert!((shot - gathered).abs() < 0.01 * shot, "{energy:?}");
        // The open front lets 10-30 % of the light out.
        assert!(
            shot < 0.9 * energy.emitted[c] && shot > 0.7 * energy.emitted[c],
            "{energy:?}"
        );
        assert!(energy.reflected_escaped[c] > 0.0);
    }
    // Reciprocity between instances: A_I F_IJ = A_J F_JI where F_IJ > 0.05
    // (A: the exposed area, which shoots and receives; not what lies under
    // the blocks),
    // within 3 % or four standard errors of the two ray estimates, whichever
    // is larger (the light has 11 patches: its F to the short block rests on
    // ~150 of its 2,816 rays, σ ≈ 12 %; binomial errors, which stratified
    // rays beat, so the bound is loose, never tight).
    let p = &bake.patches;
    let n = scene.instances.len();
    let rays_per_patch = BakeConfig::default().rays_per_patch as f64;
    let mut rays = vec![0.0f64; n];
    for k in &p.key {
        rays[k.0 as usize] += rays_per_patch;
    }
    let mut af = vec![vec![0.0f64; n]; n];
    for (i, row) in bake
        .patch_light()
        .and_then(|p| p.form_factors.as_ref())
        .unwrap()
        .matrix
        .rows()
        .enumerate()
    {
        for (j, v) in row.iter() {
            let j = j as usize;
            af[p.key[i].0 as usize][p.key[j].0 as usize] += p.exposed_area[i] as f64 * v as f64;
        }
    }
    let mut checked = 0;
    for a in 0..n {
        for b in a + 1..n {
            if af[a][b] > 0.05 * reports[a].area {
                let err = (af[a][b] - af[b][a]).abs() / af[a][b];
                // Relative standard error of a binomial fraction F from N rays.
                let se = |i: usize, f: f64| ((1.0 - f).max(0.0) / (f * rays[i])).sqrt();
                let (fab, fba) = (af[a][b] / reports[a].area, af[b][a] / reports[b].area);
                let sigma = (se(a, fab).powi(2) + se(b, fba).powi(2)).sqrt();
                assert!(
                    err < (4.0 * sigma).max(0.03),
                    "{} / {}: {} vs {} (σ {:.3})",
                    reports[a].node,
                    reports[b].node,
                    af[a][b],
                    af[b][a],
                    sigma
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 10, "only {checked} pairs checked");
}

/// The same bake on 1 and on 2 threads gives bit-identical lightmaps.
#[test]
fn deterministic_across_thread_counts() {
    let scene = load(&scene_path("cornell_box.gltf"));
    let run = |threads| {
        on_threads(threads, || {
            let b = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
            let probes = b.probes.as_ref().expect("probes on by default");
            (
                b.maps.lightmaps.pages.clone(),
                probes.sh.clone(),
                probes.valid.clone(),
            )
        })
    };
    let one = run(1);
    let two = run(2);
    assert!(one.0 == two.0, "lightmaps differ between 1 and 2 threads");
    assert!(
        one.1 == two.1 && one.2 == two.2,
        "probes differ between 1 and 2 threads"
    );
}
