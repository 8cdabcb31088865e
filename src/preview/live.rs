//! `radbake preview --live`: a live bake's sun turned on keys, its bounce
//! light re-solved by the run time ([`radbake_live::Live`], docs/live.md)
//! and the lightmap pages rewritten in place.
//!
//! The pages shown are what [`crate::output::relight::relit`] gives: the
//! bake's other layers at their weights (summed once, at start) plus the
//! live layer from the run time's solution. The probes follow as
//! relight's do: the model's probes at the starting sun plus the change
//! of [`Live::probe_delta`] since then, and the vertices they light (the
//! dynamic nodes', [`super::probe_light::vertex_light`]) are lit again.
//! The live light itself is one of the preview's real-time lights, turned
//! with the sun.

use super::model::{place_sun, LinearPage, Model};
use super::renderer::Renderer;
use crate::output::relight::{read_live, Relight};
use anyhow::{bail, Result};
use glam::Vec3;
use radbake_live::{Live, Sun};
use std::path::Path;
use std::time::Instant;

/// The sun's elevation and azimuth (degrees) for a direction towards it:
/// azimuth from +X towards +Z (`radbake preview`'s title and keys).
pub fn angles(towards: Vec3) -> (f32, f32) {
    let d = towards.normalize_or_zero();
    (
        d.y.clamp(-1.0, 1.0).asin().to_degrees(),
        d.z.atan2(d.x).to_degrees(),
    )
}

/// The direction towards a sun at `elevation`, `azimuth` (degrees; see
/// [`angles`]).
pub fn direction(elevation: f32, azimuth: f32) -> Vec3 {
    let (e, a) = (elevation.to_radians(), azimuth.to_radians());
    Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
}

/// The direction towards the live light of the bake beside `glb`, as
/// baked.
///
/// # Errors
/// A bake without live lights, or a bad `live.bin`.
pub fn baked_direction(glb: &Path) -> Result<Vec3> {
    let dir = glb.parent().unwrap_or(Path::new("."));
    let data = read_live(dir)?;
    match data.header.lights.first() {
        Some(l) => Ok(Vec3::from(l.direction)),
        None => bail!("{}: the bake has no live light", dir.display()),
    }
}

/// A live bake shown in the window, its sun movable.
pub struct LiveView {
    live: Live,
    /// The other layers' sum, per page.
    base: Vec<Vec<Vec3>>,
    /// The live layer's pages of the last update (buffers reused).
    pages: Vec<Vec<[f32; 3]>>,
    size: (u32, u32),
    light: String,
    irradiance: Vec3,
    /// The sun: elevation, azimuth (degrees).
    pub elevation: f32,
    pub azimuth: f32,
    /// Milliseconds of the last update (solve, texels, pages, probes) and
    /// its iterations.
    pub update_ms: f64,
    pub iterations: u32,
    /// The probes' change at the starting sun (None: the file has no
    /// probes' rays), and the model's probes then (taken at the first
    /// update).
    delta0: Option<Vec<radbake_live::probes::Sh9>>,
    sh0: Option<Vec<crate::probes::Sh9>>,
    /// Ranges of the model's vertices lit by the probes.
    probe_lit: Vec<std::ops::Range<usize>>,
}

impl LiveView {
    /// The live bake beside `glb`, its sun at `sun` (as baked where
    /// `None`), its other layers at `weights` (the sky's colour as `sun`
    /// says).
    ///
    /// # Errors
    /// A bake without live lights or with several, a bad `live.bin`, and
    /// [`crate::output::combine::recombined_replacing`]'s.
    pub fn open(glb: &Path, weights: &[(String, Vec3)], sun: Option<&Relight>) -> Result<LiveView> {
        let dir = glb.parent().unwrap_or(Path::new("."));
        let data = read_live(dir)?;
        let h = &data.header;
        if h.lights.len() != 1 {
            bail!(
                "--live: the bake has {} live lights; the preview turns one",
                h.lights.len()
            );
        }
        let light = h.lights[0].clone();
        let r = Relight {
            sun_direction: sun.map_or(Vec3::from(light.direction), |s| s.sun_direction),
            sun_irradiance: sun.and_then(|s| s.sun_irradiance),
            sky: sun.and_then(|s| s.sky),
            weights: weights.to_vec(),
        };
        // The other layers: the relit bake with the live layer's pages 0.
        let size = (h.pages[0].width, h.pages[0].height);
        let zero = vec![vec![Vec3::ZERO; (size.0 * size.1) as usize]; h.pages.len()];
        let base_weights = crate::output::relight::weights(&data, &r)?;
        let layer = h.layer.clone();
        let replace = Some(crate::output::combine::Replaced {
            layer: &layer,
            size: [size.0, size.1],
            pages: &zero,
            probe_delta: None,
        });
        let (base, _) = crate::output::combine::recombined_replacing(dir, &base_weights, replace)?;
        let (elevation, azimuth) = angles(r.sun_direction);
        let irradiance = r.sun_irradiance.unwrap_or(Vec3::from(light.irradiance));
        let mut live = Live::new(data);
        // The probes' change is counted from the model's: as baked (no
        // change), or relit for `sun` (its change, as relight gives it).
        let delta0 = match sun {
            Some(_) => {
                live.update(&[Sun {
                    direction: r.sun_direction.to_array(),
                    irradiance: irradiance.to_array(),
                }])?;
                live.probe_delta()
            }
            None => live.probe_delta().map(|d| vec![[[0.0; 3]; 9]; d.len()]),
        };
        Ok(LiveView {
            live,
            base: base.into_iter().map(|p| p.pages[0].clone()).collect(),
            pages: Vec::new(),
            size,
            irradiance,
            light: light.name,
            elevation,
            azimuth,
            update_ms: 0.0,
            iterations: 0,
            delta0,
            sh0: None,
            probe_lit: Vec::new(),
        })
    }

