//! The `radbake` command: its argument parser and the dispatch to one
//! subcommand.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "radbake",
    version,
    about = "Radiosity lightmap baker for glTF 2.0 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake lightmaps for a .gltf/.glb scene.
    Bake(Box<crate::cli::bake::BakeArgs>),
    /// Recombine a bake's light layers at new weights into a bake folder, without a bake.
    Combine(crate::cli::combine::CombineArgs),
    /// Relight a live bake for a new sun direction (and sky) into a bake folder, without a bake.
    Relight(crate::cli::relight::RelightArgs),
    /// Look at a baked .glb in a window (or render it offscreen with --headless).
    #[cfg(feature = "preview")]
    Preview(crate::cli::preview::PreviewArgs),
    /// Path-trace an image of a scene: the reference, or the final pass over a bake's lightmaps.
    Render(crate::cli::render::RenderArgs),
    /// Measure the irradiance nodes receive, independently of any bake (JSON out).
    Measure(crate::cli::measure::MeasureArgs),
    /// Look at a bake in a browser: the three.js viewer and the bake's files on 127.0.0.1.
    Serve(crate::cli::serve::ServeArgs),
    /// Bake the scene's signed distance field (a KTX2 3D texture, metres).
    Sdf(crate::cli::sdf::SdfArgs),
    /// Split a bake into jobs for a batch scheduler (Slurm, Kubernetes, local) and merge them.
    #[command(subcommand)]
    Shard(crate::cli::shard::ShardCommand),
}

/// Parses the arguments and runs one subcommand.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    // A panic is a bug, never the input's fault: report it in one line, exit 3.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("error: internal error (a bug in radbake){at}: {msg}");
    }));
    let result = std::panic::catch_unwind(|| match &cli.command {
        Command::Bake(args) => crate::cli::bake::run(args),
        Command::Combine(args) => crate::cli::combine::run(args),
        Command::Relight(args) => crate::cli::relight::run(args),
        Command::Render(args) => crate::cli::render::run(args),
        Command::Measure(args) => crate::cli::measure::run(args),
        Command::Sdf(args) => crate::cli::sdf::run(args),
        Command::Serve(args) => crate::cli::serve::run(args),
        Command::Shard(cmd) => crate::cli::shard::run(cmd),
        #[cfg(feature = "preview")]
        Command::Preview(args) => crate::cli::preview::run(args),
    });
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err((code, msg))) => {
            eprintln!("error: {msg}");
            ExitCode::from(code)
        }
        Err(_) => ExitCode::from(3),
    }
}
