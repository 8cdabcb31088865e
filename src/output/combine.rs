//! A bake's light layers recombined at new weights (`radbake combine`):
//! the bake at those intensities, written as a bake folder, without a bake.
//!
//! Each layer's pages and probes are its lights' share of the bake
//! ([`crate::scene::layers`]), so the bake with layer k's lights scaled by
//! wₖ (RGB) is Σₖ wₖ × layer k, per texel and per probe coefficient. A
//! layer that is given no weight keeps weight 1.
//!
//! Written (atomically, into `out`): `lightmap_<page>.exr`, its `.ktx2` in
//! the bake's KTX2 format and its `.png` preview, `probes.json`,
//! `probes.bin` and `probes_<k>.ktx2`, the shadowmask and distance-field
//! files copied as they are (they do not depend on the lights'
//! intensities), and `manifest.json` with `combined` (the source folder
//! and the weights) and no `layers`. The baked `.glb` and the
//! `lightmap_<page>_srgb.png` pages it embeds are not rewritten: the
//! manifest's `baked_gltf` and the pages' `png` are null.

use super::{ktx2, write_bytes_atomic, write_exr_rgb, write_preview_png};
use crate::error::{Error, Result};
use crate::maps::lightmap::Lightmaps;
use crate::probes::{Probes, Sh9};
use crate::util::files::read_exr_rgb;
use glam::Vec3;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The weight of each named layer, parsed from `NAME=W` or `NAME=R,G,B`.
///
/// # Errors
/// [`Error::Config`] for a malformed pair or a weight that is negative or
/// not finite.
pub fn parse_weight(pair: &str) -> Result<(String, Vec3)> {
    let bad = |message: String| Error::Config {
        key: format!("layer weight `{pair}`"),
        message,
    };
    let (name, value) = pair
        .split_once('=')
        .ok_or_else(|| bad("expected NAME=W or NAME=R,G,B".into()))?;
    let parts: Vec<f32> = value
        .split(',')
        .map(|v| v.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| bad(format!("not a number: {e}")))?;
    let w = match parts[..] {
        [w] => Vec3::splat(w),
        [r, g, b] => Vec3::new(r, g, b),
        _ => return Err(bad("expected one weight or three (R,G,B)".into())),
    };
    if !w.is_finite() || w.min_element() < 0.0 {
        return Err(bad("a weight must be finite and ≥ 0".into()));
    }
    Ok((name.to_owned(), w))
}

/// Reads `dir/name` as JSON.
pub(crate) fn read_json(dir: &Path, name: &str) -> Result<Value> {
    let path = dir.join(name);
    let bytes = std::fs::read(&path).map_err(|source| Error::Io {
        path: path.clone(),
        source,
    })?;
    serde_json::from_slice(&bytes).map_err(|e| Error::Malformed {
        path,
        message: format!("not JSON: {e}"),
    })
}

/// The bake folder's layers, each (name, weight, manifest entry), every
/// name in `weights` checked against them.
fn weighted_layers(
    dir: &Path,
    manifest: &Value,
    weights: &[(String, Vec3)],
) -> Result<Vec<(String, Vec3, Value)>> {
    let Some(layers) = manifest["layers"].as_array() else {
        return Err(Error::Malformed {
            path: dir.join("manifest.json"),
            message: "the bake has no light layers (no `layers`): bake a scene that names layers"
                .into(),
        });
    };
    let names: Vec<&str> = layers.iter().filter_map(|l| l["name"].as_str()).collect();
    if let Some((unknown, _)) = weights.iter().find(|(n, _)| !names.contains(&n.as_str())) {
        return Err(Error::Config {
            key: format!("layer weight `{unknown}`"),
            message: format!(
                "the bake has no layer `{unknown}` (its layers: {})",
                names.join(", ")
            ),
        });
    }
    Ok(layers
        .iter()
        .zip(&names)
        .map(|(l, name)| {
            let w = (weights.iter().rev())
                .find(|(n, _)| n == name)
                .map_or(Vec3::ONE, |(_, w)| *w);
            (name.to_string(), w, l.clone())
        })
        .collect())
}

