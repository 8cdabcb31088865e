//! Orbit and fly cameras (right-handed, +Y up, looking down −Z like glTF).

use glam::{Mat4, Vec3, Vec4};

/// How the mouse and keys move the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Around a target: drag rotates, right/middle drag pans, wheel zooms.
    Orbit,
    /// First person: drag looks, WASD moves, Q/E down/up, Shift faster.
    Fly,
}

/// A perspective camera as yaw/pitch around +Y (yaw 0 looks down −Z).
#[derive(Clone, Debug)]
pub struct Camera {
    /// Orbit or fly.
    pub mode: Mode,
    /// Eye position (world).
    pub eye: Vec3,
    /// Heading (radians): 0 looks down −Z, positive turns left (towards −X).
    pub yaw: f32,
    /// Elevation (radians), within ±89°.
    pub pitch: f32,
    /// Orbit distance from the eye to the target (the target is `eye + forward × distance`).
    pub distance: f32,
    /// Vertical field of view (radians).
    pub yfov: f32,
    /// Scene size (bounding-sphere radius): sets speeds and the near plane.
    pub scale: f32,
}

const MAX_PITCH: f32 = 89.0 * std::f32::consts::PI / 180.0;

impl Camera {
    /// Looking from `eye` at `target`.
    pub fn look_at(eye: Vec3, target: Vec3, yfov: f32, scale: f32) -> Camera {
        let d = target - eye;
        let distance = d.length().max(1e-4);
        let mut c = Camera {
            mode: Mode::Orbit,
            eye,
            yaw: 0.0,
            pitch: 0.0,
            distance,
            yfov,
            scale: scale.max(1e-3),
        };
        c.set_forward(d / distance);
        c
    }

    /// From a glTF camera's world transform (looking down its −Z); the orbit
    /// target is placed `distance` ahead.
    pub fn from_world(world_from_camera: Mat4, yfov: f32, distance: f32, scale: f32) -> Camera {
        let eye = world_from_camera.transform_point3(Vec3::ZERO);
        let forward = world_from_camera
            .transform_vector3(Vec3::NEG_Z)
            .normalize_or(Vec3::NEG_Z);
        let mut c = Camera::look_at(eye, eye + forward * distance.max(1e-3), yfov, scale);
        c.mode = Mode::Fly;
        c
    }

    /// Framing of the bounds `lo..hi`: from the front (+Z side), slightly above.
    pub fn frame(lo: Vec3, hi: Vec3, yfov: f32) -> Camera {
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let distance = radius / (yfov * 0.5).sin() * 1.05;
        let dir = Vec3::new(0.0, 0.25, 1.0).normalize();
        Camera::look_at(center + dir * distance, center, yfov, radius)
    }

