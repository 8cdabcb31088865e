//! `radbake sdf`: the level's signed distance field ([`radbake::sdf`]) as
//! a KTX2 3D texture (`R32_SFLOAT` or `R16_SFLOAT`, metres) and a JSON
//! sidecar with its world transform.

use super::{lib_err, Outcome};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct SdfArgs {
    /// The scene (.gltf or .glb).
    pub scene: PathBuf,
    /// The field, a KTX2 3D texture; its transform goes beside it (`<name>.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// Voxel edge in metres.
    #[arg(long, value_name = "M", conflicts_with = "resolution")]
    pub voxel_size: Option<f32>,
    /// Voxels along the scene's longest side [default: 128].
    #[arg(long, value_name = "N")]
    pub resolution: Option<u32>,
    /// Clamp distances at this many voxels (a narrow band; ≥ 2) [default: none].
    #[arg(long, value_name = "VOXELS")]
    pub band: Option<f32>,
    /// What the grid covers: the scene, or the union of its probe volumes' boxes (--resolution
    /// then counts voxels along that box's longest side) [default: scene].
    #[arg(long, value_enum, default_value = "scene")]
    pub bounds: radbake::config::SdfBounds,
    /// Texel format: r32f (32-bit floats) or r16f (half floats, half the size).
    #[arg(long, value_enum, default_value = "r32f")]
    pub format: radbake::config::SdfFormat,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Bakes and writes the field of `args.scene`.
pub fn run(args: &SdfArgs) -> Outcome {
    let start = Instant::now();
    let scene = radbake::scene::load(&args.scene, &Default::default()).map_err(lib_err)?;
    let geometry = radbake::layout::geometry::Geometry::unmapped(&scene);
    if geometry.is_empty() {
        return Err((1, format!("{}: no triangles", args.scene.display())));
    }
    let bounds = radbake::sdf::bounds(&scene, &geometry, args.bounds).ok_or_else(|| {
        (
            1,
            format!(
                "--bounds probe-volumes: {} has no probe volume (a node with extras.radbake.probe_volume)",
                args.scene.display()
            ),
        )
    })?;
    let voxel = match (args.voxel_size, args.resolution) {
        (Some(v), _) if v.is_finite() && v > 0.0 => v,
        (Some(v), _) => {
            return Err((
                1,
                format!("--voxel-size {v}: must be a positive number of metres"),
            ))
        }
        (None, Some(0)) => return Err((1, "--resolution must be at least 1".into())),
        (None, r) => radbake::sdf::voxel_for_resolution(bounds, r.unwrap_or(128)),
    };
    if let Some(b) = args.band.filter(|b| !b.is_finite() || *b < 2.0) {
        return Err((1, format!("--band {b}: must be at least 2 voxels")));
    }
    let grid = radbake::sdf::Grid::over(bounds, voxel);
    if grid.len() as u64 > radbake::sdf::MAX_VOXELS {
        return Err((
            1,
            format!(
                "{}: {} × {} × {} voxels, above the limit of {}; use a larger --voxel-size",
                args.scene.display(),
                grid.dims[0],
                grid.dims[1],
                grid.dims[2],
                radbake::sdf::MAX_VOXELS
            ),
        ));
    }
    let rays = radbake::raycast::RayCaster::new(&scene, &geometry);
    let settings = radbake::sdf::Settings {
        voxel,
        band: args.band,
    };
    let baked = Instant::now();
    let sdf = radbake::sdf::bake_over(&scene, &geometry, &rays, bounds, settings);
    let seconds = baked.elapsed().as_secs_f64();
    let files =
        radbake::output::sdf::write(&args.out, &sdf, args.band, args.format).map_err(lib_err)?;
    if !args.quiet {
        let [x, y, z] = sdf.grid.dims;
        let n = sdf.grid.len() as f64;
        eprintln!(
            "sdf: {x} × {y} × {z} voxels of {voxel:.4} m in {seconds:.2} s ({:.2} M voxels/s; {} sign rays); {:.2} s in all",
            n / seconds / 1e6,
            sdf.rays,
            start.elapsed().as_secs_f64()
        );
        let (flips, pairs) = sdf.open_air_flips(2.0);
        let inside = sdf.distance.iter().filter(|d| **d < 0.0).count();
        eprintln!(
            "sdf: {inside} voxels inside solids ({:.1} %); {flips} sign flips among {pairs} neighbour pairs more than 2 voxels from any surface",
            100.0 * inside as f64 / n
        );
        for f in files {
            eprintln!("wrote {}", f.display());
        }
    }
    Ok(())
}
