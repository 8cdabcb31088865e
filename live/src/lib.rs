//! Live radiosity for radbake bakes: the sun moves and its bounce light
//! follows, solved at run time from the baked form factors (as Enlighten
//! does: precomputed transport between surface patches, the radiosity
//! system solved for the current lights; Martin & Einarsson 2010).
//!
//! A live bake (`radbake bake --live`) puts its live (directional) lights
//! in a light layer of their own, whose pages hold their bounced light
//! only (the engine draws their direct light, with its shadows, as for an
//! `indirect` light), and writes `live.bin` ([`format`]): the patches'
//! form factors F and albedo ρ, each patch's direct light from a unit sun
//! for a grid of directions ([`directions`]), and how texels are made from
//! patches. [`Live::update`] then, for a new sun:
//!
//! 1. D = Σₖ wₖ Vₖ × E: the patches' direct light (irradiance / π),
//!    interpolated between the four precomputed directions around the sun;
//! 2. L = ρ ⊙ (D + F L) by Jacobi iteration from the previous L, until
//!    Σ|ΔL| / Σ|L| is below the bake's tolerance;
//! 3. the texels' bounce light F L, reconstructed from the patches as the
//!    bake's first pass does.
//!
//! The result replaces the live layer's pages, and [`Live::probe_delta`]
//! moves the live layer's probes with it ([`probes`]); the other layers (the sky's,
//! scaled by a new sky colour, and everything else) stay as baked.
//! Texels hold incident irradiance / π, as every radbake lightmap.

pub mod directions;
pub mod format;
pub mod probes;
mod solve;

pub use format::{Header, LiveData, LiveLight, PageSize, SkyLayer};
pub use solve::{Live, Solve, Sun};

/// What can go wrong.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The file cannot be read.
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    /// The file is not a valid `live.bin`.
    #[error("{path}: {message}")]
    Malformed { path: String, message: String },
    /// A run-time input that cannot be used (a zero or NaN direction).
    #[error("{0}")]
    Input(String),
}

/// This crate's results.
pub type Result<T> = std::result::Result<T, LiveError>;
