//! Decoded 8-bit sRGB textures and their bilinear sampling, with glTF sampler
//! wrap modes and `KHR_texture_transform`.

use glam::{Vec2, Vec4};

/// glTF sampler wrap mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// `REPEAT` (10497), the default.
    Repeat,
    /// `CLAMP_TO_EDGE` (33071).
    Clamp,
    /// `MIRRORED_REPEAT` (33648).
    Mirror,
}

impl Wrap {
    /// Wraps an integer texel coordinate into `0..size`.
    fn apply(self, i: i64, size: u32) -> u32 {
        let n = size as i64;
        let j = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m < n {
                    m
                } else {
                    2 * n - 1 - m
                }
            }
        };
        j as u32
    }
}

/// An RGBA8 texture whose RGB is sRGB-encoded (base colour, emissive).
#[derive(Clone, Debug)]
pub struct Texture {
    /// Width in texels (> 0).
    pub width: u32,
    /// Height in texels (> 0).
    pub height: u32,
    /// Row-major RGBA8 texels.
    pub rgba: Vec<[u8; 4]>,
    /// Horizontal wrap.
    pub wrap_s: Wrap,
    /// Vertical wrap.
    pub wrap_t: Wrap,
}

/// sRGB transfer function inverse, IEC 61966-2-1.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB transfer function, IEC 61966-2-1.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

fn srgb_lut() -> &'static [f32; 256] {
    static LUT: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

impl Texture {
    fn fetch(&self, x: i64, y: i64) -> Vec4 {
        self.texel(
            self.wrap_s.apply(x, self.width),
            self.wrap_t.apply(y, self.height),
        )
    }

    /// The texel at wrapped coordinates (`xi` < width, `yi` < height).
    fn texel(&self, xi: u32, yi: u32) -> Vec4 {
        let lut = srgb_lut();
        let [r, g, b, a] = self.rgba[(yi * self.width + xi) as usize];
        Vec4::new(
            lut[r as usize],
            lut[g as usize],
            lut[b as usize],
            a as f32 / 255.0,
        )
    }

    /// Bilinear sample at `uv` (glTF convention: (0,0) is the first texel's
    /// top-left corner). RGB is linear, alpha as stored.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        if !uv.is_finite() {
            return self.fetch(0, 0);
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // Each axis wrapped once (not once per corner).
        let (xa, xb) = (
            self.wrap_s.apply(x0, self.width),
            self.wrap_s.apply(x0 + 1, self.width),
        );
        let (ya, yb) = (
            self.wrap_t.apply(y0, self.height),
            self.wrap_t.apply(y0 + 1, self.height),
        );
        let a = self.texel(xa, ya).lerp(self.texel(xb, ya), tx);
        let b = self.texel(xa, yb).lerp(self.texel(xb, yb), tx);
        a.lerp(b, ty)
    }
}

/// A material's use of a texture: which one, and its `KHR_texture_transform`.
#[derive(Clone, Debug)]
pub struct TextureRef {
    /// Index into [`crate::scene::Scene::textures`].
    pub texture: u32,
    /// UV offset.
    pub offset: Vec2,
    /// UV rotation (radians, counter-clockwise).
    pub rotation: f32,
    /// UV scale.
    pub scale: Vec2,
}

impl TextureRef {
    /// Applies `KHR_texture_transform`: uv' = T · R · S · uv.
    pub fn transform_uv(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        if self.rotation == 0.0 {
            // The common case, without a sine and cosine per sample (the
            // same result: cos 0 = 1 and sin 0 = 0 exactly).
            return s + self.offset;
        }
        let (sin, cos) = self.rotation.sin_cos();
        Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + self.offset
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip() {
        for i in 0..=255 {
            let c = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(Wrap::Repeat.apply(-1, 4), 3);
        assert_eq!(Wrap::Clamp.apply(-1, 4), 0);
        assert_eq!(Wrap::Clamp.apply(9, 4), 3);
        assert_eq!(Wrap::Mirror.apply(4, 4), 3);
        assert_eq!(Wrap::Mirror.apply(-1, 4), 0);
    }

    #[test]
    fn transform_identity_and_offset() {
        let t = TextureRef {
            texture: 0,
            offset: Vec2::new(0.5, 0.0),
            rotation: 0.0,
            scale: Vec2::new(2.0, 1.0),
        };
        assert_eq!(t.transform_uv(Vec2::new(0.25, 0.5)), Vec2::new(1.0, 0.5));
    }

    #[test]
    fn sample_uniform_texture() {
        let t = Texture {
            width: 2,
            height: 2,
            rgba: vec![[255, 255, 255, 128]; 4],
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        };
        let v = t.sample(Vec2::new(0.3, 0.9));
        assert!((v.x - 1.0).abs() < 1e-6 && (v.w - 128.0 / 255.0).abs() < 1e-6);
    }
}
