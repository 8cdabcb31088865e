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

pub mod config;
pub mod error;
pub mod layout;
pub mod light;
pub mod maps;
pub mod output;
pub mod pipeline;
#[cfg(feature = "preview")]
pub mod preview;
pub mod probes;
pub mod radiosity;
pub mod raycast;
pub mod scene;
pub mod sdf;
pub mod surface;
pub mod trace;
pub mod util;

pub use config::BakeConfig;
pub use error::{Error, Result};
pub use pipeline::progress::{Progress, Silent, Snapshot};
pub use pipeline::{bake, bake_with, Bake};
