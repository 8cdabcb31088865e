//! The independent irradiance meter (`radbake::trace::measure`, `radbake
//! measure`): first checked against exact answers, then used as the oracle
//! for the bake's physical per-instance figure (`report.json`'s `mean`).
//! The meter shares no code with the atlas, texels, validity test or hole
//! filling, so a mistake there shows here.

mod common;

use common::{expected, scene_path};
use radbake::trace::measure::{Meter, MeterSettings, Reading};
use radbake::{BakeConfig, Silent};
use std::process::Command;

fn settings(samples: u64) -> MeterSettings {
    MeterSettings {
        samples,
        normal: Default::default(),
        sky: glam::Vec3::ZERO,
        seed: 7,
    }
}

fn grey(r: &Reading) -> (f64, f64) {
    let m = r.mean.iter().sum::<f64>() / 3.0;
    let se = (r.std_error.iter().map(|s| s * s).sum::<f64>()).sqrt() / 3.0;
    (m, se)
}

/// Exact answers: the furnace (2.0 everywhere, all bounces) and Howell's
/// parallel and perpendicular plates, within 4 standard errors.
#[test]
fn meter_reads_exact_answers() {
    let exp = expected();
    let cases = [
        (
            "furnace_box.gltf",
            None,
            exp["furnace_box.gltf"]["lightmap_everywhere"].as_f64(),
        ),
        (
            "parallel_plates.gltf",
            Some("receiver"),
            exp["parallel_plates.gltf"]["receiver_area_mean"].as_f64(),
        ),
        (
            "perpendicular_plates.gltf",
            Some("receiver"),
            exp["perpendicular_plates.gltf"]["receiver_area_mean"].as_f64(),
        ),
    ];
    for (file, node, want) in cases {
        let want = want.expect("expected value");
        let scene = radbake::scene::load(&scene_path(file), &Default::default()).unwrap();
        let nodes: Vec<String> = node.map(String::from).into_iter().collect();
        let readings = Meter::new(&scene)
            .measure(&nodes, &settings(200_000))
            .unwrap();
        assert!(!readings.is_empty());
        for r in &readings {
            let (m, se) = grey(r);
            assert!(se > 0.0 || want == 0.0, "{file} {}: no spread", r.node);
            assert!(
                (m - want).abs() <= 4.0 * se + 1e-9,
                "{file} {}: {m:.5} ± {se:.5}, exact {want:.5}",
                r.node
            );
        }
    }
}

/// The same seed gives the same readings whatever the thread count.
#[test]
fn meter_is_deterministic_across_threads() {
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| Meter::new(&scene).measure(&[], &settings(20_000)).unwrap())
    };
    assert_eq!(run(1), run(2));
}

/// Cornell: every mesh's `mean` (the light that arrives, buried parts at
/// what they receive) within 1 % of the meter or 3 standard errors,
/// whichever is larger, at 232 texels/m. The filled lightmap's mean is
/// kept apart: the floor's (buried under the blocks) reads well above.
#[test]
fn cornell_means_match_the_meter() {
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let config = BakeConfig {
        texels_per_meter: 232.0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent).unwrap();
    let readings = Meter::new(&scene).measure(&[], &settings(400_000)).unwrap();
    let reports = bake.instance_reports();
    assert_eq!(readings.len(), reports.len());
    for (r, m) in reports.iter().zip(&readings) {
        assert_eq!(r.node, m.node);
        let (want, se) = grey(m);
        let got = r.mean.iter().sum::<f32>() as f64 / 3.0;
        let bound = (0.01 * want).max(3.0 * se);
        assert!(
            (got - want).abs() <= bound,
            "{}: mean {got:.5}, meter {want:.5} ± {se:.5} ({:+.2} %)",
            r.node,
            100.0 * (got / want - 1.0)
        );
        assert!(r.valid_area <= r.area + 1e-9);
    }
    let floor = reports.iter().find(|r| r.node == "floor").unwrap();
    assert!(
        floor.valid_area < 0.9 * floor.area,
        "the blocks bury the floor"
    );
    let lm = floor.lightmap_mean.iter().sum::<f32>();
    let mean = floor.mean.iter().sum::<f32>();
    assert!(lm > 1.1 * mean, "filled {lm} vs arrived {mean}");
}

/// `radbake measure`: JSON on stdout with one reading per node asked for;
/// an unknown node is a one-line error naming it.
#[test]
fn measure_command_prints_json() {
    let exe = env!("CARGO_BIN_EXE_radbake");
    let scene = scene_path("cornell_box.gltf");
    let out = Command::new(exe)
        .args(["measure", "--node", "floor", "--samples", "2000"])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let readings = json["readings"].as_array().unwrap();
    assert_eq!(readings.len(), 1);
    assert_eq!(readings[0]["node"], "floor");
    assert_eq!(readings[0]["samples"], 2000);
    let bad = Command::new(exe)
        .args(["measure", "--node", "no_such_node"])
        .arg(&scene)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("no_such_node") && err.lines().count() == 1,
        "{err}"
    );
}
