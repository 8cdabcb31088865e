//! Where probes go: regular grids over boxes. A box is the unit cube
//! [−½, ½]³ under a world transform (as Bevy's `IrradianceVolume` is), and
//! a grid of resolution R puts probe (i, j, k) at the centre of its cell,
//! local ((i, j, k) + ½)/R − ½: exactly the voxel centres Bevy 0.19's
//! shader samples (`stp = clamp((p + 0.5) · R, 0.5, R − 0.5)`).
//!
//! The boxes are the scene's `probe_volume` nodes, or one box over the
//! scene's bounds. The spacing is the node's, else `probe_spacing`; when
//! the grids together would exceed `probe_budget`, every spacing grows by
//! one factor until they fit.

pub use crate::scene::probe_volume::VolumeSpec;
use glam::{Mat4, UVec3, Vec3};

/// One probe grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// The node's name, or `scene` for the automatic box.
    pub name: String,
    /// World from the unit cube [−½, ½]³.
    pub world_from_box: Mat4,
    /// Probes per axis.
    pub resolution: UVec3,
    /// Index of this grid's first probe among all probes.
    pub first: usize,
}

impl Volume {
    /// Probes in the grid.
    pub fn len(&self) -> usize {
        (self.resolution.x * self.resolution.y * self.resolution.z) as usize
    }

    /// True for a grid without probes (never made by [`place`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Grid coordinates of probe `i` of this grid (x fastest, then y, z).
    pub fn coords(&self, i: usize) -> UVec3 {
        let r = self.resolution;
        let i = i as u32;
        UVec3::new(i % r.x, (i / r.x) % r.y, i / (r.x * r.y))
    }

    /// Index in this grid of the probe at `c`.
    pub fn index(&self, c: UVec3) -> usize {
        let r = self.resolution;
        (c.x + r.x * (c.y + r.y * c.z)) as usize
    }

    /// World position of probe `i` of this grid.
    pub fn position(&self, i: usize) -> Vec3 {
        let local = (self.coords(i).as_vec3() + 0.5) / self.resolution.as_vec3() - 0.5;
        self.world_from_box.transform_point3(local)
    }

    /// World point `p` in the box's unit-cube coordinates ([−½, ½]³ inside).
    pub fn to_local(&self, p: Vec3) -> Vec3 {
        self.world_from_box.inverse().transform_point3(p)
    }

    /// Edge lengths of the box (metres).
    pub fn size(&self) -> Vec3 {
        box_size(&self.world_from_box)
    }
}

/// Edge lengths of the box `world_from_box` maps the unit cube to.
fn box_size(m: &Mat4) -> Vec3 {
    Vec3::new(
        m.x_axis.truncate().length(),
        m.y_axis.truncate().length(),
        m.z_axis.truncate().length(),
    )
}

/// Cells per axis for a box of edge lengths `size` at `spacing`: at least
/// one, and no cell longer than the spacing.
fn resolution(size: Vec3, spacing: f32) -> UVec3 {
    let per = |e: f32| ((e / spacing).ceil() as u32).clamp(1, 1 << 16);
    UVec3::new(per(size.x), per(size.y), per(size.z))
}

fn count(r: UVec3) -> u64 {
    r.x as u64 * r.y as u64 * r.z as u64
}

/// The probe grids: over `specs`, or, without any, over the scene's
/// `bounds` (min, max). `spacing` is the default spacing; `budget` the most
/// probes in all. Returns the grids and the factor (≥ 1) by which the
/// budget coarsened every spacing.
pub fn place(
    bounds: (Vec3, Vec3),
    specs: &[VolumeSpec],
    spacing: f32,
    budget: u32,
) -> (Vec<Volume>, f32) {
    let boxes: Vec<(String, Mat4, f32)> = if specs.is_empty() {
        let (lo, hi) = bounds;
        let size = (hi - lo).max(Vec3::splat(1e-3));
        let m = Mat4::from_translation((lo + hi) * 0.5) * Mat4::from_scale(size);
        vec![("scene".to_owned(), m, spacing)]
    } else {
        specs
            .iter()
            .map(|s| {
                let sp = s.spacing.unwrap_or(spacing);
                (s.name.clone(), s.world_from_box, sp)
            })
            .collect()
    };
    let budget = budget.max(boxes.len() as u32) as u64;
    let total = |f: f32| -> u64 {
        boxes
            .iter()
            .map(|(_, m, sp)| count(resolution(box_size(m), sp * f)))
            .sum()
    };
    let mut factor = 1.0f32;
    if total(factor) > budget {
        // Start from the volume ratio, then grow in 1 % steps (the counts
        // are step functions of the spacing).
        factor = (total(1.0) as f32 / budget as f32).cbrt();
        while total(factor) > budget {
            factor *= 1.01;
        }
    }
    let mut first = 0;
    let volumes = boxes
        .into_iter()
        .map(|(name, m, sp)| {
            let v = Volume {
                name,
                resolution: resolution(box_size(&m), sp * factor),
                world_from_box: m,
                first,
            };
            first += v.len();
            v
        })
        .collect();
    (volumes, factor)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_bounds_hold_the_box() {
        let spec = |m: Mat4| VolumeSpec {
            name: "v".into(),
            world_from_box: m,
            spacing: None,
        };
        let m = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))
            * Mat4::from_scale(Vec3::new(2.0, 4.0, 6.0));
        let (lo, hi) = spec(m).world_bounds();
        assert!(
            (lo - Vec3::new(0.0, 0.0, 0.0)).abs().max_element() < 1e-6,
            "{lo}"
        );
        assert!(
            (hi - Vec3::new(2.0, 4.0, 6.0)).abs().max_element() < 1e-6,
            "{hi}"
        );
        // A unit cube turned 45° about Y spans √2 in x and z.
        let (lo, hi) = spec(Mat4::from_rotation_y(std::f32::consts::FRAC_PI_4)).world_bounds();
        let r = std::f32::consts::SQRT_2 / 2.0;
        assert!(
            (hi - Vec3::new(r, 0.5, r)).abs().max_element() < 1e-6,
            "{hi}"
        );
        assert!((lo + hi).abs().max_element() < 1e-6);
    }

    #[test]
    fn probes_sit_at_cell_centres_inside_the_bounds() {
        let (v, f) = place((Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0)), &[], 1.0, 1000);
        assert_eq!(f, 1.0);
        assert_eq!(v[0].resolution, UVec3::new(4, 2, 1));
        assert_eq!(v[0].position(0), Vec3::new(0.5, 0.5, 0.5));
        assert_eq!(v[0].position(7), Vec3::new(3.5, 1.5, 0.5));
        for i in 0..v[0].len() {
            assert_eq!(v[0].index(v[0].coords(i)), i);
        }
    }

    #[test]
    fn the_budget_coarsens_every_grid() {
        let spec = |name: &str, x: f32| VolumeSpec {
            name: name.into(),
            world_from_box: Mat4::from_translation(Vec3::X * x)
                * Mat4::from_scale(Vec3::splat(10.0)),
            spacing: Some(0.5),
        };
        let (v, f) = place(
            (Vec3::ZERO, Vec3::ONE),
            &[spec("a", 0.0), spec("b", 20.0)],
            1.0,
            2000,
        );
        let total: usize = v.iter().map(Volume::len).sum();
        assert!(total <= 2000 && total > 1000, "{total}");
        assert!(f > 1.0);
        assert_eq!(v[1].first, v[0].len());
    }
}
