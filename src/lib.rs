//! # radbake — a radiosity lightmap baker for glTF 2.0 scenes
//!
//! The bake is a pipeline of plain data, one module per stage; [`bake`]
//! ([`pipeline`]) reads top to bottom as this data flow:
//!
//! ```text
//! Scene ─► Atlas ─► Geometry ─► Texels ─► Patches ─► RayCaster ─► TexelLight ─────────► Maps ──────► files
//! scene    atlas    geometry    texels    patches    raycast      light transport:      lightmap,    output
//!                                                                 radiosity (form_factors, seams
//!                                                                 direct, solve, gather,
//!                                                                 denoise) | trace | photon
//! ```
//!
//! It solves the discrete radiosity equation (Goral, Torrance, Greenberg &
//! Battaile 1984) for Lambertian surfaces, in radiance form:
//! Lᵢ = Eᵢ + ρᵢ Σⱼ Fᵢⱼ Lⱼ.
//!
//! **Units and the lightmap convention.** glTF emissive (`emissiveFactor` ×
//! `KHR_materials_emissive_strength`) is emitted radiance. A lightmap texel
//! holds *incident irradiance / π* (linear RGB), so a Lambertian surface's
//! outgoing radiance is `albedo × lightmap + emission`.
//!
//! ```no_run
//! let scene = radbake::scene::load("scene.gltf".as_ref(), &Default::default())?;
//! let bake = radbake::bake(&scene, &radbake::BakeConfig::default(), &radbake::Silent)?;
//! radbake::output::write_lightmaps("out".as_ref(), &bake.maps.lightmaps)?;
//! radbake::output::write_report("out".as_ref(), &bake.report("scene.gltf"))?;
//! # Ok::<(), radbake::Error>(())
//! ```

#[cfg(feature = "gpu")]
pub mod adapter;
pub mod atlas;
pub mod burial;
pub mod config;
pub mod denoise;
pub mod direct;
pub mod error;
pub mod form_factors;
pub mod gather;
pub mod geometry;
pub mod incremental;
pub mod lightmap;
pub mod measure;
pub mod nee;
pub mod output;
pub mod patches;
pub mod photon;
pub mod pipeline;
#[cfg(feature = "preview")]
pub mod preview;
pub mod probes;
pub mod progress;
pub mod raycast;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod sdf;
pub mod seams;
pub mod shadowmask;
pub mod shard;
pub mod sky;
pub mod solve;
pub mod texels;
pub mod trace;

pub use config::BakeConfig;
pub use error::{Error, Result};
pub use pipeline::{bake, bake_with, Bake};
pub use progress::{Progress, Silent, Snapshot};
