//! `radbake combine`: a bake's light layers recombined at new weights
//! ([`radbake::output::combine`]), written as a bake folder.

use super::{lib_err, Outcome};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct CombineArgs {
    /// A bake folder whose scene names light layers (its manifest.json lists `layers`).
    pub bake: PathBuf,
    /// A weight per layer: `NAME=W` or `NAME=R,G,B` (linear, ≥ 0); a layer not named keeps 1.
    #[arg(value_name = "NAME=WEIGHT", value_parser = parse_weight)]
    pub weights: Vec<(String, [f32; 3])>,
    /// The folder to write (not the bake folder itself).
    #[arg(long)]
    pub out: PathBuf,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn parse_weight(s: &str) -> Result<(String, [f32; 3]), String> {
    radbake::output::combine::parse_weight(s)
        .map(|(name, w)| (name, w.to_array()))
        .map_err(|e| e.to_string())
}

/// Recombines `args.bake` into `args.out`.
pub fn run(args: &CombineArgs) -> Outcome {
    let weights: Vec<_> = (args.weights.iter())
        .map(|(n, w)| (n.clone(), glam::Vec3::from_array(*w)))
        .collect();
    let written =
        radbake::output::combine::combine(&args.bake, &weights, &args.out).map_err(lib_err)?;
    if !args.quiet {
        println!("wrote {} files to {}", written.len(), args.out.display());
    }
    Ok(())
}
