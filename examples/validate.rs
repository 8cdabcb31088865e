//! Bakes the shipped reference scenes with the given settings and prints the
//! error against their exact answers (the README's accuracy table):
//!
//!     cargo run --release --example validate [-- bake.toml]

use radbake::{BakeConfig, Silent};
use std::path::Path;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let config = match std::env::args().nth(1) {
        Some(p) => BakeConfig::from_toml(&std::fs::read_to_string(p)?)?,
        None => BakeConfig::default(),
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let expected: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("expected.json"))?)?;
    println!("| scene | quantity | exact | radbake | error | bake time |");
    println!("|---|---|---|---|---|---|");
    for (file, node, key) in [
        ("furnace_box.gltf", "box", "lightmap_everywhere"),
        ("parallel_plates.gltf", "receiver", "receiver_area_mean"),
        (
            "perpendicular_plates.gltf",
            "receiver",
            "receiver_area_mean",
        ),
    ] {
        let t = Instant::now();
        let scene = radbake::scene::load(&dir.join(file), &Default::default())?;
        let bake = radbake::bake(&scene, &config, &Silent)?;
        let secs = t.elapsed().as_secs_f64();
        let exact = expected[file][key].as_f64().unwrap_or(f64::NAN);
        let reports = bake.instance_reports();
        let got = reports
            .iter()
            .find(|r| r.node == node)
            .map_or(f64::NAN, |r| r.mean[0] as f64);
        println!(
            "| {file} | {node} mean | {exact:.6} | {got:.6} | {:+.3} % | {secs:.2} s |",
            100.0 * (got - exact) / exact
        );
        if file == "furnace_box.gltf" {
            let worst = bake
                .lightmaps
                .texel_values
                .iter()
                .map(|v| ((v.x as f64) - exact).abs() / exact)
                .fold(0.0, f64::max);
            println!(
                "| {file} | worst texel | {exact:.6} | | {:.3} % | |",
                100.0 * worst
            );
        }
    }
    Ok(())
}
