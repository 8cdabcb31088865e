//! Lightmap pages from the patch solution. Each texel's value is
//! H = incident irradiance / π = its own direct light (sampled per texel,
//! sharp) + the indirect light of the patches, bilinearly interpolated
//! between the centres of the four nearest patch blocks of the same region
//! (chart, cut by walls: see [`crate::surface::burial`])
//! (missing blocks drop out and the weights are renormalised), so patches do
//! not show as blocks.
//! Empty texels around charts are then filled by dilation, ring by ring, so
//! bilinear filtering and mipmaps never fetch black.

use crate::layout::patches::Patches;
use crate::layout::texels::Texels;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Lightmap pages of linear RGB (irradiance / π).
#[derive(Clone, Debug, Default)]
pub struct Lightmaps {
    /// Page width.
    pub width: u32,
    /// Page height.
    pub height: u32,
    /// Row-major RGB values per page.
    pub pages: Vec<Vec<Vec3>>,
    /// Value of each covered texel (indexed by texel id), before dilation.
    pub texel_values: Vec<Vec3>,
}

/// Every texel's value interpolated from per-patch values, then shifted per
/// patch so the area-weighted mean over a patch's texels equals the patch's
/// value: interpolation moves light around within a patch but neither makes
/// nor loses any (clamped at 0).
pub fn interpolate(texels: &Texels, patches: &Patches, patch_values: &[Vec3]) -> Vec<Vec3> {
    let mut values = interpolate_unclamped(texels, patches, patch_values);
    for v in &mut values {
        *v = v.max(Vec3::ZERO);
    }
    values
}

/// [`interpolate`] before its clamp at 0: linear in `patch_values`.
pub fn interpolate_unclamped(
    texels: &Texels,
    patches: &Patches,
    patch_values: &[Vec3],
) -> Vec<Vec3> {
    let mut values = interpolate_bilinear(texels, patches, patch_values);
    for (i, target) in patch_values.iter().enumerate() {
        let ids = patches.texels_of(i);
        let mean: Vec3 = ids
            .iter()
            .map(|&t| values[t as usize] * texels.area[t as usize])
            .sum::<Vec3>()
            / patches.area[i];
        let shift = *target - mean;
        for &t in ids {
            values[t as usize] += shift;
        }
    }
    values
}

fn interpolate_bilinear(texels: &Texels, patches: &Patches, patch_values: &[Vec3]) -> Vec<Vec3> {
    (0..texels.len())
        .into_par_iter()
        .map(|t| {
            let (corners, wsum) = bilinear_weights(texels, patches, t);
            let mut acc = Vec3::ZERO;
            for (p, wt) in corners.into_iter().flatten() {
                acc += patch_values[p as usize] * wt;
            }
            if wsum > 0.0 {
                acc / wsum
            } else {
                patch_values[patches.of_texel[t].0 as usize]
            }
        })
        .collect()
}

/// Texel `t`'s bilinear weights ([`interpolate`]): up to four patches of
/// its region (its patch's key: blocks across a wall are other regions'
/// and drop out) with their weights, not normalised, and the weights' sum
/// (0: the texel takes its own patch's value).
pub fn bilinear_weights(
    texels: &Texels,
    patches: &Patches,
    t: usize,
) -> ([Option<(u32, f32)>; 4], f32) {
    let k = patches.block as f32;
    let [x, y] = texels.xy[t];
    let inst = texels.instance[t];
    let region = patches.key[patches.of_texel[t].0 as usize].1;
    let f = (Vec2::new(x as f32, y as f32) + 0.5) / k - 0.5;
    let b0 = f.floor();
    let w = f - b0;
    let mut out = [None; 4];
    let mut wsum = 0.0f32;
    for (slot, (dx, dy, wt)) in [
        (0, 0, (1.0 - w.x) * (1.0 - w.y)),
        (1, 0, w.x * (1.0 - w.y)),
        (0, 1, (1.0 - w.x) * w.y),
        (1, 1, w.x * w.y),
    ]
    .into_iter()
    .enumerate()
    {
        let bx = b0.x as i64 + dx;
        let by = b0.y as i64 + dy;
        if bx < 0 || by < 0 || wt <= 0.0 {
            continue;
        }
        if let Some(p) = patches.by_key.get(&(inst, region, bx as u32, by as u32)) {
            out[slot] = Some((p.0, wt));
            wsum += wt;
        }
    }
    (out, wsum)
}

/// Fills `rings` rings of empty texels around covered ones with the mean of
/// their covered (or already filled) 8-neighbours.
pub fn dilate(values: &mut [Vec3], filled: &mut [bool], width: u32, height: u32, rings: u32) {
    let (w, h) = (width as i64, height as i64);
    for _ in 0..rings {
        let mut updates: Vec<(usize, Vec3)> = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if filled[i] {
                    continue;
                }
                let (mut acc, mut n) = (Vec3::ZERO, 0);
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (nx, ny) = (x + dx, y + dy);
                        if nx >= 0 && ny >= 0 && nx < w && ny < h && filled[(ny * w + nx) as usize]
                        {
                            acc += values[(ny * w + nx) as usize];
                            n += 1;
                        }
                    }
                }
                if n > 0 {
                    updates.push((i, acc / n as f32));
                }
            }
        }
        if updates.is_empty() {
            break;
        }
        for (i, v) in updates {
            values[i] = v;
            filled[i] = true;
        }
    }
}

/// The first-pass value of every texel: its direct light plus the patches'
/// indirect light interpolated (see [`interpolate`]).
pub fn first_pass(
    texels: &Texels,
    patches: &Patches,
    direct: &[Vec3],
    indirect: &[Vec3],
) -> Vec<Vec3> {
    let mut values = interpolate(texels, patches, indirect);
    for (v, d) in values.iter_mut().zip(direct) {
        *v += *d;
    }
    values
}