    fn set_forward(&mut self, f: Vec3) {
        self.pitch = f.y.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH);
        self.yaw = (-f.x).atan2(-f.z);
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(-sy * cp, sp, -cy * cp)
    }

    /// Unit right vector (horizontal).
    pub fn right(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        Vec3::new(cy, 0.0, -sy)
    }

    /// The orbit target.
    pub fn target(&self) -> Vec3 {
        self.eye + self.forward() * self.distance
    }

    /// view_from_world.
    pub fn view(&self) -> Mat4 {
        let f = self.forward();
        let r = self.right();
        let u = r.cross(f);
        Mat4::from_cols(
            Vec4::new(r.x, u.x, -f.x, 0.0),
            Vec4::new(r.y, u.y, -f.y, 0.0),
            Vec4::new(r.z, u.z, -f.z, 0.0),
            Vec4::new(-r.dot(self.eye), -u.dot(self.eye), f.dot(self.eye), 1.0),
        )
    }

    /// Near plane distance.
    pub fn near(&self) -> f32 {
        (self.scale * 1e-3).max(1e-4)
    }

    /// clip_from_world: reverse-Z with an infinite far plane (depth 1 at the
    /// near plane, 0 at infinity).
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let f = 1.0 / (self.yfov * 0.5).tan();
        let proj = Mat4::from_cols(
            Vec4::new(f / aspect.max(1e-4), 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, self.near(), 0.0),
        );
        proj * self.view()
    }

    /// Mouse drag by (dx, dy) pixels with the primary button: orbit around
    /// the target, or look around (fly).
    pub fn rotate(&mut self, dx: f32, dy: f32) {
        let target = self.target();
        self.yaw -= dx * 0.005;
        self.pitch = (self.pitch - dy * 0.005).clamp(-MAX_PITCH, MAX_PITCH);
        if self.mode == Mode::Orbit {
            self.eye = target - self.forward() * self.distance;
        }
    }

    /// Mouse drag with the secondary button: move the eye (and target) in
    /// the view plane.
    pub fn pan(&mut self, dx: f32, dy: f32, viewport_height: f32) {
        let up = self.right().cross(self.forward());
        let per_pixel = 2.0 * self.distance * (self.yfov * 0.5).tan() / viewport_height.max(1.0);
        self.eye += (-self.right() * dx + up * dy) * per_pixel;
    }

    /// Mouse wheel: dolly towards the target (orbit) or change the orbit
    /// distance used by a later switch to orbit (fly: moves forward).
    pub fn zoom(&mut self, steps: f32) {
        let factor = 0.9f32.powf(steps);
        match self.mode {
            Mode::Orbit => {
                let target = self.target();
                self.distance = (self.distance * factor).max(self.near() * 2.0);
                self.eye = target - self.forward() * self.distance;
            }
            Mode::Fly => self.eye += self.forward() * (self.scale * 0.1 * steps),
        }
    }

    /// Fly movement over `dt` seconds: `dir` = (right, up, forward) in −1..1.
    pub fn fly(&mut self, dir: Vec3, dt: f32, fast: bool) {
        let speed = self.scale * if fast { 2.0 } else { 0.5 };
        let up = Vec3::Y;
        let step = (self.right() * dir.x + up * dir.y + self.forward() * dir.z) * speed * dt;
        self.eye += step;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_round_trips_direction() {
        let c = Camera::look_at(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-2.0, 0.5, -1.0),
            0.8,
            1.0,
        );
        let want = (Vec3::new(-2.0, 0.5, -1.0) - Vec3::new(1.0, 2.0, 3.0)).normalize();
        assert!((c.forward() - want).length() < 1e-5);
        assert!((c.target() - Vec3::new(-2.0, 0.5, -1.0)).length() < 1e-4);
    }

    #[test]
    fn orbit_keeps_target() {
        let mut c = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 0.8, 1.0);
        let t = c.target();
        c.rotate(40.0, -25.0);
        assert!((c.target() - t).length() < 1e-4);
        c.zoom(3.0);
        assert!((c.target() - t).length() < 1e-4);
    }

    #[test]
    fn gltf_camera_looks_down_minus_z() {
        let m = Mat4::from_translation(Vec3::new(0.0, 1.0, 4.0));
        let c = Camera::from_world(m, 0.7, 2.0, 1.0);
        assert!((c.forward() - Vec3::NEG_Z).length() < 1e-6);
        assert_eq!(c.mode, Mode::Fly);
        // The point ahead projects to the centre of the screen.
        let p = c.view_proj(1.5) * Vec3::new(0.0, 1.0, 0.0).extend(1.0);
        assert!((p.x / p.w).abs() < 1e-6 && (p.y / p.w).abs() < 1e-6);
        // Reverse-Z: depth 1 at the near plane, towards 0 far away.
        let near = c.view_proj(1.5) * Vec3::new(0.0, 1.0, 4.0 - c.near()).extend(1.0);
        assert!((near.z / near.w - 1.0).abs() < 1e-4);
        assert!((p.z / p.w) < 0.01 && p.z / p.w > 0.0);
        // Right is +x on screen, up is +y.
        let right = c.view_proj(1.0) * Vec3::new(0.5, 1.0, 0.0).extend(1.0);
        let up = c.view_proj(1.0) * Vec3::new(0.0, 1.5, 0.0).extend(1.0);
        assert!(right.x > 0.0 && up.y > 0.0);
    }
}
