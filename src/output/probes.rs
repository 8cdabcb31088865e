//! The probe files:
//!
//! - `probes.json` and `probes.bin`: every grid (its world transform,
//!   resolution, first probe) and, per probe, 9 × RGB little-endian f32 of
//!   **radiance** SH in three.js's `SphericalHarmonics3` order and
//!   normalisation (`new LightProbe(sh)` gives the right irradiance).
//! - `probes_<k>.ktx2`: grid k as a Bevy `IrradianceVolume`, a KTX2 3D
//!   texture in `E5B9G9R9_UFLOAT_PACK32` holding an ambient cube per voxel
//!   (E/π for ±X, ±Y, ±Z from the SH), laid out as Bevy 0.19's shader reads
//!   it: size (Rx, 2·Ry, 3·Rz), texel (x, y + Ry·[negative face], z + Rz·axis).
//!
//! Every file is written atomically.

use super::ktx2::{ktx2_rgb9e5, rgb9e5};
use super::write_bytes_atomic;
use crate::error::Result;
use crate::probes::{sh, Probes};
use std::path::{Path, PathBuf};

/// Grid `k`'s ambient cubes in Bevy's layout, packed in RGB9E5.
pub fn volume_texels(probes: &Probes, k: usize) -> ([u32; 3], Vec<u32>) {
    volume_texels_of(probes, &probes.sh, k)
}

/// [`volume_texels`] of the SH set `sh` (one per probe of `probes`: a
/// light layer's).
fn volume_texels_of(probes: &Probes, sh_set: &[sh::Sh9], k: usize) -> ([u32; 3], Vec<u32>) {
    let v = &probes.volumes[k];
    let r = v.resolution.to_array();
    let size = radbake_live::probes::volume_size(r);
    let mut texels = vec![0u32; (size[0] * size[1] * size[2]) as usize];
    for i in 0..v.len() {
        let cube = sh::ambient_cube(&sh_set[v.first + i]);
        for (face, value) in cube.iter().enumerate() {
            let at = radbake_live::probes::volume_texel(r, v.coords(i).to_array(), face);
            texels[at] = rgb9e5(*value);
        }
    }
    (size, texels)
}

/// Per probe 9 × RGB little-endian f32.
fn sh_bytes(sh_set: &[sh::Sh9]) -> Vec<u8> {
    let mut bin = Vec::with_capacity(sh_set.len() * 27 * 4);
    for coeffs in sh_set {
        for c in coeffs {
            for v in c.to_array() {
                bin.extend(v.to_le_bytes());
            }
        }
    }
    bin
}

/// Writes light layer `name`'s probes (`sh_set`, one per probe of
/// `probes`): `probes_<name>.bin` as `probes.bin` and
/// `probes_<k>_<name>.ktx2` as `probes_<k>.ktx2`. Returns the paths and
/// the manifest's entry (the files' names).
///
/// # Errors
/// [`crate::Error::Io`].
pub fn write_layer(
    out_dir: &Path,
    probes: &Probes,
    (name, sh_set): (&str, &[sh::Sh9]),
) -> Result<(Vec<PathBuf>, serde_json::Value)> {
    let bin_name = format!("probes_{name}.bin");
    write_bytes_atomic(&out_dir.join(&bin_name), &sh_bytes(sh_set))?;
    let mut written = vec![out_dir.join(&bin_name)];
    let mut volumes = Vec::new();
    for k in 0..probes.volumes.len() {
        let (size, texels) = volume_texels_of(probes, sh_set, k);
        let file = format!("probes_{k}_{name}.ktx2");
        write_bytes_atomic(&out_dir.join(&file), &ktx2_rgb9e5(size, &texels))?;
        written.push(out_dir.join(&file));
        volumes.push(file);
    }
    let entry = serde_json::json!({ "binary": bin_name, "bevy_irradiance_volumes": volumes });
    Ok((written, entry))
}

/// Writes `probes.json`, `probes.bin` and `probes_<k>.ktx2` into `out_dir`.
/// Returns the paths and the manifest's `probes` entry.
///
/// # Errors
/// [`crate::Error::Io`] / [`crate::Error::Encode`].
pub fn write(out_dir: &Path, probes: &Probes) -> Result<(Vec<PathBuf>, serde_json::Value)> {
    let mut written = Vec::new();
    let bin = sh_bytes(&probes.sh);
    let bin_path = out_dir.join("probes.bin");
    write_bytes_atomic(&bin_path, &bin)?;
    written.push(bin_path);
    let mut volumes = Vec::new();
    for (k, v) in probes.volumes.iter().enumerate() {
        let (size, texels) = volume_texels(probes, k);
        let name = format!("probes_{k}.ktx2");
        let path = out_dir.join(&name);
        write_bytes_atomic(&path, &ktx2_rgb9e5(size, &texels))?;
        written.push(path);
        let (scale, rotation, translation) = v.world_from_box.to_scale_rotation_translation();
        let r = v.resolution;
        volumes.push(serde_json::json!({
            "name": v.name,
            "resolution": [r.x, r.y, r.z],
            "first_probe": v.first,
            "probes": v.len(),
            "spacing": (v.size() / r.as_vec3()).to_array(),
            "world_from_box": v.world_from_box.to_cols_array(),
            "translation": translation.to_array(),
            "rotation_xyzw": rotation.to_array(),
            "scale": scale.to_array(),
            "bevy_irradiance_volume": name,
            "bevy_texture_size": size,
        }));
    }
    let invalid: Vec<usize> = (0..probes.len()).filter(|&i| !probes.valid[i]).collect();
    let json = serde_json::json!({
        "format": "radbake probes 1",
        "quantity": "incident radiance as L2 spherical harmonics (W·sr⁻¹·m⁻², linear RGB), three.js SphericalHarmonics3 order and normalisation: Y00, Y1-1 (y), Y10 (z), Y11 (x), Y2-2 (xy), Y2-1 (yz), Y20 (3z²-1), Y21 (xz), Y22 (x²-y²); irradiance E(n) = Σ Â_l L_lm Y_lm(n), Â = π, 2π/3, π/4",
        "layout": "probes.bin: per probe 9 coefficients × RGB little-endian f32 (108 bytes); grid probe (i, j, k) is first_probe + i + Rx·(j + Ry·k), at world_from_box · (((i, j, k) + 0.5) / R − 0.5)",
        "binary": "probes.bin",
        "probes": probes.len(),
        "invalid_probes": invalid,
        "unfilled_probes": probes.unfilled,
        "bevy": "each probes_<k>.ktx2 is an IrradianceVolume (RGB9E5 ambient cubes holding E/π) for an entity with the volume's translation, rotation and scale; set intensity = 1 for the bake's units",
        "volumes": volumes,
    });
    let path = out_dir.join("probes.json");
    let text = serde_json::to_vec_pretty(&json).map_err(|e| crate::Error::Encode {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_bytes_atomic(&path, &text)?;
    written.push(path);
    Ok((written, json))
}
