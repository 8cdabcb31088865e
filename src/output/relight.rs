//! A live bake relit (`radbake relight`): the live lights' bounced light
//! re-solved for a new sun ([`radbake_live::Live`]) and written, with the
//! other layers (the sky's scaled to a new sky colour), as a bake folder
//! (as [`super::combine`] writes one).
//!
//! The pages are the bake at the new sun: every layer but `live` as baked
//! (at its weight), the sky's layer × new sky / baked sky per channel, and
//! the live layer from the run time's solution. The live layer's probes
//! are its baked ones moved by the run time's change since the baked sun
//! ([`radbake_live::probes`]), where `live.bin` has the probes' rays.

use super::combine::{combine_replacing, read_json, recombined_replacing, Replaced};
use crate::error::{Error, Result};
use crate::maps::lightmap::Lightmaps;
use crate::probes::Probes;
use crate::probes::Sh9;
use glam::Vec3;
use radbake_live::{Live, LiveData, Sun};
use serde_json::json;
use std::path::{Path, PathBuf};

/// What to relight a live bake for.
#[derive(Clone, Debug)]
pub struct Relight {
    /// Towards the sun (y up; any length > 0).
    pub sun_direction: Vec3,
    /// The sun's irradiance (W/m², RGB); `None`: as baked.
    pub sun_irradiance: Option<Vec3>,
    /// The sky's radiance (RGB); `None`: as baked.
    pub sky: Option<Vec3>,
    /// Other layers' weights (as `radbake combine`'s).
    pub weights: Vec<(String, Vec3)>,
}

/// The solve's figures, for the manifest and the command's summary.
#[derive(Clone, Debug)]
pub struct Relit {
    /// The live light relit (its name in the scene) and its irradiance.
    pub light: String,
    pub irradiance: Vec3,
    pub iterations: u32,
    pub residual: f32,
    /// Seconds: the update (direct light, solve, texels, pages).
    pub seconds: f64,
}

/// Reads the live data of the bake in `dir`.
///
/// # Errors
/// [`Error::Malformed`] for a bake without `live` or a bad `live.bin`.
pub fn read_live(dir: &Path) -> Result<LiveData> {
    if !dir.join("manifest.json").is_file() {
        return Err(Error::Malformed {
            path: dir.join("manifest.json"),
            message: "not found: a live bake's folder has one (bake with --live)".into(),
        });
    }
    let manifest = read_json(dir, "manifest.json")?;
    let Some(file) = manifest["live"]["file"].as_str() else {
        return Err(Error::Malformed {
            path: dir.join("manifest.json"),
            message: "the bake has no live lights (no `live`): bake with --live or a light in mode `live`".into(),
        });
    };
    let path = dir.join(file);
    LiveData::read(&path).map_err(|e| Error::Malformed {
        path,
        message: match e {
            radbake_live::LiveError::Malformed { message, .. }
            | radbake_live::LiveError::Io { message, .. } => message,
            e => e.to_string(),
        },
    })
}

/// The live layer relit: its pages (one Vec per page), the change of
/// its probes (none without the probes' rays) and the solve's figures.
pub struct LivePages {
    pub pages: Vec<Vec<Vec3>>,
    pub probe_delta: Option<Vec<Sh9>>,
    pub relit: Relit,
}

impl LivePages {
    /// As the layer to put in place of the live one's files.
    fn replaced<'a>(&'a self, layer: &'a str, size: radbake_live::PageSize) -> Replaced<'a> {
        Replaced {
            layer,
            size: [size.width, size.height],
            pages: &self.pages,
            probe_delta: self.probe_delta.as_deref(),
        }
    }
}

/// The live layer's pages and probes for `r` ([`LivePages`]).
///
/// # Errors
/// [`Error::Config`] for a sun direction of zero length or not finite, or
/// a bake of several live lights (one sun is given).
pub fn live_pages(data: LiveData, r: &Relight) -> Result<LivePages> {
    let h = &data.header;
    if h.lights.len() != 1 {
        return Err(Error::Config {
            key: "--sun-direction".into(),
            message: format!(
                "the bake has {} live lights; relight takes one",
                h.lights.len()
            ),
        });
    }
    let irradiance = r
        .sun_irradiance
        .unwrap_or(Vec3::from(h.lights[0].irradiance));
    let sun = Sun {
        direction: r.sun_direction.to_array(),
        irradiance: irradiance.to_array(),
    };
    let light = h.lights[0].name.clone();
    let start = std::time::Instant::now();
    let mut live = Live::new(data);
    let solve = live.update(&[sun]).map_err(|e| Error::Config {
        key: "--sun-direction".into(),
        message: e.to_string(),
    })?;
    let pages = (live.pages().into_iter())
        .map(|p| p.into_iter().map(Vec3::from).collect())
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    let probe_delta = live
        .probe_delta()
        .map(|d| d.iter().map(|sh| sh.map(Vec3::from)).collect());
    let relit = Relit {
        light,
        irradiance,
        iterations: solve.iterations,
        residual: solve.residual,
        seconds,
    };
    Ok(LivePages {
        pages,
        probe_delta,
        relit,
    })
}