    /// Turns the sun by `d_elevation`, `d_azimuth` degrees (elevation kept
    /// within 0.5°–89.5°).
    pub fn turn(&mut self, d_elevation: f32, d_azimuth: f32) {
        self.elevation = (self.elevation + d_elevation).clamp(0.5, 89.5);
        self.azimuth = (self.azimuth + d_azimuth).rem_euclid(360.0);
    }

    /// Re-solves for the current sun and writes the pages into
    /// `renderer`, the sun light into `model`'s scene and the renderer's
    /// real-time lights.
    ///
    /// # Errors
    /// The run time's (a sun direction not finite).
    pub fn update(&mut self, model: &mut Model, renderer: &mut Renderer) -> Result<()> {
        let t = Instant::now();
        let (towards, iterations, moved) = self.relight(model)?;
        for (i, (live, base)) in self.pages.iter().zip(&self.base).enumerate() {
            let page = LinearPage {
                width: self.size.0,
                height: self.size.1,
                rgb: (live.iter().zip(base))
                    .map(|(l, b)| *b + Vec3::from(*l))
                    .collect(),
            };
            renderer.write_linear_page(i, &page);
        }
        if moved {
            for r in &self.probe_lit {
                renderer.write_vertices(r.start, &model.vertices[r.clone()]);
            }
            if let Some(p) = &model.probes {
                renderer.set_probes(p);
            }
        }
        place_sun(&mut model.scene, &self.light, towards, self.irradiance);
        renderer.set_lights(&model.scene, &model.light_channels);
        self.update_ms = t.elapsed().as_secs_f64() * 1e3;
        self.iterations = iterations;
        Ok(())
    }

    /// The solve for the current sun, the live layer's pages into
    /// `self.pages` and [`LiveView::move_probes`]: what
    /// [`LiveView::update`] then writes to the GPU. Returns the sun's
    /// direction, the iterations and whether the probes moved.
    ///
    /// # Errors
    /// As [`LiveView::update`].
    pub fn relight(&mut self, model: &mut Model) -> Result<(Vec3, u32, bool)> {
        let towards = direction(self.elevation, self.azimuth);
        let solve = self.live.update(&[Sun {
            direction: towards.to_array(),
            irradiance: self.irradiance.to_array(),
        }])?;
        self.live.write_pages(&mut self.pages);
        let moved = self.move_probes(model)?;
        Ok((towards, solve.iterations, moved))
    }

    /// The model's probes for the current solution (the model's as loaded,
    /// plus the change since the starting sun), and the probe-lit vertices
    /// lit from them; false where nothing moved (no probes, or no probes'
    /// rays).
    ///
    /// # Errors
    /// A `live.bin` whose probe count is not the model's probes'.
    pub fn move_probes(&mut self, model: &mut Model) -> Result<bool> {
        let (Some(delta0), Some(probes)) = (&self.delta0, &mut model.probes) else {
            return Ok(false);
        };
        let Some(delta) = self.live.probe_delta() else {
            return Ok(false);
        };
        if delta.len() != probes.sh.len() {
            bail!(
                "live.bin has {} probes, probes.json {}",
                delta.len(),
                probes.sh.len()
            );
        }
        if self.sh0.is_none() {
            self.sh0 = Some(probes.sh.clone());
            self.probe_lit = probe_lit_ranges(&model.vertices);
        }
        let sh0 = self.sh0.as_ref().expect("taken above");
        for (((sh, s0), d), d0) in probes.sh.iter_mut().zip(sh0).zip(&delta).zip(delta0) {
            for k in 0..9 {
                sh[k] = s0[k] + (Vec3::from(d[k]) - Vec3::from(d0[k]));
            }
        }
        let probes = model.probes.as_ref();
        for r in &self.probe_lit {
            for v in &mut model.vertices[r.clone()] {
                v.probe = super::probe_light::vertex_light(
                    probes,
                    Vec3::from(v.position),
                    Vec3::from(v.normal),
                );
            }
        }
        Ok(true)
    }
}

/// The runs of consecutive vertices lit by the probes.
fn probe_lit_ranges(vertices: &[super::gpu::Vertex]) -> Vec<std::ops::Range<usize>> {
    let mut out: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, v) in vertices.iter().enumerate() {
        if v.probe[3] != super::gpu::PROBE_LIT {
            continue;
        }
        match out.last_mut() {
            Some(r) if r.end == i => r.end = i + 1,
            _ => out.push(i..i + 1),
        }
    }
    out
}
