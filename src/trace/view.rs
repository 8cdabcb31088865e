//! The pinhole camera that images are rendered through (by the path
//! tracer and BDPT): from a glTF camera, a look-at, or a framing of the
//! scene.

use crate::layout::geometry::Geometry;
use crate::scene::Camera;
use glam::{Vec2, Vec3};

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Eye position (world).
    pub eye: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit right vector.
    pub right: Vec3,
    /// Unit up vector.
    pub up: Vec3,
    /// tan(yfov / 2).
    pub tan_half_y: f32,
}

impl View {
    /// Looking from `eye` at `target` with +Y up and vertical field of view `yfov`.
    pub fn look_at(eye: Vec3, target: Vec3, yfov: f32) -> View {
        let forward = (target - eye).normalize_or(Vec3::NEG_Z);
        let up_hint = if forward.y.abs() > 0.999 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let right = forward.cross(up_hint).normalize();
        View {
            eye,
            forward,
            right,
            up: right.cross(forward),
            tan_half_y: (yfov * 0.5).tan(),
        }
    }

    /// A glTF camera (looks down its −Z, +Y up).
    pub fn from_camera(camera: &Camera) -> View {
        let m = camera.world_from_camera;
        let eye = m.transform_point3(Vec3::ZERO);
        let forward = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
        let right = m.transform_vector3(Vec3::X).normalize_or(Vec3::X);
        View {
            eye,
            forward,
            right,
            up: right.cross(forward).normalize_or(Vec3::Y),
            tan_half_y: (camera.yfov * 0.5).tan(),
        }
    }

    /// The whole scene in view: from the front-top of its bounding sphere.
    pub fn framing(geometry: &Geometry, yfov: f32) -> View {
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for p in geometry.p_ws.iter().flatten() {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if lo.x > hi.x {
            return View::look_at(Vec3::Z, Vec3::ZERO, yfov);
        }
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let distance = radius / (yfov * 0.5).sin();
        View::look_at(
            centre + Vec3::new(0.0, 0.25, 1.0).normalize() * distance,
            centre,
            yfov,
        )
    }

    /// The film point in [−1, 1]² (y up) where world point `p` is seen,
    /// if it is in front of the camera and inside the frame.
    pub fn project(&self, p: Vec3, aspect: f32) -> Option<Vec2> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let x = d.dot(self.right) / (z * self.tan_half_y * aspect);
        let y = d.dot(self.up) / (z * self.tan_half_y);
        (x.abs() <= 1.0 && y.abs() <= 1.0).then_some(Vec2::new(x, y))
    }

    /// Unit direction through film point `ndc` ∈ [−1, 1]² (y up) for an
    /// image of aspect ratio `aspect` = width / height.
    pub fn ray(&self, ndc: Vec2, aspect: f32) -> Vec3 {
        (self.forward
            + self.right * (ndc.x * self.tan_half_y * aspect)
            + self.up * (ndc.y * self.tan_half_y))
            .normalize()
    }
}
