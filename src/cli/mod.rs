//! The `radbake` subcommands, one file each: [`bake`], [`combine`], [`render`],
//! [`measure`], [`preview`] and [`serve`], with [`progress`] (bars or JSON lines). This file holds what
//! they share: viewpoint arguments, value parsers and exit codes.
//!
//! Exit codes: 0 success (or already up to date), 1 bad input (scene or
//! settings), 2 usage error, 3 I/O or internal error.

pub mod app;
pub mod bake;
pub mod combine;
pub mod measure;
#[cfg(feature = "preview")]
pub mod preview;
pub mod progress;
pub mod relight;
pub mod render;
pub mod sdf;
pub mod serve;
pub mod shard;

use clap::Args;

/// A subcommand's outcome: `Err((exit code, one-line message))`.
pub type Outcome = Result<(), (u8, String)>;

/// Where `render` and `preview` look from.
#[derive(Args)]
pub struct ViewArgs {
    /// The glTF camera of this name [default: the first camera, or a framing of the scene].
    #[arg(long, conflicts_with = "look_from")]
    pub camera: Option<String>,
    /// Eye position `x,y,z` (world, metres).
    #[arg(long, value_parser = parse_vec3)]
    pub look_from: Option<[f32; 3]>,
    /// Look towards `x,y,z` [default: the centre of the scene].
    #[arg(long, value_parser = parse_vec3, requires = "look_from")]
    pub look_at: Option<[f32; 3]>,
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| "expected WIDTHxHEIGHT, e.g. 1280x720".to_string())?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("`{v}`: {e}"));
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err("width and height must be 1..=16384".into());
    }
    Ok((w, h))
}

pub fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    match parse_rgb(s)? {
        v if s.split(',').count() == 3 => Ok(v),
        _ => Err("expected x,y,z".into()),
    }
}

/// Parses `r,g,b` (or one number for grey).
pub fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [g] => Ok([*g; 3]),
        [r, g, b] => Ok([*r, *g, *b]),
        _ => Err("expected r,g,b".into()),
    }
}

pub fn lib_err(e: radbake::Error) -> (u8, String) {
    (if e.is_input_error() { 1 } else { 3 }, e.to_string())
}

pub fn classify(e: &anyhow::Error) -> u8 {
    match e.downcast_ref::<radbake::Error>() {
        Some(le) if le.is_input_error() => 1,
        Some(_) => 3,
        None => 1,
    }
}
