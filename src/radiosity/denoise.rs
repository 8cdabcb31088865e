//! Edge-aware denoising of the gathered light: an à-trous wavelet
//! filter (Dammertz, Sewtz, Hanika & Lensch, "Edge-Avoiding À-Trous Wavelet
//! Transform for fast Global Illumination Filtering", HPG 2010) in lightmap
//! space. Three passes of the 5 × 5 B3-spline kernel with holes 1, 2, 4
//! texels; a neighbour counts only if it is a valid texel of the same
//! instance and region (its chart, cut by walls), and is weighted down by its world distance, normal
//! difference and — as in SVGF (Schied et al. 2017) — its difference in
//! value relative to the texel's estimated noise (the gather's variance), so
//! real gradients (contact shadows, corners) survive while noise goes.
//! Only what the final gather's rays estimated is filtered (the indirect
//! light and the hemisphere-sampled share of the sky's and area lights'
//! direct light): light-sampled direct light keeps its sharp shadows.
//! Each chart is then scaled back to the power it had before filtering.

use crate::layout::texels::Texels;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Filters `values` (one per texel) in place; `variance` is each value's
/// noise variance (luminance); `texel_size[instance]` is a texel's world
/// size on that instance (metres), the scale of the position guide.
///
/// Only texels of one region mix (`region(t)`, a chart cut by walls, see
/// [`crate::layout::burial::Burial::region`]).
pub fn atrous(
    texels: &Texels,
    region: &(dyn Fn(usize) -> u32 + Sync),
    values: &mut [Vec3],
    valid: &[bool],
    variance: &[f32],
    texel_size: &[f32],
) {
    atrous_layers(texels, region, (values, &mut []), valid, variance, texel_size);
}

/// [`atrous`] of `values` and, with the same weights, of its light layers
/// (`layers`, which sum to `values`): every weight (the value guide and
/// each chart's power scale included) is decided from `values`, so the
/// filtered layers still sum to the filtered `values`.
pub fn atrous_layers(
    texels: &Texels,
    region: &(dyn Fn(usize) -> u32 + Sync),
    (values, layers): (&mut [Vec3], &mut [Vec<Vec3>]),
    valid: &[bool],
    variance: &[f32],
    texel_size: &[f32],
) {
    let before = chart_sums(texels, values);
    let mut variance = variance.to_vec();
    for pass in 0..3 {
        let step = 1i64 << pass;
        // 1 / 2σ_p² per instance, σ_p = the texel size × the step.
        let inv_2sp2: Vec<f32> = texel_size
            .iter()
            .map(|size| {
                let sigma_p = size * step as f32;
                1.0 / (2.0 * sigma_p * sigma_p)
            })
            .collect();
        let current = values.to_vec();
        let current_layers: Vec<Vec<Vec3>> = layers.to_vec();
        // Per texel, its value then its layers' values.
        let stride = 1 + layers.len();
        let mut next = vec![Vec3::ZERO; texels.len() * stride];
        next.par_chunks_mut(stride).enumerate().for_each(|(t, out)| {
                let own = |out: &mut [Vec3]| {
                    out[0] = current[t];
                    for (o, l) in out[1..].iter_mut().zip(&current_layers) {
                        *o = l[t];
                    }
                };
                if !valid[t] {
                    return own(out);
                }
                let [x, y] = texels.xy[t];
                let (p, n) = (texels.p_ws[t], texels.n_ws[t]);
                let lum = current[t].element_sum() / 3.0;
                let (mut acc, mut wsum) = (Vec3::ZERO, 0.0f32);
                let (first, acc_layers) = out.split_at_mut(1);
                acc_layers.fill(Vec3::ZERO);
                for (j, kj) in KERNEL.iter().enumerate() {
                    for (i, ki) in KERNEL.iter().enumerate() {
                        let dx = (i as i64 - 2) * step;
                        let dy = (j as i64 - 2) * step;
                        let Some(u) = texels.at(texels.page[t], x as i64 + dx, y as i64 + dy)
                        else {
                            continue;
                        };
                        let u = u as usize;
                        if !valid[u]
                            || texels.instance[u] != texels.instance[t]
                            || region(u) != region(t)
                        {
                            continue;
                        }
                        let wn = n.dot(texels.n_ws[u]).max(0.0).powi(32);
                        let wp = (-(texels.p_ws[u] - p).length_squared()
                            * inv_2sp2[texels.instance[t] as usize])
                            .exp();
                        // Symmetric in the pair's noise, so a quiet texel still
                        // takes in a noisy neighbour's rare bright samples
                        // (otherwise filtering would lose their energy).
                        let sigma_l = 2.0 * (variance[t] + variance[u]).sqrt() + 1e-6;
                        let wl = (-(current[u].element_sum() / 3.0 - lum).abs() / sigma_l).exp();
                        let w = ki * kj * wn * wp * wl;
                        acc += current[u] * w;
                        wsum += w;
                        for (a, l) in acc_layers.iter_mut().zip(&current_layers) {
                            *a += l[u] * w;
                        }
                    }
                }
                if wsum > 0.0 {
                    first[0] = acc / wsum;
                    for a in acc_layers.iter_mut() {
                        *a /= wsum;
                    }
                } else {
                    own(out);
                }
            });
        for (t, out) in next.chunks(stride).enumerate() {
            values[t] = out[0];
            for (l, x) in layers.iter_mut().zip(&out[1..]) {
                l[t] = *x;
            }
        }
        // Each pass averages several samples: the noise left is smaller.
        for v in variance.iter_mut() {
            *v *= 0.25;
        }
    }
    // Normalised weights move light around but do not conserve it: scale
    // each chart back to the power it had (Σ area × value per channel).
    let after = chart_sums(texels, values);
    for (t, v) in values.iter_mut().enumerate() {
        let key = (texels.instance[t], texels.chart[t]);
        let (b, a) = (before[&key], after[&key]);
        let scale = Vec3::select(a.cmpgt(Vec3::ZERO), b / a, Vec3::ONE);
        *v *= scale;
        for l in layers.iter_mut() {
            l[t] *= scale;
        }
    }
}

/// Σ area × value per (instance, chart).
fn chart_sums(texels: &Texels, values: &[Vec3]) -> HashMap<(u32, u32), Vec3> {
    let mut sums: HashMap<(u32, u32), Vec3> = HashMap::new();
    for (t, v) in values.iter().enumerate() {
        *sums
            .entry((texels.instance[t], texels.chart[t]))
            .or_default() += *v * texels.area[t];
    }
    sums
}
