//! A build-script style bake: re-bake only when the scene, anything it
//! references, the settings or radbake itself changed (the content hash in
//! `bake.hash`), as a `build.rs` or an asset pipeline step would.
//!
//!     cargo run --release --example build_step -- scenes/cornell_box.gltf out/build_step

use radbake::incremental;
use radbake::BakeConfig;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let scene_path = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "scenes/cornell_box.gltf".into()),
    );
    let out = PathBuf::from(args.next().unwrap_or_else(|| "out/build_step".into()));
    // In a build.rs, tell cargo what to watch:
    println!("cargo:rerun-if-changed={}", scene_path.display());

    let config = BakeConfig::preview();
    let mut scene = radbake::scene::load(&scene_path, &Default::default())?;
    config.light_modes.apply(&mut scene)?;
    let hash = incremental::content_hash(&scene, &config);
    let stem = scene_path
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let glb = format!("{stem}.baked.glb");
    if incremental::up_to_date(&out, &hash, &["report.json", "manifest.json", &glb]) {
        println!("{}: up to date", out.display());
        return Ok(());
    }
    let bake = radbake::bake(&scene, &config, &radbake::Silent)?;
    radbake::output::write_lightmaps(&out, &bake.maps.lightmaps)?;
    radbake::output::write_engine_outputs(&out, &stem, &bake)?;
    radbake::output::write_report(&out, &bake.report(&scene_path.display().to_string()))?;
    incremental::record(&out, &hash)?; // last: marks the bake complete
    println!("{}: baked", out.display());
    Ok(())
}