/// One layer's pages given in place of its files (`radbake relight`'s
/// live layer), and a change of its probes.
#[derive(Clone, Copy)]
pub struct Replaced<'a> {
    /// The layer's name.
    pub layer: &'a str,
    /// The pages' size and the pages, row-major RGB.
    pub size: [u32; 2],
    pub pages: &'a [Vec<Vec3>],
    /// Per probe, added to the layer's probes as read (none: as baked).
    pub probe_delta: Option<&'a [Sh9]>,
}

/// A [`Replaced`] layer, or none.
pub type Replacement<'a> = Option<Replaced<'a>>;

/// Page `page` of every layer, weighted and summed (a `replace`d layer's
/// from its given pages).
fn combined_page(
    dir: &Path,
    layers: &[(String, Vec3, Value)],
    page: usize,
    replace: Replacement,
) -> Result<Lightmaps> {
    let mut out: Option<Lightmaps> = None;
    for (name, w, entry) in layers {
        let file = entry["pages"][page]["exr"]
            .as_str()
            .ok_or_else(|| Error::Malformed {
                path: dir.join("manifest.json"),
                message: format!("layer `{name}` has no EXR for page {page}"),
            })?;
        let path = dir.join(file);
        let (width, height, px) = match replace {
            Some(r) if r.layer == name => {
                let [w, h] = r.size;
                (w, h, r.pages.get(page).cloned().unwrap_or_default())
            }
            _ => read_exr_rgb(&path, "lightmap page", 1 << 16, 1 << 30)?,
        };
        if px.len() != width as usize * height as usize {
            return Err(Error::Malformed {
                path,
                message: format!("{} pixels for a {width} × {height} page", px.len()),
            });
        }
        let lm = out.get_or_insert_with(|| Lightmaps {
            width,
            height,
            pages: vec![vec![Vec3::ZERO; px.len()]],
            texel_values: Vec::new(),
        });
        if (lm.width, lm.height) != (width, height) {
            return Err(Error::Malformed {
                path,
                message: format!(
                    "{width} × {height}, but the other layers' page {page} is {} × {}",
                    lm.width, lm.height
                ),
            });
        }
        for (acc, v) in lm.pages[0].iter_mut().zip(&px) {
            *acc += *v * *w;
        }
    }
    out.ok_or_else(|| Error::Malformed {
        path: dir.join("manifest.json"),
        message: "`layers` is empty".into(),
    })
}

/// The bake's probes with their SH the layers' weighted sum; `None` for a
/// bake without probes.
fn combined_probes(
    dir: &Path,
    layers: &[(String, Vec3, Value)],
    replace: Replacement,
) -> Result<Option<Probes>> {
    if !dir.join("probes.json").is_file() {
        return Ok(None);
    }
    let mut probes = Probes::read(&dir.join("probes.json"))?;
    let mut sh: Vec<Sh9> = vec![[Vec3::ZERO; 9]; probes.len()];
    for (name, w, entry) in layers {
        let file = entry["probes"]["binary"]
            .as_str()
            .ok_or_else(|| Error::Malformed {
                path: dir.join("manifest.json"),
                message: format!("layer `{name}` has no probes"),
            })?;
        let path = dir.join(file);
        let bin = std::fs::read(&path).map_err(|source| Error::Io {
            path: path.clone(),
            source,
        })?;
        if bin.len() != probes.len() * 108 {
            return Err(Error::Malformed {
                path,
                message: format!(
                    "{} bytes, but the bake has {} probes ({} bytes)",
                    bin.len(),
                    probes.len(),
                    probes.len() * 108
                ),
            });
        }
        let f: Vec<f32> = (bin.chunks_exact(4))
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let delta = replace
            .filter(|r| r.layer == name)
            .and_then(|r| r.probe_delta);
        if delta.is_some_and(|d| d.len() != probes.len()) {
            return Err(Error::Malformed {
                path: dir.join("live.bin"),
                message: format!(
                    "its probes are not the bake's {} (probes.json)",
                    probes.len()
                ),
            });
        }
        for (i, (acc, c)) in sh.iter_mut().zip(f.chunks_exact(27)).enumerate() {
            for (k, a) in acc.iter_mut().enumerate() {
                let d = delta.map_or(Vec3::ZERO, |d| d[i][k]);
                *a += (Vec3::new(c[3 * k], c[3 * k + 1], c[3 * k + 2]) + d) * *w;
            }
        }
    }
    probes.sh = sh;
    Ok(Some(probes))
}

