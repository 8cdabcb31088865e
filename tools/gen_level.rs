//! Writes a generated game level (a three-storey atrium: floors, outer
//! walls, finely tessellated columns and arches placed by nodes, emissive
//! wall lamps and a sun) as a `.glb` of about the requested triangle count,
//! for benchmarks and big-scene tests. Deterministic: the same count gives
//! the same bytes. The surface area does not change with the count, so
//! bakes of different sizes have about the same texels.
//!
//!     cargo run --release --example gen_level -- --triangles 250000 --out level.glb
//!     radbake bake level.glb --out out/level --texels-per-meter 8

#[path = "../tests/benches/common/level.rs"]
mod level;

use clap::Parser;
use std::path::PathBuf;

#[derive(Parser)]
#[command(about = "Write a generated atrium level (.glb) of about N triangles")]
struct Args {
    /// Target triangle count after instancing (the level gets the closest it can).
    #[arg(long, default_value_t = 250_000)]
    triangles: u64,
    /// Output .glb.
    #[arg(long, short, default_value = "level.glb")]
    out: PathBuf,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let level = level::generate(args.triangles);
    let (doc, bin) = level.to_gltf();
    let glb = radbake::output::baked::glb(&doc, &bin);
    radbake::output::write_bytes_atomic(&args.out, &glb)?;
    let unique: usize = level.meshes.iter().map(|m| m.triangles()).sum();
    eprintln!(
        "{}: {} triangles ({} unique in {} meshes, {} nodes; columns of {} segments), {:.1} MB",
        args.out.display(),
        level.triangle_count(),
        unique,
        level.meshes.len(),
        level.nodes.len(),
        level.column_segments,
        glb.len() as f64 / 1e6
    );
    Ok(())
}
