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

/// A glTF sampler filter (`magFilter`, and each half of `minFilter`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// `NEAREST` (9728).
    Nearest,
    /// `LINEAR` (9729), the default.
    #[default]
    Linear,
}

/// A glTF sampler's filters. The bake filters bilinearly whatever they say
/// (its texels stage picks mip levels itself); `radbake preview` follows
/// them as three.js's `GLTFLoader` does: an absent filter is `LINEAR` for
/// magnification and `LINEAR_MIPMAP_LINEAR` for minification, and a
/// `minFilter` of `NEAREST` or `LINEAR` means no mipmaps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Filters {
    /// `magFilter`.
    pub mag: Filter,
    /// The texel filter of `minFilter`.
    pub min: Filter,
    /// The mip filter of `minFilter`; None: level 0 only.
    pub mipmap: Option<Filter>,
}

impl Default for Filters {
    /// No sampler, or one without filters: `LINEAR` / `LINEAR_MIPMAP_LINEAR`.
    fn default() -> Self {
        Filters {
            mag: Filter::Linear,
            min: Filter::Linear,
            mipmap: Some(Filter::Linear),
        }
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
    /// The sampler's filters (used by the preview only).
    pub filters: Filters,
}

/// Box-filtered levels 1, 2, … (each half the size of the one above, to
/// 1 × 1) of a scene's textures, each built on first use; held only while
/// they are read (the texels stage), not by the scene.
#[derive(Debug, Default)]
pub struct Mips(Vec<std::sync::OnceLock<Vec<Level>>>);

impl Mips {
    /// Room for `textures` textures' levels (none built yet).
    pub fn new(textures: usize) -> Mips {
        Mips((0..textures).map(|_| Default::default()).collect())
    }

    /// The levels of texture `index`, `texture`.
    fn of(&self, index: u32, texture: &Texture) -> &[Level] {
        self.0[index as usize].get_or_init(|| texture.build_mips())
    }
}

/// One prefiltered level of a [`Texture`]: linear RGBA, 16 bits per
/// channel (averaging in linear space; no sRGB requantisation).
#[derive(Clone, Debug)]
pub struct Level {
    width: u32,
    height: u32,
    texels: Vec<[u16; 4]>,
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
    #[inline]
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
        self.bilinear(uv, self.width, self.height, |x, y| self.texel(x, y))
    }

    /// Bilinear sample at `uv` of level `level` (0: the texture itself;
    /// levels past the last, 1 × 1, read the last) of texture `index` of
    /// `mips`: the texture box-filtered over 2^level × 2^level texels
    /// first, as a mipmap (Williams 1983), for averaging samples spread
    /// that far apart.
    pub fn sample_level(&self, mips: &Mips, index: u32, uv: Vec2, level: u32) -> Vec4 {
        if level == 0 || !uv.is_finite() {
            return self.sample(uv);
        }
        let levels = mips.of(index, self);
        let Some(l) = levels.get((level as usize).min(levels.len()).wrapping_sub(1)) else {
            return self.sample(uv);
        };
        self.bilinear(uv, l.width, l.height, |x, y| {
            Vec4::from_array(l.texels[(y * l.width + x) as usize].map(|c| c as f32 / 65535.0))
        })
    }

    /// Bilinear interpolation of `texel` over a `width` × `height` grid
    /// at `uv`, with this texture's wrap modes (each axis wrapped once, not
    /// once per corner).
    #[inline]
    fn bilinear(
        &self,
        uv: Vec2,
        width: u32,
        height: u32,
        texel: impl Fn(u32, u32) -> Vec4,
    ) -> Vec4 {
        let x = uv.x * width as f32 - 0.5;
        let y = uv.y * height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (xa, xb) = (
            self.wrap_s.apply(x0, width),
            self.wrap_s.apply(x0 + 1, width),
        );
        let (ya, yb) = (
            self.wrap_t.apply(y0, height),
            self.wrap_t.apply(y0 + 1, height),
        );
        let a = texel(xa, ya).lerp(texel(xb, ya), tx);
        let b = texel(xa, yb).lerp(texel(xb, yb), tx);
        a.lerp(b, ty)
    }

