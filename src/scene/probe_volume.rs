//! Probe volumes the user placed: a node with `extras.radbake.probe_volume`
//! is a box (the unit cube [−½, ½]³ under the node's world transform) that
//! [`crate::probes`] fills with a probe grid.

use glam::{Mat4, Vec3};

/// A box the user placed (a node with `extras.radbake.probe_volume`).
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeSpec {
    /// The node's name.
    pub name: String,
    /// World from the unit cube [−½, ½]³ (the node's world transform).
    pub world_from_box: Mat4,
    /// Probe spacing in metres, if the node sets one.
    pub spacing: Option<f32>,
}

impl VolumeSpec {
    /// The box's world bounds (min, max): the axis-aligned box around its
    /// eight corners (the box itself where the node is not rotated).
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for k in 0..8 {
            let corner = Vec3::new(
                (k & 1) as f32 - 0.5,
                ((k >> 1) & 1) as f32 - 0.5,
                ((k >> 2) & 1) as f32 - 0.5,
            );
            let p = self.world_from_box.transform_point3(corner);
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        (lo, hi)
    }
}
