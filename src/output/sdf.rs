//! The signed distance field's files ([`crate::sdf`]): a KTX2 3D texture
//! in `R32_SFLOAT` (metres, Zstandard supercompressed; texel (x, y, z) is
//! voxel (x, y, z), x fastest) and a JSON sidecar with its world
//! transform, both written atomically.

use super::{ktx2, write_bytes_atomic};
use crate::error::{Error, Result};
use crate::sdf::Sdf;
use std::path::{Path, PathBuf};

/// Writes `sdf` to `ktx2_path` and its sidecar (`ktx2_path` with `.json`);
/// returns both paths.
///
/// # Errors
/// [`Error::Io`] / [`Error::Encode`].
pub fn write(ktx2_path: &Path, sdf: &Sdf, band: Option<f32>) -> Result<Vec<PathBuf>> {
    let bytes = ktx2::ktx2_r32f_zstd(sdf.grid.dims, &sdf.distance, 9);
    write_bytes_atomic(ktx2_path, &bytes)?;
    let json_path = ktx2_path.with_extension("json");
    let g = &sdf.grid;
    let size = glam::Vec3::new(g.dims[0] as f32, g.dims[1] as f32, g.dims[2] as f32) * g.voxel;
    let name = ktx2_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned());
    let entry = serde_json::json!({
        "ktx2": name,
        "format": "R32_SFLOAT",
        "unit": "metres",
        "sign": "positive in free space, negative inside solids (behind one-sided faces; ray voting)",
        "dims": g.dims,
        "voxel_size": g.voxel,
        "origin": g.origin.to_array(),
        "bounds_min": g.origin.to_array(),
        "bounds_max": (g.origin + size).to_array(),
        "texel_centre": "world = origin + (xyz + 0.5) * voxel_size; texture uvw = (world - bounds_min) / (bounds_max - bounds_min)",
        "narrow_band_voxels": band,
    });
    let text = serde_json::to_vec_pretty(&serde_json::json!({"sdf": entry})).map_err(|e| {
        Error::Encode {
            path: json_path.clone(),
            message: e.to_string(),
        }
    })?;
    write_bytes_atomic(&json_path, &text)?;
    Ok(vec![ktx2_path.to_path_buf(), json_path])
}
