//! Where light is stored: the lightmap atlas, the world-space triangles with
//! their lightmap coordinates, the texels and the patches.
//!
//! `Scene` → [`atlas::Atlas`] → [`geometry::Geometry`] →
//! [`texels::Texels`] → [`patches::Patches`].

pub mod atlas;
pub mod burial;
pub mod geometry;
pub mod patches;
pub mod texels;
