//! The signed distance field's files ([`crate::sdf`]): a KTX2 3D texture
//! in `R32_SFLOAT` or `R16_SFLOAT` ([`SdfFormat`]; metres, Zstandard
//! supercompressed; texel (x, y, z) is voxel (x, y, z), x fastest) and its
//! entry: a JSON sidecar for `radbake sdf`, the manifest's `sdf` for a
//! bake with `--sdf`. Written atomically.

use super::{ktx2, write_bytes_atomic};
use crate::config::SdfFormat;
use crate::error::{Error, Result};
use crate::sdf::Sdf;
use std::path::{Path, PathBuf};

/// Writes `sdf` to `ktx2_path` in `format` and its sidecar (`ktx2_path`
/// with `.json`); returns both paths.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write(
    ktx2_path: &Path,
    sdf: &Sdf,
    band: Option<f32>,
    format: SdfFormat,
) -> Result<Vec<PathBuf>> {
    write_ktx2(ktx2_path, sdf, format)?;
    let json_path = ktx2_path.with_extension("json");
    let name = ktx2_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned());
    let entry = manifest_entry(sdf, band, name, format);
    let text = serde_json::to_vec_pretty(&serde_json::json!({ "sdf": entry })).map_err(|e| {
        Error::Encode {
            path: json_path.clone(),
            message: e.to_string(),
        }
    })?;
    write_bytes_atomic(&json_path, &text)?;
    Ok(vec![ktx2_path.to_path_buf(), json_path])
}

/// Writes the field's KTX2 texture alone in `format` (atomically).
///
/// # Errors
/// [`Error::Io`].
pub fn write_ktx2(ktx2_path: &Path, sdf: &Sdf, format: SdfFormat) -> Result<()> {
    let bytes = match format {
        SdfFormat::R32f => ktx2::ktx2_r32f_zstd(sdf.grid.dims, &sdf.distance, ktx2::ZSTD_LEVEL),
        SdfFormat::R16f => ktx2::ktx2_r16f_zstd(sdf.grid.dims, &sdf.distance, ktx2::ZSTD_LEVEL),
    };
    write_bytes_atomic(ktx2_path, &bytes)
}

/// The field's entry: the file (`name`), its format and the grid's world
/// transform.
pub fn manifest_entry(
    sdf: &Sdf,
    band: Option<f32>,
    name: Option<String>,
    format: SdfFormat,
) -> serde_json::Value {
    let g = &sdf.grid;
    let size = glam::Vec3::new(g.dims[0] as f32, g.dims[1] as f32, g.dims[2] as f32) * g.voxel;
    serde_json::json!({
        "ktx2": name,
        "format": format.vk_name(),
        "unit": "metres",
        "sign": "positive in free space, negative inside solids (behind one-sided faces)",
        "dims": g.dims,
        "voxel_size": g.voxel,
        "origin": g.origin.to_array(),
        "bounds_min": g.origin.to_array(),
        "bounds_max": (g.origin + size).to_array(),
        "texel_centre": "world = origin + (xyz + 0.5) * voxel_size; texture uvw = (world - bounds_min) / (bounds_max - bounds_min)",
        "narrow_band_voxels": band,
    })
}
