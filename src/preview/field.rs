//! The level's signed distance field as the preview reads it (issue #24):
//! the KTX2 3D texture that `radbake bake --sdf N` writes as `sdf.ktx2`
//! (found through `manifest.json` beside the `.glb`), or that `radbake sdf
//! --out f.ktx2` writes with its sidecar `f.json`. The entry gives the
//! grid's world box; the texture holds metres, positive in free space and
//! negative inside solids ([`crate::sdf`]). The preview marches it for the
//! real-time lights' soft shadows, distance-field ambient occlusion on
//! probe-lit objects and the `sdf` debug view (`shaders/sdf.wgsl`).

use anyhow::{anyhow, bail, Context as _, Result};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Most voxels the preview uploads (as [`crate::sdf::MAX_VOXELS`]).
const MAX_VOXELS: u64 = crate::sdf::MAX_VOXELS;

/// A distance field on the CPU, ready to upload.
#[derive(Clone, Debug)]
pub struct Field {
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
    /// World box of the grid (voxel (0, 0, 0)'s minimum corner to the last
    /// voxel's maximum corner).
    pub bounds: (Vec3, Vec3),
    /// Voxel edge (metres).
    pub voxel: f32,
    /// Signed distances (metres), x fastest, then y, then z.
    pub values: Vec<f32>,
}

/// Where the preview looks for a bake's field: `manifest.json` beside the
/// `.glb`.
pub fn manifest_path(glb: &Path) -> PathBuf {
    glb.with_file_name("manifest.json")
}

/// The field of the bake that wrote `glb`: `manifest.json`'s `sdf` entry
/// and the texture it names. None without a manifest or without an entry.
///
/// # Errors
/// The manifest or the texture exists but cannot be read (naming the file).
pub fn find(glb: &Path) -> Result<Option<Field>> {
    let manifest = manifest_path(glb);
    if !manifest.exists() {
        return Ok(None);
    }
    let json = read_json(&manifest)?;
    let entry = &json["sdf"];
    if entry.is_null() {
        return Ok(None);
    }
    let name = entry["ktx2"]
        .as_str()
        .ok_or_else(|| anyhow!("{}: sdf.ktx2 is not a file name", manifest.display()))?;
    read(&manifest.with_file_name(name), entry).map(Some)
}

/// The field in `ktx2`, placed by its sidecar (`ktx2` with `.json`, as
/// `radbake sdf` writes it).
///
/// # Errors
/// Either file cannot be read or does not describe a field.
pub fn open(ktx2: &Path) -> Result<Field> {
    let sidecar = ktx2.with_extension("json");
    let json = read_json(&sidecar)?;
    if json["sdf"].is_null() {
        bail!("{}: no `sdf` entry", sidecar.display());
    }
    read(ktx2, &json["sdf"])
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("{}: not JSON", path.display()))
}

