//! `radbake relight`: a live bake relit for a new sun
//! ([`radbake::output::relight`]), written as a bake folder.

use super::{lib_err, parse_rgb, parse_vec3, Outcome};
use clap::Args;
use glam::Vec3;
use std::path::PathBuf;

#[derive(Args)]
pub struct RelightArgs {
    /// A live bake's folder (baked with --live or a light in mode `live`; its manifest lists `live`).
    pub bake: PathBuf,
    /// Direction towards the sun `x,y,z` (y up; any length > 0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub sun_direction: [f32; 3],
    /// The sun's irradiance `r,g,b` in W/m² (linear) [default: as baked].
    #[arg(long, value_parser = parse_rgb)]
    pub sun_irradiance: Option<[f32; 3]>,
    /// The sky's radiance `r,g,b` (a uniform sky in a layer of its own) [default: as baked].
    #[arg(long, value_parser = parse_rgb)]
    pub sky: Option<[f32; 3]>,
    /// A weight per other layer: `NAME=W` or `NAME=R,G,B`, as `radbake combine`'s.
    #[arg(long = "layer", value_name = "NAME=WEIGHT", value_parser = super::combine::parse_weight)]
    pub weights: Vec<(String, [f32; 3])>,
    /// The folder to write (not the bake folder itself).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Relights `args.bake` into `args.out`.
pub fn run(args: &RelightArgs) -> Outcome {
    let r = radbake::output::relight::Relight {
        sun_direction: Vec3::from_array(args.sun_direction),
        sun_irradiance: args.sun_irradiance.map(Vec3::from_array),
        sky: args.sky.map(Vec3::from_array),
        weights: (args.weights.iter())
            .map(|(n, w)| (n.clone(), Vec3::from_array(*w)))
            .collect(),
    };
    let (written, relit) =
        radbake::output::relight::relight(&args.bake, &r, &args.out).map_err(lib_err)?;
    if !args.quiet {
        println!(
            "relit in {:.1} ms ({} iterations, residual {:.2e}) → {} files in {}",
            relit.seconds * 1e3,
            relit.iterations,
            relit.residual,
            written.len(),
            args.out.display()
        );
    }
    Ok(())
}
