//! Full mip chains of the preview's base-colour and emissive textures, built
//! on the CPU at upload, so distant textured surfaces are filtered
//! trilinearly as three.js filters them (`GLTFLoader` sets
//! `LinearMipmapLinearFilter` and `generateMipmaps` where the glTF sampler
//! names no `minFilter`, and WebGL 2 mipmaps textures of any size).
//!
//! Level n has the size of Vulkan / WebGL level n, max(1, ⌊size / 2ⁿ⌋),
//! down to 1 × 1. Each texel is the box mean of its exact footprint in the
//! level above (Williams 1983's pyramid; for power-of-two sizes the mean of
//! 2 × 2 texels; an odd size spreads three source texels over two, with
//! fractional weights), in **linear** RGB: sRGB texels are decoded before
//! averaging and the mean encoded again, as the GPU's sRGB formats (and
//! `glGenerateMipmap` on `SRGB8_ALPHA8`) expect; alpha is averaged as
//! stored. Each level is filtered from the one above kept in `f32`, so the
//! only rounding is the final 8-bit encoding of each level.

use crate::scene::texture::{linear_to_srgb, srgb_to_linear};

/// Number of levels of a full chain for a `width` × `height` texture
/// (1 + ⌊log2 max(width, height)⌋).
pub fn level_count(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

/// The per-axis box weights from a row of `from` texels to `to` (≤ `from`)
/// texels: for each output texel, (first source texel, weights), the
/// weights being the overlap of each source texel with the output texel's
/// footprint, normalised to sum 1.
fn axis_weights(from: u32, to: u32) -> Vec<(usize, Vec<f32>)> {
    let step = from as f64 / to as f64;
    (0..to)
        .map(|i| {
            let (lo, hi) = (i as f64 * step, (i + 1) as f64 * step);
            let first = lo.floor() as usize;
            let last = (hi.ceil() as usize).min(from as usize);
            let w = (first..last)
                .map(|j| ((hi.min(j as f64 + 1.0) - lo.max(j as f64)) / step) as f32)
                .collect();
            (first, w)
        })
        .collect()
}

/// One level down: `src` (`w` × `h`, linear RGBA) box-filtered to
/// max(1, w/2) × max(1, h/2).
fn downsample(src: &[[f32; 4]], w: u32, h: u32) -> (Vec<[f32; 4]>, u32, u32) {
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let (wx, wy) = (axis_weights(w, nw), axis_weights(h, nh));
    let mut out = Vec::with_capacity((nw * nh) as usize);
    for (y0, ky) in &wy {
        for (x0, kx) in &wx {
            let mut sum = [0f32; 4];
            for (dy, &fy) in ky.iter().enumerate() {
                let row = (y0 + dy) * w as usize;
                for (dx, &fx) in kx.iter().enumerate() {
                    let t = src[row + x0 + dx];
                    for c in 0..4 {
                        sum[c] += fx * fy * t[c];
                    }
                }
            }
            out.push(sum);
        }
    }
    (out, nw, nh)
}

/// Levels 1, 2, … to 1 × 1 (level 0, `rgba` itself, not included) of a
/// `width` × `height` RGBA8 image, each as RGBA8 rows; `srgb`: RGB is
/// sRGB-encoded (filtered in linear space).
pub fn mip_chain(width: u32, height: u32, rgba: &[u8], srgb: bool) -> Vec<Vec<u8>> {
    let decode = |c: u8| {
        let v = c as f32 / 255.0;
        if srgb {
            srgb_to_linear(v)
        } else {
            v
        }
    };
    let lut: Vec<f32> = (0..=255u8).map(decode).collect();
    let encode = |v: f32, colour: bool| {
        let v = v.clamp(0.0, 1.0);
        let e = if colour && srgb { linear_to_srgb(v) } else { v };
        (e * 255.0).round() as u8
    };
    let mut level: Vec<[f32; 4]> = rgba
        .chunks_exact(4)
        .map(|p| {
            [
                lut[p[0] as usize],
                lut[p[1] as usize],
                lut[p[2] as usize],
                p[3] as f32 / 255.0,
            ]
        })
        .collect();
    let (mut w, mut h) = (width, height);
    let mut out = Vec::new();
    while w > 1 || h > 1 {
        let next = downsample(&level, w, h);
        (level, w, h) = next;
        out.push(
            level
                .iter()
                .flat_map(|t| {
                    [
                        encode(t[0], true),
                        encode(t[1], true),
                        encode(t[2], true),
                        encode(t[3], false),
                    ]
                })
                .collect(),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A full chain: one level per halving down to 1 × 1, each of
    /// max(1, ⌊size / 2ⁿ⌋) (odd and non-square sizes included).
    #[test]
    fn chain_sizes_follow_the_gpu_rule() {
        for (w, h) in [(1, 1), (2, 2), (5, 3), (1024, 256), (7, 1), (640, 480)] {
            let levels = mip_chain(w, h, &vec![128; (4 * w * h) as usize], true);
            assert_eq!(levels.len() as u32 + 1, level_count(w, h), "{w}×{h}");
            for (n, l) in levels.iter().enumerate() {
                let n = n as u32 + 1;
                let (lw, lh) = ((w >> n).max(1), (h >> n).max(1));
                assert_eq!(l.len() as u32, 4 * lw * lh, "{w}×{h} level {n}");
            }
        }
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(1024, 1), 11);
        assert_eq!(level_count(1000, 3), 10);
    }

    /// A black-and-white checker averages, in linear space, to linear ½
    /// (sRGB 188), not to sRGB ½ (128); alpha is averaged as stored; a
    /// uniform texture stays exactly itself at every level (odd sizes too).
    #[test]
    fn levels_are_linear_box_means() {
        let (w, h) = (8u32, 8u32);
        let rgba: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let on = ((i % w) + (i / w)) % 2 == 0;
                let v = if on { 255 } else { 0 };
                [v, v, v, if on { 255 } else { 0 }]
            })
            .collect();
        let levels = mip_chain(w, h, &rgba, true);
        let want = (linear_to_srgb(0.5) * 255.0).round() as u8;
        assert_eq!(want, 188);
        for l in &levels {
            for px in l.chunks_exact(4) {
                assert_eq!(px, [want, want, want, 128]);
            }
        }
        // Not sRGB: the plain mean.
        let data = mip_chain(w, h, &rgba, false);
        assert_eq!(&data[0][..4], &[128, 128, 128, 128]);
        // Uniform, odd size: every texel of every level unchanged.
        let flat = vec![77u8; 4 * 5 * 3];
        for l in mip_chain(5, 3, &flat, true) {
            assert!(l.iter().all(|&c| c == 77), "{l:?}");
        }
    }

    /// An odd row of three texels into one spreads the weights evenly; five
    /// into two gives the middle texel half to each.
    #[test]
    fn odd_footprints_are_exact() {
        let w = axis_weights(3, 1);
        assert_eq!(w[0].0, 0);
        assert!(w[0].1.iter().all(|&x| (x - 1.0 / 3.0).abs() < 1e-6));
        let w = axis_weights(5, 2);
        assert_eq!((w[0].0, w[1].0), (0, 2));
        let (a, b) = (&w[0].1, &w[1].1);
        assert_eq!((a.len(), b.len()), (3, 3));
        assert!((a[2] - 0.2).abs() < 1e-6 && (b[0] - 0.2).abs() < 1e-6);
        assert!((a.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }
}
