//! `radbake measure`: the independent irradiance meter
//! ([`radbake::trace::measure`]) from the command line, JSON out: the area-weighted
//! mean irradiance / π each node receives, with its standard error.

use super::{lib_err, parse_rgb, Outcome};
use clap::Args;
use radbake::trace::measure::{Meter, MeterNormal, MeterSettings};
use std::path::PathBuf;

#[derive(Args)]
pub struct MeasureArgs {
    /// The scene (.gltf or .glb).
    pub scene: PathBuf,
    /// Measure this node (repeatable) [default: every node with triangles].
    #[arg(long)]
    pub node: Vec<String>,
    /// Sample points per node (one path each).
    #[arg(long, default_value_t = 100_000)]
    pub samples: u64,
    /// Sky radiance `r,g,b` seen by rays leaving the scene (as `bake --sky`).
    #[arg(long, value_parser = parse_rgb, default_value = "0")]
    pub sky: [f32; 3],
    /// The normal of each sample point: the interpolated NORMAL, or the triangle's own.
    #[arg(long, value_enum, default_value = "shading")]
    pub normal: MeterNormal,
    /// Seed of the random sequences (readings are deterministic for a seed).
    #[arg(long, default_value_t = 0x5eed)]
    pub seed: u64,
    /// Write the JSON here (atomically) instead of to stdout.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
}

/// Measures the nodes of `args.scene` and prints (or writes) the readings.
pub fn run(args: &MeasureArgs) -> Outcome {
    if args.samples < 2 {
        return Err((1, "--samples must be at least 2".into()));
    }
    let scene = radbake::scene::load(&args.scene, &Default::default()).map_err(lib_err)?;
    let settings = MeterSettings {
        samples: args.samples,
        normal: args.normal,
        sky: args.sky.into(),
        seed: args.seed,
    };
    let readings = Meter::new(&scene)
        .measure(&args.node, &settings)
        .map_err(|e| (1, format!("{}: {e}", args.scene.display())))?;
    let json = serde_json::json!({
        "scene": args.scene.display().to_string(),
        "quantity": "area-weighted mean incident irradiance / pi (linear RGB), with its standard error",
        "samples_per_node": args.samples,
        "sky": args.sky,
        "seed": args.seed,
        "readings": readings,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| (3, e.to_string()))? + "\n";
    match &args.out {
        Some(path) => radbake::output::write_bytes_atomic(path, text.as_bytes())
            .map_err(|e| (3, e.to_string()))?,
        None => print!("{text}"),
    }
    Ok(())
}
