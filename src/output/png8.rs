//! The 8-bit lightmap encoding the `.glb` embeds (glTF core allows only
//! 8-bit PNG/JPEG images): sRGB(value / s), rounded after a dither.
//!
//! - **One scale per instance.** Each instance owns a rectangle of its page
//!   and a material copy, so its texels are encoded against its own
//!   largest value s, and its `MOZ_lightmap.intensity` is π s. One scale
//!   per page squeezed dim instances into the bottom codes (on Sponza the
//!   ceiling, at 0.4 % of the page's largest value, was quantised in steps
//!   of 9–16 %). With sRGB's curve, a value at 2 % of its instance's
//!   largest is quantised in steps of 4.6 % (see [`relative_step`]).
//! - **Dither.** Before rounding, each channel gets a deterministic offset
//!   uniform in [−½, ½) code (a hash of page, texel and channel), so that
//!   smooth gradients come out as fine noise, not as bands (Roberts 1962;
//!   the rounding error becomes independent of the signal on average).
//!
//! Texels outside every instance's rectangle (unused padding) are encoded
//! against the page's largest value.

use crate::layout::atlas::Atlas;
use crate::maps::lightmap::Lightmaps;
use crate::scene::texture::{linear_to_srgb, srgb_to_linear};
use glam::Vec3;

/// One page, encoded.
pub struct EncodedPage {
    /// The PNG file's bytes.
    pub png: Vec<u8>,
    /// Per instance of the atlas: its scale s if it lies on this page
    /// (decode: value = srgb_to_linear(byte / 255) × s).
    pub scales: Vec<Option<f32>>,
    /// The scale of texels outside every rectangle (the page's largest).
    pub page_scale: f32,
}

/// Texel ranges [x0, x1) × [y0, y1) of an instance rectangle on a page of
/// `w` × `h` texels.
fn texel_range(min: [f32; 2], max: [f32; 2], w: u32, h: u32) -> (u32, u32, u32, u32) {
    let f = |v: f32, n: u32| ((v * n as f32).round().max(0.0) as u32).min(n);
    (f(min[0], w), f(max[0], w), f(min[1], h), f(max[1], h))
}

/// Which instance's scale each texel of `page` uses: `usize::MAX` where no
/// rectangle covers it.
fn owners(atlas: &Atlas, page: u32, w: u32, h: u32) -> Vec<usize> {
    let mut owner = vec![usize::MAX; (w * h) as usize];
    for (i, r) in atlas.instances.iter().enumerate() {
        if r.page != page {
            continue;
        }
        let (x0, x1, y0, y1) = texel_range(r.min, r.max, w, h);
        for y in y0..y1 {
            for x in x0..x1 {
                owner[(y * w + x) as usize] = i;
            }
        }
    }
    owner
}

/// A dither offset in [−½, ½) for (page, texel, channel): a hash, so the
/// output is the same on every run and thread count.
fn dither(page: usize, texel: u32, channel: u32) -> f32 {
    let z = crate::util::sampling::mix((page as u64) << 40 ^ (texel as u64) << 2 ^ channel as u64);
    (z >> 40) as f32 / (1u64 << 24) as f32 - 0.5
}

/// The 8-bit code of `v` / `scale` (clamped to [0, 1]) with dither `d`.
pub fn code(v: f32, scale: f32, d: f32) -> u8 {
    let s = linear_to_srgb((v / scale).clamp(0.0, 1.0)) * 255.0;
    (s + 0.5 + d).floor().clamp(0.0, 255.0) as u8
}

/// The linear value code `c` decodes to under `scale`.
pub fn decode(c: u8, scale: f32) -> f32 {
    srgb_to_linear(c as f32 / 255.0) * scale
}

/// The quantisation step at value `v` under `scale`, relative to `v`: the
/// distance between the two codes around it.
pub fn relative_step(v: f32, scale: f32) -> f32 {
    let c = (linear_to_srgb((v / scale).clamp(0.0, 1.0)) * 255.0).floor();
    let lo = decode(c as u8, scale);
    let hi = decode((c as u8).saturating_add(1), scale);
    (hi - lo) / v.max(f32::MIN_POSITIVE)
}

/// Encodes page `page` with one scale per instance rectangle (see the
/// module doc).
pub fn encode_page(lightmaps: &Lightmaps, atlas: &Atlas, page: usize) -> EncodedPage {
    let (w, h) = (lightmaps.width, lightmaps.height);
    let values = &lightmaps.pages[page];
    let owner = owners(atlas, page as u32, w, h);
    let mut scales: Vec<Option<f32>> = atlas
        .instances
        .iter()
        .map(|r| (r.page as usize == page).then_some(0.0f32))
        .collect();
    let mut page_scale = 0.0f32;
    for (t, v) in values.iter().enumerate() {
        let m = v.max_element();
        page_scale = page_scale.max(m);
        if let Some(Some(s)) = scales.get_mut(owner[t]) {
            *s = s.max(m);
        }
    }
    let page_scale = page_scale.max(1e-8);
    for s in scales.iter_mut().flatten() {
        *s = s.max(1e-8);
    }
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        let t = y * w + x;
        let scale = scales
            .get(owner[t as usize])
            .copied()
            .flatten()
            .unwrap_or(page_scale);
        let v: Vec3 = values[t as usize];
        let c = |ch: u32| code(v[ch as usize], scale, dither(page, t, ch));
        image::Rgb([c(0), c(1), c(2)])
    });
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("PNG encoding to memory cannot fail");
    EncodedPage {
        png,
        scales,
        page_scale,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_percent_of_the_scale_is_quantised_finer_than_five_percent() {
        let step = relative_step(0.02, 1.0);
        assert!(step < 0.05 && step > 0.04, "{step}");
        // One scale for a page whose brightest texel is 250 × brighter:
        // Sponza's ceiling under the page scale.
        assert!(relative_step(0.004, 1.0) > 0.08);
    }

    #[test]
    fn dither_is_centred_and_decode_inverts_code_within_half_a_step() {
        let n = 100_000;
        let mean: f32 = (0..n).map(|t| dither(0, t, 1)).sum::<f32>() / n as f32;
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((0..n).all(|t| (-0.5..0.5).contains(&dither(3, t, 2))));
        for v in [0.03f32, 0.2, 0.77, 1.0] {
            let c = code(v, 1.0, 0.0);
            assert!((decode(c, 1.0) - v).abs() <= 0.5 * relative_step(v, 1.0) * v + 1e-6);
        }
    }

    /// Dithered codes average to the value: no bias from the dither.
    #[test]
    fn dithered_codes_average_to_the_value() {
        let v = 0.0123f32;
        let n = 20_000;
        let mean_srgb: f32 = (0..n)
            .map(|t| code(v, 1.0, dither(1, t, 0)) as f32)
            .sum::<f32>()
            / n as f32
            / 255.0;
        let want = linear_to_srgb(v);
        assert!((mean_srgb - want).abs() < 0.002, "{mean_srgb} vs {want}");
    }
}
