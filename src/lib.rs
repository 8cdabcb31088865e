//! # radbake — a radiosity lightmap baker for glTF 2.0 scenes
//!
//! The bake is a pipeline of plain data, one module per stage, run in order
//! by [`bake`].
//!
//! The stages, their order and the rules between them are drawn once, in
//! `ARCHITECTURE.md` at the repository's root (the code map).
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
//! **The facade.** A build step needs only the names at the crate root
//! ([`load`], [`bake`], [`BakeConfig`], [`Bake`], [`incremental`],
//! [`measure`]) and the writers in [`output`]; the stage modules are public
//! only with the `internals` feature, which `cli` turns on.
//!
//! ```no_run
//! let scene = radbake::load("scene.gltf".as_ref(), &Default::default())?;
//! let bake = radbake::bake(&scene, &radbake::BakeConfig::default(), &radbake::Silent)?;
//! radbake::output::write_lightmaps("out".as_ref(), &bake.maps.lightmaps)?;
//! radbake::output::write_report("out".as_ref(), &bake.report("scene.gltf"))?;
//! # Ok::<(), radbake::Error>(())
//! ```

// ── The facade: what a build step needs (`examples/library.rs`). ─────────
pub mod config;
pub mod error;
pub mod output;
#[cfg(feature = "preview")]
pub mod preview;
pub mod scene;

// (`crate::` paths below: the stage modules are declared by `stages!`.)
pub use crate::maps::lightmap::Lightmaps;
pub use crate::pipeline::incremental;
pub use crate::pipeline::progress::{Progress, Silent, Snapshot};
pub use crate::pipeline::report::Report;
pub use crate::pipeline::{bake, bake_with, Bake, Maps};
pub use crate::probes::Probes;
/// The independent irradiance meter (`radbake measure`): a path-traced
/// estimate of what each instance receives that shares no atlas, texel or
/// fill code with the bake.
pub use crate::trace::measure;
pub use config::{BakeConfig, Preset};
pub use error::{Error, Result};
pub use scene::{load, LoadOptions, Scene};

// ── The stages. ──────────────────────────────────────────────────────────
// Public with the `internals` feature (which `cli` turns on, and so the
// tests, tools and benchmarks): every stage can be called on its own there.
// Without it they are private to the crate, and a dependency sees only the
// facade above. They are not a stable interface either way.
macro_rules! stages {
    ($($(#[$doc:meta])* $name:ident),* $(,)?) => {$(
        $(#[$doc])*
        #[cfg(feature = "internals")]
        pub mod $name;
        $(#[$doc])*
        #[cfg(not(feature = "internals"))]
        #[allow(dead_code, unused_imports)]
        mod $name;
    )*};
}
stages!(
    /// Atlas, geometry, texels, patches and the burial data.
    layout,
    /// The light-sampling library and the direct-light stage.
    light,
    /// Lightmap pages, seams and the shadowmask.
    maps,
    /// The stage order, transport dispatch, summary, shards and report.
    pipeline,
    /// Irradiance probes.
    probes,
    /// Form factors, the solvers, the final gather and the denoiser.
    radiosity,
    /// The BVH and the CPU/GPU ray casters.
    raycast,
    /// Signed distance fields.
    sdf,
    /// Surfaces, the burial stage and texel validity.
    surface,
    /// Path tracing, BDPT, photon mapping and the meter.
    trace,
    /// Sampling, the GPU adapter and atomic writes.
    util,
);
