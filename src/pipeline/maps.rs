//! The lightmap stage: [`TexelLight`] → [`Maps`]. Invalid texels are
//! filled from their valid neighbours, texels are written into pages and
//! dilated, UV seams are stitched, and the optional directional (L1 SH) and
//! ambient-occlusion pages are built from the same texels.

use super::texel_light::TexelLight;
use crate::config::BakeConfig;
use crate::layout::texels::Texels;
use crate::light::lights::Directional;
use crate::maps::lightmap::{self, Lightmaps};
use crate::maps::seams;
use crate::surface::Surfaces;
use glam::{Vec2, Vec3};

/// The lightmap stage's product.
pub struct Maps {
    /// Lightmap pages (irradiance / π); `texel_values` are the final values.
    pub lightmaps: Lightmaps,
    /// Directional lightmaps (`--directional sh`): a, b_x, b_y, b_z pages,
    /// irradiance / π for a normal n being a + n_x b_x + n_y b_y + n_z b_z.
    pub sh: Option<[Lightmaps; 4]>,
    /// Ambient-occlusion pages (grey), with `--ao DISTANCE`.
    pub ao: Option<Lightmaps>,
    /// Texels found inside or under geometry (filled from their neighbours).
    pub invalid_texels: u64,
    /// Seam sample pairs stitched.
    pub seam_samples: u64,
    /// Mean |difference| across seams (RGB sum) before and after stitching.
    pub seam_mismatch: [f64; 2],
    /// One set of pages per light layer ([`TexelLight::layers`]; empty
    /// without layers), built as `lightmaps` with the same fill, dilation
    /// and seam weights: they sum to `lightmaps`.
    pub layers: Vec<Lightmaps>,
}

/// Pages from `light`: invalid texels filled, dilated by twice the padding,
/// seams stitched (`config.stitch_seams`), then the SH and AO pages.
pub fn build(s: &Surfaces, page_count: u32, light: &TexelLight, config: &BakeConfig) -> Maps {
    let texels = s.texels;
    let dilate = 2 * config.padding;
    let rings = lightmap::fill_rings(config.patch_texels);
    let invalid_texels = light.valid.iter().filter(|v| !**v).count() as u64;
    let seam_samples = if config.stitch_seams {
        // A seam sample off every texel (padding) does not veto stitching.
        let valid = |page: u32, uv: Vec2| {
            let (x, y) = (uv.x.floor() as i64, uv.y.floor() as i64);
            texels
                .at(page, x, y)
                .is_none_or(|t| light.valid[t as usize])
        };
        seams::find(s.geometry, s.rays, &valid)
    } else {
        Vec::new()
    };
    // Filled, paged, dilated and stitched: the same weights for the whole
    // light and for each layer.
    let pages = |values: &[Vec3]| {
        let mut values = values.to_vec();
        lightmap::fill_invalid(texels, &mut values, &light.valid, rings);
        lightmap::build(texels, values, page_count, dilate)
    };
    let mut lightmaps = pages(&light.values);
    let mut layers: Vec<Lightmaps> = light.layers.iter().map(|l| pages(&l.values)).collect();
    let before = seams::mismatch(&lightmaps, &seam_samples);
    if layers.is_empty() {
        seams::stitch(&mut lightmaps, &seam_samples, 16);
    } else {
        seams::stitch_layers(&mut lightmaps, &mut layers, &seam_samples, 16);
    }
    let after = seams::mismatch(&lightmaps, &seam_samples);
    // The texels' final values, as stitched.
    for lm in std::iter::once(&mut lightmaps).chain(&mut layers) {
        for t in 0..texels.len() {
            let [x, y] = texels.xy[t];
            lm.texel_values[t] = lm.pages[texels.page[t] as usize][(y * texels.width + x) as usize];
        }
    }
    let page = |v: Vec<Vec3>| lightmap::build(texels, v, page_count, dilate);
    let sh = light
        .directional
        .as_ref()
        .map(|b| sh_pages(texels, &lightmaps.texel_values, b, page));
    let ao = light
        .ao
        .as_ref()
        .map(|ao| page(ao.iter().map(|&v| Vec3::splat(v)).collect()));
    Maps {
        lightmaps,
        sh,
        ao,
        invalid_texels,
        seam_samples: seam_samples.len() as u64,
        seam_mismatch: [before, after],
        layers,
    }
}

/// L1 directional pages from the directional part `b` of each texel's
/// light: a = value − n · b, so a + n · b reproduces the lightmap at the
/// surface normal (Ramamoorthi & Hanrahan 2001).
fn sh_pages(
    texels: &Texels,
    values: &[Vec3],
    b: &[Directional],
    page: impl Fn(Vec<Vec3>) -> Lightmaps,
) -> [Lightmaps; 4] {
    let a: Vec<Vec3> = (0..texels.len())
        .map(|t| {
            let n = texels.n_ws[t];
            values[t] - b[t][0] * n.x - b[t][1] * n.y - b[t][2] * n.z
        })
        .collect();
    [
        page(a),
        page(b.iter().map(|d| d[0]).collect()),
        page(b.iter().map(|d| d[1]).collect()),
        page(b.iter().map(|d| d[2]).collect()),
    ]
}