    /// Levels 1, 2, … to 1 × 1: each texel the mean of the 2 × 2 texels
    /// above it in linear RGBA (of an odd size, the last row or column
    /// counts twice).
    fn build_mips(&self) -> Vec<Level> {
        let mut levels: Vec<Level> = Vec::new();
        let (mut w, mut h) = (self.width, self.height);
        while w > 1 || h > 1 {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            // The level above: this texture, or the last level built (read
            // in place, so no full-size copy in floats is ever made).
            let above = levels.last();
            let at = |x: u32, y: u32| match above {
                None => self.texel(x, y),
                Some(l) => {
                    Vec4::from_array(l.texels[(y * w + x) as usize].map(|c| c as f32 / 65535.0))
                }
            };
            let mut texels = Vec::with_capacity((nw * nh) as usize);
            for y in 0..nh {
                let (y0, y1) = (2 * y, (2 * y + 1).min(h - 1));
                for x in 0..nw {
                    let (x0, x1) = (2 * x, (2 * x + 1).min(w - 1));
                    let mean = 0.25 * (at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1));
                    texels.push(
                        mean.to_array()
                            .map(|c| (c.clamp(0.0, 1.0) * 65535.0).round() as u16),
                    );
                }
            }
            levels.push(Level {
                width: nw,
                height: nh,
                texels,
            });
            (w, h) = (nw, nh);
        }
        levels
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
    /// The `TEXCOORD_n` set the texture is read through (`texCoord`, or
    /// `KHR_texture_transform.texCoord` where that overrides it). The bake
    /// reads every texture through `TEXCOORD_0` (with a warning otherwise);
    /// the preview reads sets 0 and 1, as three.js does.
    pub tex_coord: u32,
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

    /// Mip levels are linear-space box means, down to 1 × 1 (odd sizes
    /// included), and a level past the last reads the whole texture's mean.
    #[test]
    fn mips_are_linear_box_means() {
        let (dark, light) = (100u8, 210u8);
        let t = Texture {
            width: 5,
            height: 3,
            rgba: (0..15)
                .map(|i| {
                    let g = if i % 2 == 0 { dark } else { light };
                    [g, g, g, 255]
                })
                .collect(),
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
            filters: Filters::default(),
        };
        let levels = t.build_mips();
        let dims: Vec<(u32, u32)> = levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(dims, [(3, 2), (2, 1), (1, 1)]);
        // Level 1's first texel: the 2 × 2 block of texels 0, 1, 5, 6 — two
        // dark, two light — in linear space (not the sRGB mean).
        let lin = |g: u8| srgb_to_linear(g as f32 / 255.0);
        let want = 0.5 * (lin(dark) + lin(light));
        let got = levels[0].texels[0][0] as f32 / 65535.0;
        assert!((got - want).abs() < 1e-4, "{got} vs {want}");
        let mips = Mips::new(1);
        let deep = t.sample_level(&mips, 0, Vec2::splat(0.5), 30);
        let one = levels.last().unwrap().texels[0][0] as f32 / 65535.0;
        assert!((deep.x - one).abs() < 1e-6 && deep.w > 0.999);
        // Level 0 is the texture's own bilinear sample.
        let uv = Vec2::new(0.3, 0.6);
        assert_eq!(t.sample_level(&mips, 0, uv, 0), t.sample(uv));
    }

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
            tex_coord: 0,
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
            filters: Filters::default(),
        };
        let v = t.sample(Vec2::new(0.3, 0.9));
        assert!((v.x - 1.0).abs() < 1e-6 && (v.w - 128.0 / 255.0).abs() < 1e-6);
    }
}