/// Relights the live bake in `dir` for `r` into `out` (see the module
/// documentation). Returns the paths written and the solve's figures.
///
/// # Errors
/// As [`read_live`], [`live_pages`] and [`super::combine::combine`]; a
/// new sky for a bake whose sky has no layer of its own, or whose baked
/// sky is 0 in a channel the new one lights.
pub fn relight(dir: &Path, r: &Relight, out: &Path) -> Result<(Vec<PathBuf>, Relit)> {
    let (data, weights) = prepare(dir, r)?;
    let layer = data.header.layer.clone();
    let size = data.header.pages[0];
    let live = live_pages(data, r)?;
    let relit = live.relit.clone();
    let note = json!({
        "sun_direction": r.sun_direction.to_array(),
        "sun_irradiance": r.sun_irradiance.map(|s| s.to_array()),
        "sky": r.sky.map(|s| s.to_array()),
        "iterations": relit.iterations,
        "residual": relit.residual,
        "probes": if live.probe_delta.is_some() {
            "the live layer's probes: as baked + the change of the patches' radiance since the baked sun, seen along the probes' rays"
        } else {
            "the live lights' bounce in the probes is as baked (the bake kept no probe rays)"
        },
    });
    let replace = Some(live.replaced(&layer, size));
    let written = combine_replacing(dir, &weights, replace, out, Some(("relit", note)))?;
    Ok((written, relit))
}

/// The live bake in `dir` relit for `r`, in memory: its pages (one per
/// [`Lightmaps`], as [`relight`] writes them) and probes. What `radbake
/// preview --sun-direction` shows.
///
/// # Errors
/// As [`relight`]'s.
pub fn relit(dir: &Path, r: &Relight) -> Result<(Vec<Lightmaps>, Option<Probes>, Relit)> {
    let (data, weights) = prepare(dir, r)?;
    let layer = data.header.layer.clone();
    let size = data.header.pages[0];
    let live = live_pages(data, r)?;
    let replace = Some(live.replaced(&layer, size));
    let (pages, probes) = recombined_replacing(dir, &weights, replace)?;
    Ok((pages, probes, live.relit))
}

/// The live data of the bake in `dir` and the other layers' weights for
/// `r` ([`weights`]).
fn prepare(dir: &Path, r: &Relight) -> Result<(LiveData, Vec<(String, Vec3)>)> {
    let data = read_live(dir)?;
    let weights = weights(&data, r)?;
    Ok((data, weights))
}

/// The weights of the layers other than the live one for `r`: its
/// `weights`, and the sky's where its colour changes.
///
/// # Errors
/// [`Error::Config`] for a weight on the live layer, or a new sky that
/// the bake's cannot scale to.
pub fn weights(data: &LiveData, r: &Relight) -> Result<Vec<(String, Vec3)>> {
    let layer = &data.header.layer;
    let mut weights = r.weights.clone();
    if weights.iter().any(|(n, _)| n == layer) {
        return Err(Error::Config {
            key: format!("layer weight `{layer}`"),
            message: "the live layer is re-solved for the sun: give --sun-irradiance instead"
                .into(),
        });
    }
    if let Some(sky) = r.sky {
        weights.push(sky_weight(data, sky)?);
    }
    Ok(weights)
}

/// The sky layer's weight for a new sky: new / baked per channel.
fn sky_weight(data: &LiveData, sky: Vec3) -> Result<(String, Vec3)> {
    let bad = |message: String| Error::Config {
        key: "--sky".into(),
        message,
    };
    if !sky.is_finite() || sky.min_element() < 0.0 {
        return Err(bad(format!("{sky}: must be finite and ≥ 0")));
    }
    let Some(s) = &data.header.sky else {
        return Err(bad(
            "the bake's sky has no layer of its own (an HDRI, black, or shared with other lights): it cannot change colour".into(),
        ));
    };
    let baked = Vec3::from(s.radiance);
    let w = Vec3::select(baked.cmpgt(Vec3::ZERO), sky / baked, Vec3::ZERO);
    if (0..3).any(|c| baked[c] == 0.0 && sky[c] > 0.0) {
        return Err(bad(format!(
            "the baked sky {baked} is 0 in a channel that {sky} lights: bake with a sky that is not"
        )));
    }
    Ok((s.layer.clone(), w))
}