/// The layers of the bake in `dir` (its `manifest`) at `weights`, their
/// pages (one per [`Lightmaps`]) and probes (`None` without probes).
type Recombined = (Vec<(String, Vec3, Value)>, Vec<Lightmaps>, Option<Probes>);

/// The bake in `dir` (its `manifest.json` read as `manifest`) at
/// `weights`: its layers, and its pages and probes as the layers'
/// weighted sum.
fn recombine(
    dir: &Path,
    manifest: &Value,
    weights: &[(String, Vec3)],
    replace: Replacement,
) -> Result<Recombined> {
    let layers = weighted_layers(dir, manifest, weights)?;
    let page_count = manifest["pages"].as_array().map_or(0, Vec::len);
    let pages: Vec<Lightmaps> = (0..page_count)
        .map(|page| combined_page(dir, &layers, page, replace))
        .collect::<Result<_>>()?;
    let probes = combined_probes(dir, &layers, replace)?;
    Ok((layers, pages, probes))
}

/// The bake in `dir` at `weights` (layers not named keep weight 1): its
/// lightmap pages (one page per [`Lightmaps`], irradiance / π per texel)
/// and its probes (`None` for a bake without probes), each the layers'
/// weighted sum. What `radbake preview --layer` shows.
///
/// # Errors
/// As [`combine`]'s, before anything is written.
pub fn recombined(
    dir: &Path,
    weights: &[(String, Vec3)],
) -> Result<(Vec<Lightmaps>, Option<Probes>)> {
    recombined_replacing(dir, weights, None)
}

/// [`recombined`], with `replace`'s layer taken from its given pages (as
/// [`combine_replacing`]): what `radbake preview --sun-direction` shows.
///
/// # Errors
/// As [`combine`]'s.
pub fn recombined_replacing(
    dir: &Path,
    weights: &[(String, Vec3)],
    replace: Replacement,
) -> Result<(Vec<Lightmaps>, Option<Probes>)> {
    let manifest = read_json(dir, "manifest.json")?;
    let (_, pages, probes) = recombine(dir, &manifest, weights, replace)?;
    Ok((pages, probes))
}

/// Recombines the light layers of the bake in `dir` at `weights` (layers
/// not named keep weight 1) into `out` (see the module documentation).
/// Everything is read and checked before anything is written. Returns the
/// paths written.
///
/// # Errors
/// [`Error::Config`] for a weight naming no layer; [`Error::Malformed`]
/// for a bake folder without layers or with a missing or mismatched file;
/// [`Error::Io`] / [`Error::Encode`].
pub fn combine(dir: &Path, weights: &[(String, Vec3)], out: &Path) -> Result<Vec<PathBuf>> {
    combine_replacing(dir, weights, None, out, None)
}

