//! Bakes the shipped reference scenes with every form-factor method and
//! solver and prints the error against their exact answers and the time
//! taken (the accuracy table of docs/accuracy.md):
//!
//!     cargo run --release --example validate [-- bake.toml]
//!
//! Settings come from the optional TOML file (default settings otherwise);
//! `form_factors` and `solver` are overridden in turn.

use radbake::config::{FormFactorMethod, Solver};
use radbake::{BakeConfig, Silent};
use std::path::Path;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let base = match std::env::args().nth(1) {
        Some(p) => BakeConfig::from_toml(&std::fs::read_to_string(p)?)?,
        None => BakeConfig::default(),
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let expected: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("expected.json"))?)?;
    println!("| scene | form factors | solver | exact | radbake (mean) | error | worst texel error | time |");
    println!("|---|---|---|---|---|---|---|---|");
    for (file, node, key) in [
        ("furnace_box.gltf", "box", "lightmap_everywhere"),
        ("parallel_plates.gltf", "receiver", "receiver_area_mean"),
        (
            "perpendicular_plates.gltf",
            "receiver",
            "receiver_area_mean",
        ),
    ] {
        let scene = radbake::scene::load(&dir.join(file), &Default::default())?;
        let exact = expected[file][key].as_f64().unwrap_or(f64::NAN);
        for method in [FormFactorMethod::Raycast, FormFactorMethod::Hemicube] {
            for solver in [
                Solver::Jacobi,
                Solver::GaussSeidel,
                Solver::Progressive,
                Solver::Direct,
            ] {
                let config = BakeConfig {
                    form_factors: method,
                    solver,
                    ..base.clone()
                };
                let t = Instant::now();
                let bake = match radbake::bake(&scene, &config, &Silent) {
                    Ok(b) => b,
                    Err(e) => {
                        println!("| {file} | {method:?} | {solver:?} | {exact:.6} | refused: {e} | | | |");
                        continue;
                    }
                };
                let secs = t.elapsed().as_secs_f64();
                let got = bake
                    .instance_reports()
                    .iter()
                    .find(|r| r.node == node)
                    .map_or(f64::NAN, |r| r.mean[0] as f64);
                let worst = if file == "furnace_box.gltf" {
                    let w = bake
                        .maps
                        .lightmaps
                        .texel_values
                        .iter()
                        .map(|v| ((v.x as f64) - exact).abs() / exact)
                        .fold(0.0, f64::max);
                    format!("{:.3} %", 100.0 * w)
                } else {
                    String::new()
                };
                println!(
                    "| {file} | {method:?} | {solver:?} | {exact:.6} | {got:.6} | {:+.3} % | {worst} | {secs:.2} s |",
                    100.0 * (got - exact) / exact
                );
            }
        }
    }
    Ok(())
}