/// Reads the texture `ktx2` (R32_SFLOAT or R16_SFLOAT, uncompressed or
/// Zstandard) placed by `entry` (`dims`, `voxel_size`, `bounds_min`,
/// `bounds_max`).
///
/// # Errors
/// A malformed entry or texture, or one whose size disagrees with the entry.
pub fn read(ktx2: &Path, entry: &serde_json::Value) -> Result<Field> {
    let bad = |what: &str| anyhow!("{}: {what}", ktx2.display());
    let vec3 = |key: &str| -> Result<Vec3> {
        let a = entry[key]
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| bad(&format!("the entry's {key} is not 3 numbers")))?;
        let v: Vec<f32> = a
            .iter()
            .filter_map(|x| x.as_f64())
            .map(|x| x as f32)
            .collect();
        (v.len() == 3 && v.iter().all(|x| x.is_finite()))
            .then(|| Vec3::new(v[0], v[1], v[2]))
            .ok_or_else(|| bad(&format!("the entry's {key} is not 3 finite numbers")))
    };
    let (lo, hi) = (vec3("bounds_min")?, vec3("bounds_max")?);
    let voxel = entry["voxel_size"].as_f64().unwrap_or(0.0) as f32;
    if !(voxel.is_finite() && voxel > 0.0) || hi.cmple(lo).any() {
        return Err(bad("the entry's voxel_size or bounds are not a grid"));
    }
    let bytes = std::fs::read(ktx2).with_context(|| format!("cannot read {}", ktx2.display()))?;
    let reader =
        ktx2::Reader::new(&bytes[..]).map_err(|e| bad(&format!("not a KTX2 file ({e})")))?;
    let h = reader.header();
    let dims = [h.pixel_width, h.pixel_height, h.pixel_depth];
    let voxels = dims.iter().map(|&d| d as u64).product::<u64>();
    if voxels == 0 || voxels > MAX_VOXELS {
        return Err(bad(&format!(
            "a 3D texture of {dims:?} texels (1 to {MAX_VOXELS} expected)"
        )));
    }
    let listed: Vec<u64> = entry["dims"]
        .as_array()
        .map(|a| a.iter().filter_map(|x| x.as_u64()).collect())
        .unwrap_or_default();
    if listed != dims.map(u64::from) {
        return Err(bad(&format!(
            "a 3D texture of {dims:?} texels, but its entry says dims {}",
            entry["dims"]
        )));
    }
    let size = match h.format {
        Some(ktx2::Format::R32_SFLOAT) => 4,
        Some(ktx2::Format::R16_SFLOAT) => 2,
        f => return Err(bad(&format!("format {f:?}, not R32_SFLOAT or R16_SFLOAT"))),
    };
    let level = reader.levels().next().ok_or_else(|| bad("no mip level"))?;
    let expected = voxels as usize * size;
    let raw = match h.supercompression_scheme {
        None => level.data.to_vec(),
        Some(ktx2::SupercompressionScheme::Zstandard) => {
            zstd::bulk::decompress(level.data, expected).map_err(|e| bad(&format!("zstd: {e}")))?
        }
        Some(s) => return Err(bad(&format!("supercompression {s:?} is not read"))),
    };
    if raw.len() != expected {
        return Err(bad(&format!(
            "{} bytes of texels, {expected} expected",
            raw.len()
        )));
    }
    let values = if size == 4 {
        raw.chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    } else {
        raw.chunks_exact(2)
            .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect()
    };
    Ok(Field {
        dims,
        bounds: (lo, hi),
        voxel,
        values,
    })
}

impl Field {
    /// The field as half floats for a filterable `R16Float` 3D texture
    /// (every adapter filters it; `R32Float` needs a feature). Half
    /// precision is 2⁻¹¹ relative: under a millimetre within 2 m of a
    /// surface, where shadows and occlusion are decided.
    /// Returns their bits.
    pub fn halves(&self) -> Vec<u16> {
        self.values
            .iter()
            .map(|&v| half::f16::from_f32(v.clamp(-65000.0, 65000.0)).to_bits())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_the_bake_writes_and_refuses_a_mismatch() {
        let grid = crate::sdf::Grid {
            origin: Vec3::new(-1.0, 0.0, 2.0),
            voxel: 0.5,
            dims: [3, 2, 4],
        };
        let sdf = crate::sdf::Sdf {
            grid,
            distance: (0..24).map(|i| i as f32 * 0.25 - 3.0).collect(),
            rays: 0,
        };
        let dir = std::env::temp_dir().join(format!("radbake-field-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("f.ktx2");
        // Both formats; the quarter-metre steps are exact in half floats.
        for format in [
            crate::config::SdfFormat::R16f,
            crate::config::SdfFormat::R32f,
        ] {
            crate::output::sdf::write(&path, &sdf, None, format).unwrap();
            let f = open(&path).unwrap();
            assert_eq!(f.dims, [3, 2, 4]);
            assert_eq!(f.values, sdf.distance);
        }
        let f = open(&path).unwrap();
        assert_eq!(
            f.bounds,
            (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(0.5, 1.0, 4.0))
        );
        // An entry that places a texture of another size.
        let entry =
            serde_json::json!({"bounds_min": [0, 0, 0], "bounds_max": [1, 1, 1], "voxel_size": -1});
        let e = read(&path, &entry).unwrap_err().to_string();
        assert!(e.contains("f.ktx2") && e.contains("voxel_size"), "{e}");
        std::fs::write(&path, b"not a texture").unwrap();
        let e = open(&path).unwrap_err().to_string();
        assert!(e.contains("not a KTX2 file"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