/// [`combine`], with `replace`'s layer taken from its given pages (at its
/// weight) rather than its files, and `note` (if any) added to the
/// manifest under its key (`radbake relight`'s `relit`).
///
/// # Errors
/// As [`combine`].
pub fn combine_replacing(
    dir: &Path,
    weights: &[(String, Vec3)],
    replace: Replacement,
    out: &Path,
    note: Option<(&str, Value)>,
) -> Result<Vec<PathBuf>> {
    let same_folder = match (dir.canonicalize(), out.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same_folder {
        return Err(Error::Config {
            key: "--out".into(),
            message: format!(
                "{} is the bake folder itself: write the recombined bake to another folder",
                out.display()
            ),
        });
    }
    let mut manifest = read_json(dir, "manifest.json")?;
    let (layers, pages, probes) = recombine(dir, &manifest, weights, replace)?;
    std::fs::create_dir_all(out).map_err(|source| Error::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    for (page, lm) in pages.iter().enumerate() {
        let exr = out.join(format!("lightmap_{page}.exr"));
        write_exr_rgb(&exr, lm.width, lm.height, &lm.pages[0])?;
        let png = out.join(format!("lightmap_{page}.png"));
        write_preview_png(&png, lm, 0)?;
        written.extend([exr, png]);
        let entry = &mut manifest["pages"][page];
        if let Some(file) = entry["ktx2"].as_str().map(str::to_owned) {
            let bytes = if entry["ktx2_format"] == "bc6h" {
                ktx2::ktx2_bc6h_zstd(lm.width, lm.height, &lm.pages[0], ktx2::ZSTD_LEVEL)
            } else {
                let packed: Vec<u32> = lm.pages[0].iter().map(|v| ktx2::rgb9e5(*v)).collect();
                ktx2::ktx2_rgb9e5_zstd([lm.width, lm.height, 0], &packed, ktx2::ZSTD_LEVEL)
            };
            write_bytes_atomic(&out.join(&file), &bytes)?;
            written.push(out.join(file));
        }
        entry["png"] = Value::Null;
        entry["png_page_scale"] = Value::Null;
        if let Some(page) = entry.as_object_mut() {
            // The directional pages are not per layer: not recombined.
            page.remove("sh");
        }
    }
    if let Some(p) = &probes {
        let (files, _) = super::probes::write(out, p)?;
        written.extend(files);
    }
    // What the lights' intensities do not change, as it is.
    let same = std::fs::read_dir(dir).map_err(|source| Error::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    for entry in same.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with("shadowmask") || name.starts_with("sdf.") {
            let bytes = std::fs::read(entry.path()).map_err(|source| Error::Io {
                path: entry.path(),
                source,
            })?;
            write_bytes_atomic(&out.join(&name), &bytes)?;
            written.push(out.join(name));
        }
    }
    let obj = manifest.as_object_mut().ok_or_else(|| Error::Malformed {
        path: dir.join("manifest.json"),
        message: "not a JSON object".into(),
    })?;
    obj.remove("layers");
    obj.remove("layer_convention");
    obj.insert("baked_gltf".into(), Value::Null);
    let w: serde_json::Map<String, Value> = (layers.iter())
        .map(|(name, w, _)| (name.clone(), serde_json::json!(w.to_array())))
        .collect();
    obj.insert(
        "combined".into(),
        serde_json::json!({"from": dir.display().to_string(), "weights": w}),
    );
    obj.remove("live");
    if let Some((key, value)) = note {
        obj.insert(key.into(), value);
    }
    let path = out.join("manifest.json");
    super::write_json(&path, &manifest)?;
    written.push(path);
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_parse_or_say_why_not() {
        assert_eq!(
            parse_weight("lamp=0.5").unwrap(),
            ("lamp".into(), Vec3::splat(0.5))
        );
        assert_eq!(
            parse_weight("sky=0.3,0.3,0.5").unwrap(),
            ("sky".into(), Vec3::new(0.3, 0.3, 0.5))
        );
        for bad in [
            "lamp", "lamp=-1", "lamp=nan", "lamp=inf", "lamp=1,2", "lamp=x",
        ] {
            let e = parse_weight(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
