//! The shadowmask's files ([`crate::maps::shadowmask`]): per page
//! `shadowmask_<page>.png` (RGBA, 8-bit, *linear*: the visible fraction ×
//! 255, no sRGB curve), `shadowmask_<page>.exr` (RGBA float) and, unless
//! `--ktx2 off`, `shadowmask_<page>.ktx2` (`R8G8B8A8_UNORM`, zstd), with
//! the manifest's `shadowmask` entry: the files and which lights each
//! channel holds.

use super::{ktx2, write_atomic, write_bytes_atomic};
use crate::error::{Error, Result};
use crate::maps::shadowmask::{Shadowmask, CHANNELS, CHANNEL_NAMES};
use crate::scene::Light;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A visible fraction as an 8-bit code (round to nearest; clamped).
pub fn code(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// One page's texels as 8-bit RGBA.
fn rgba8(mask: &Shadowmask, page: usize) -> Vec<[u8; 4]> {
    mask.pages[page].iter().map(|m| m.map(code)).collect()
}

/// Writes one page as RGBA float OpenEXR, atomically (serially
/// compressed, as [`super::write_exr_rgb`], for identical bytes).
fn write_exr_rgba(path: &Path, mask: &Shadowmask, page: usize) -> Result<()> {
    let w = mask.width as usize;
    let values = &mask.pages[page];
    write_atomic(path, |tmp| {
        use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage as _};
        let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
            let v = values[y * w + x];
            (v[0], v[1], v[2], v[3])
        });
        Image::from_channels((w, mask.height as usize), channels)
            .write()
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| Error::Encode {
                path: path.to_path_buf(),
                message: e.to_string(),
            })
    })
}

/// One page as PNG bytes (RGBA8, linear).
///
/// # Errors
/// [`Error::Encode`] naming `name`.
pub fn png(mask: &Shadowmask, page: usize, name: &Path) -> Result<Vec<u8>> {
    let img = image::RgbaImage::from_raw(
        mask.width,
        mask.height,
        rgba8(mask, page).into_iter().flatten().collect(),
    )
    .expect("a page holds width × height texels");
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::Encode {
        path: name.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(bytes)
}

/// The files of [`write`]: paths written, the manifest's `shadowmask`
/// entry, and each page's PNG bytes (for the baked `.glb`).
pub struct Written {
    /// Paths written.
    pub paths: Vec<PathBuf>,
    /// The manifest's `shadowmask` entry.
    pub manifest: Value,
    /// PNG bytes per page.
    pub png: Vec<Vec<u8>>,
}

/// Writes the shadowmask pages into `out_dir` (see the module doc).
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write(
    out_dir: &Path,
    mask: &Shadowmask,
    lights: &[Light],
    ktx2_on: bool,
) -> Result<Written> {
    let mut paths = Vec::new();
    let mut pages = Vec::new();
    let mut pngs = Vec::new();
    for page in 0..mask.pages.len() {
        let png_name = format!("shadowmask_{page}.png");
        let bytes = png(mask, page, &out_dir.join(&png_name))?;
        write_bytes_atomic(&out_dir.join(&png_name), &bytes)?;
        paths.push(out_dir.join(&png_name));
        pngs.push(bytes);
        let exr = format!("shadowmask_{page}.exr");
        write_exr_rgba(&out_dir.join(&exr), mask, page)?;
        paths.push(out_dir.join(&exr));
        let ktx = ktx2_on.then(|| format!("shadowmask_{page}.ktx2"));
        if let Some(k) = &ktx {
            let bytes = ktx2::ktx2_rgba8_zstd(
                mask.width,
                mask.height,
                &rgba8(mask, page),
                ktx2::ZSTD_LEVEL,
            );
            write_bytes_atomic(&out_dir.join(k), &bytes)?;
            paths.push(out_dir.join(k));
        }
        pages.push(json!({"page": page, "png": png_name, "exr": exr, "ktx2": ktx}));
    }
    Ok(Written {
        paths,
        manifest: manifest_entry(mask, lights, pages),
        png: pngs,
    })
}

/// The manifest's `shadowmask` entry.
pub fn manifest_entry(mask: &Shadowmask, lights: &[Light], pages: Vec<Value>) -> Value {
    let light = |l: usize| json!({"name": lights[l].name, "node": lights[l].node, "node_index": lights[l].node_index});
    let channels: Vec<Value> = (0..CHANNELS as u8)
        .map(|c| {
            let holders: Vec<Value> = (0..lights.len())
                .filter(|&l| mask.channel[l] == Some(c))
                .map(light)
                .collect();
            json!({"channel": CHANNEL_NAMES[c as usize], "lights": holders})
        })
        .collect();
    json!({
        "encoding": "per channel, the visible fraction (0 = shadowed, 1 = unoccluded) of the light that holds it, 0 where it does not reach; PNG and KTX2 (R8G8B8A8_UNORM) linear 8-bit (value / 255, no sRGB curve), EXR float",
        "uv": "as the lightmap: the same atlas, pages and instance rectangles (instances[].uv_rect)",
        "pages": pages,
        "channels": channels,
        "fallback_to_indirect": mask.fallback.iter().map(|&l| light(l)).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_and_clamp() {
        assert_eq!(code(0.0), 0);
        assert_eq!(code(1.0), 255);
        assert_eq!(code(0.5), 128);
        assert_eq!(code(-0.2), 0);
        assert_eq!(code(1.7), 255);
    }
}