/// One light layer's first pass ([`first_pass`]) within the whole bake's:
/// `indirect` is the layer's patch indirect light, `whole` the whole
/// bake's [`interpolate_unclamped`]. A texel channel that the whole bake
/// clamps at 0 is 0 in every layer, so the layers sum to the whole bake's
/// first pass.
pub fn first_pass_layer(
    texels: &Texels,
    patches: &Patches,
    direct: &[Vec3],
    indirect: &[Vec3],
    whole: &[Vec3],
) -> Vec<Vec3> {
    let mut values = interpolate_unclamped(texels, patches, indirect);
    for ((v, d), w) in values.iter_mut().zip(direct).zip(whole) {
        *v = Vec3::select(w.cmplt(Vec3::ZERO), Vec3::ZERO, *v) + *d;
    }
    values
}

/// Rings of neighbours an invalid texel is filled from ([`fill_invalid`]):
/// four patches' width (patches of `patch_texels`²), at least 16 texels.
pub fn fill_rings(patch_texels: u32) -> u32 {
    4 * patch_texels.max(4)
}

/// Replaces every invalid texel (see `gather`'s texel validity) by the mean
/// of its valid 8-neighbours of the same instance and chart, ring by ring
/// (up to `rings`), so light from inside walls never shows; an invalid texel
/// with no valid texel of its chart nearby keeps its own value.
pub fn fill_invalid(texels: &Texels, values: &mut [Vec3], valid: &[bool], rings: u32) {
    let mut ok = valid.to_vec();
    for _ in 0..rings {
        let mut updates: Vec<(usize, Vec3)> = Vec::new();
        for t in 0..texels.len() {
            if ok[t] {
                continue;
            }
            let [x, y] = texels.xy[t];
            let (mut acc, mut n) = (Vec3::ZERO, 0);
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    if let Some(u) = texels.at(texels.page[t], x as i64 + dx, y as i64 + dy) {
                        let u = u as usize;
                        if ok[u]
                            && texels.instance[u] == texels.instance[t]
                            && texels.chart[u] == texels.chart[t]
                        {
                            acc += values[u];
                            n += 1;
                        }
                    }
                }
            }
            if n > 0 {
                updates.push((t, acc / n as f32));
            }
        }
        if updates.is_empty() {
            break;
        }
        for (t, v) in updates {
            values[t] = v;
            ok[t] = true;
        }
    }
}

/// Builds the pages from final per-texel values, then `dilate_rings` of
/// dilation into the padding.
pub fn build(
    texels: &Texels,
    texel_values: Vec<Vec3>,
    page_count: u32,
    dilate_rings: u32,
) -> Lightmaps {
    let (w, h) = (texels.width, texels.height);
    let pages = (0..page_count.max(1))
        .map(|p| {
            let mut values = vec![Vec3::ZERO; (w * h) as usize];
            let mut filled = vec![false; (w * h) as usize];
            for (i, &e) in texels.index[p as usize].iter().enumerate() {
                if e != crate::layout::texels::EMPTY_ENTRY {
                    values[i] = texel_values[e as u32 as usize];
                    filled[i] = true;
                }
            }
            dilate(&mut values, &mut filled, w, h, dilate_rings);
            values
        })
        .collect();
    Lightmaps {
        width: w,
        height: h,
        pages,
        texel_values,
    }
}

/// Where [`build`]'s dilation puts each padding pixel's value from, as a
/// copy: per page, (row-major pixel index, the 3 × 3 neighbour 0–8 in row
/// order it copies) for every pixel within `rings` rings of a chart, ring
/// by ring, each from its first covered (or already filled) 8-neighbour in
/// row order. A run time that rewrites a page (`radbake_live`) fills its
/// padding so, in this order, without [`dilate`]'s pass over the page.
pub fn padding_sources(texels: &Texels, page_count: u32, rings: u32) -> Vec<Vec<(u32, u8)>> {
    let (w, h) = (texels.width as i64, texels.height as i64);
    (0..page_count.max(1))
        .map(|p| {
            let mut filled: Vec<bool> = (texels.index[p as usize].iter())
                .map(|&e| e != crate::layout::texels::EMPTY_ENTRY)
                .collect();
            let mut out = Vec::new();
            for _ in 0..rings {
                let mut updates = Vec::new();
                for y in 0..h {
                    for x in 0..w {
                        let i = (y * w + x) as usize;
                        if filled[i] {
                            continue;
                        }
                        let from = (0..9u8).find(|&n| {
                            let (nx, ny) = (x + n as i64 % 3 - 1, y + n as i64 / 3 - 1);
                            nx >= 0 && ny >= 0 && nx < w && ny < h && filled[(ny * w + nx) as usize]
                        });
                        if let Some(n) = from {
                            updates.push((i as u32, n));
                        }
                    }
                }
                if updates.is_empty() {
                    break;
                }
                for &(i, _) in &updates {
                    filled[i as usize] = true;
                }
                out.extend(updates);
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dilation_fills_rings() {
        let (w, h) = (5, 5);
        let mut v = vec![Vec3::ZERO; 25];
        let mut f = vec![false; 25];
        v[12] = Vec3::ONE;
        f[12] = true;
        dilate(&mut v, &mut f, w, h, 1);
        assert!(f[6] && f[18] && !f[0]);
        assert_eq!(v[6], Vec3::ONE);
        dilate(&mut v, &mut f, w, h, 1);
        assert!(f.iter().all(|&x| x));
    }
}
