//! Using radbake as a library: load a scene, bake it with settings built in
//! Rust, and write every output.
//!
//!     cargo run --release --example library -- scenes/cornell_box.gltf out/library

use radbake::config::{BakeConfig, Solver};
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let scene_path = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "scenes/cornell_box.gltf".into()),
    );
    let out = PathBuf::from(args.next().unwrap_or_else(|| "out/library".into()));

    // Start from a preset, change what you need; `validate` names any bad key.
    let config = BakeConfig {
        texels_per_meter: 64.0,
        solver: Solver::GaussSeidel,
        sky: [0.0; 3],
        ..BakeConfig::preview()
    };
    config.validate()?;

    let mut scene = radbake::load(&scene_path, &Default::default())?;
    config.light_modes.apply(&mut scene)?;
    let bake = radbake::bake(&scene, &config, &radbake::Silent)?;
    for w in &bake.warnings {
        eprintln!("warning: {w}");
    }
    radbake::output::write_lightmaps(&out, &bake.maps.lightmaps)?;
    let stem = scene_path
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    radbake::output::write_engine_outputs(&out, &stem, &bake)?;
    radbake::output::write_report(&out, &bake.report(&scene_path.display().to_string()))?;

    // Per-instance results are plain data.
    for r in bake.instance_reports() {
        println!(
            "{:>20}: mean lightmap {:.4?} over {} texels, uv_rect {:?}",
            r.node, r.mean, r.texels, r.uv_rect
        );
    }
    Ok(())
}
