//! Utilities every layer may use: seeded sampling and the GPU adapter.
//! Nothing here knows of a scene or a bake.

#[cfg(feature = "gpu")]
pub mod adapter;
pub mod files;
pub mod sampling;
