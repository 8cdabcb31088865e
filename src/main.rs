//! `radbake` command line: parses the arguments and dispatches to one
//! subcommand of [`cli`]; a thin layer over [`radbake::bake`].
//!
//! Exit codes: 0 success (or already up to date), 1 bad input (scene or
//! settings), 2 usage error, 3 I/O or internal error.

#[cfg(feature = "cli")]
mod cli;

#[cfg(feature = "cli")]
fn main() -> std::process::ExitCode {
    cli::app::main()
}

/// Built without the `cli` feature: the library only.
#[cfg(not(feature = "cli"))]
fn main() -> std::process::ExitCode {
    eprintln!("radbake was built without the `cli` feature (cargo build --features cli)");
    std::process::ExitCode::from(2)
}
