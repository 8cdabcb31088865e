//! The run-time solve ([`Live::update`]): the sun's direct light on the
//! patches, Jacobi iterations warm-started from the last solution, and the
//! texels' bounce light reconstructed from the patches.

use crate::directions;
use crate::format::LiveData;
use crate::{LiveError, Result};
use rayon::prelude::*;

/// A live light's state at run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Towards the light (any length > 0; y up, as glTF).
    pub direction: [f32; 3],
    /// Irradiance on a surface facing it, W/m² (linear RGB).
    pub irradiance: [f32; 3],
}

impl Sun {
    /// The unit direction.
    ///
    /// # Errors
    /// [`LiveError::Input`] for a direction of zero length or not finite.
    pub fn unit(&self) -> Result<[f32; 3]> {
        let d = self.direction;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !len.is_finite() || len < 1e-12 {
            return Err(LiveError::Input(format!(
                "sun direction {d:?}: of zero length or not finite"
            )));
        }
        if !self.irradiance.iter().all(|x| x.is_finite() && *x >= 0.0) {
            return Err(LiveError::Input(format!(
                "sun irradiance {:?}: must be finite and ≥ 0",
                self.irradiance
            )));
        }
        Ok([d[0] / len, d[1] / len, d[2] / len])
    }
}

/// What one solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Solve {
    /// Jacobi iterations run.
    pub iterations: u32,
    /// Σ|ΔL| / Σ|L| of the last one.
    pub residual: f32,
}

/// A live bake at run time: its data and the current solution.
pub struct Live {
    data: LiveData,
    /// F's entries as f32 (decoded once).
    vals: Vec<f32>,
    /// Per patch: D (irradiance / π) of the current suns.
    direct: Vec<[f32; 3]>,
    /// Per patch: outgoing radiance L (warm start of the next solve).
    radiance: Vec<[f32; 3]>,
    /// Per patch: F L, the bounce light arriving (irradiance / π).
    indirect: Vec<[f32; 3]>,
    /// Per texel: its four corners' bilinear weights, normalised over the
    /// corners present (all 0: the texel takes its own patch's value).
    weights: Vec<[f32; 4]>,
    /// Texels by patch: patch p's are `by_patch[starts[p]..starts[p + 1]]`.
    starts: Vec<u32>,
    by_patch: Vec<u32>,
    /// Per page and pixel: the texel whose value it shows (u32::MAX: none),
    /// the padding's copies resolved to their texel.
    sources: Vec<Vec<u32>>,
    /// With probe hits: per ray, its SH basis × 4π/n, and the fill.
    probe_basis: Vec<[f32; 9]>,
    probe_fill: Vec<(u32, Vec<u32>)>,
    /// [`Live::write_pages`]' texel buffers, kept between updates.
    scratch: (Vec<[f32; 3]>, Vec<[f32; 3]>),
}

impl Live {
    /// The runtime of `data`, its solution zero (no sun yet).
    pub fn new(data: LiveData) -> Live {
        let p = data.header.patches as usize;
        let vals = data
            .matrix
            .vals
            .iter()
            .map(|&v| half::f16::from_bits(v).to_f32())
            .collect();
        let weights = corner_weights(&data);
        let (starts, by_patch) = texels_by_patch(&data);
        let sources = pixel_sources(&data);
        let (probe_basis, probe_fill) = match (&data.header.probes, &data.probes) {
            (Some(q), Some(hits)) => (
                crate::probes::weighted_basis(q.rays),
                crate::probes::fill_plan(&q.grids, &hits.valid),
            ),
            _ => (Vec::new(), Vec::new()),
        };
        Live {
            data,
            vals,
            direct: vec![[0.0; 3]; p],
            radiance: vec![[0.0; 3]; p],
            indirect: vec![[0.0; 3]; p],
            weights,
            starts,
            by_patch,
            sources,
            probe_basis,
            probe_fill,
            scratch: (Vec::new(), Vec::new()),
        }
    }

    /// The file's content back (the solution dropped).
    pub fn into_data(self) -> LiveData {
        self.data
    }

    /// The suns as baked (the header's lights).
    pub fn baked_suns(&self) -> Vec<Sun> {
        (self.data.header.lights.iter())
            .map(|l| Sun {
                direction: l.direction,
                irradiance: l.irradiance,
            })
            .collect()
    }

    /// Per probe, the change of the live layer's radiance SH since the
    /// baked suns (the patches' L then: [`crate::format::ProbeHits`]'s
    /// `baked`), filled into the invalid probes as the bake fills them
    /// ([`crate::probes`]): the live layer's probes now are its baked ones
    /// (`probes_<layer>.bin`) + this. `None` for a file without probe
    /// hits.
    pub fn probe_delta(&self) -> Option<Vec<crate::probes::Sh9>> {
        let hits = self.data.probes.as_ref()?;
        let baked = &hits.baked;
        let dl: Vec<[f32; 3]> = (self.radiance.iter().zip(baked))
            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
            .collect();
        let mut delta = crate::probes::delta(hits, &self.probe_basis, &dl);
        crate::probes::apply_fill(&self.probe_fill, &mut delta, crate::probes::mean_sh);
        Some(delta)
    }

    /// The file's content.
    pub fn data(&self) -> &LiveData {
        &self.data
    }

    /// Per patch, the current suns' direct light D (irradiance / π).
    pub fn patch_direct(&self) -> &[[f32; 3]] {
        &self.direct
    }

    /// Per patch, the current bounce light F L (irradiance / π).
    pub fn patch_indirect(&self) -> &[[f32; 3]] {
        &self.indirect
    }

    /// Per patch, the current outgoing radiance L.
    pub fn patch_radiance(&self) -> &[[f32; 3]] {
        &self.radiance
    }

    /// Sets the live lights (one [`Sun`] per [`crate::Header::lights`],
    /// in order) and solves to the bake's tolerance from the last solution.
    ///
    /// # Errors
    /// [`LiveError::Input`] for the wrong number of suns or a bad one.
    pub fn update(&mut self, suns: &[Sun]) -> Result<Solve> {
        self.set_suns(suns)?;
        Ok(self.solve(self.data.header.max_iterations))
    }

    /// D for `suns`: per patch, Σ over the lights of E × the four grid
    /// directions' table values weighted bilinearly ([`directions::weights`]).
    ///
    /// # Errors
    /// As [`Live::update`].
    pub fn set_suns(&mut self, suns: &[Sun]) -> Result<()> {
        let h = &self.data.header;
        if suns.len() != h.lights.len() {
            return Err(LiveError::Input(format!(
                "{} sun(s) given, the bake has {} live light(s)",
                suns.len(),
                h.lights.len()
            )));
        }
        let p = h.patches as usize;
        let mut terms = Vec::new();
        for ((sun, table), light) in suns.iter().zip(&self.data.suns).zip(&h.lights) {
            let d = sun.unit()?;
            let w: Option<Vec<(u32, f32)>> = match &light.path {
                Some(path) => directions::path_weights(path, d).map(|w| w.to_vec()),
                None => directions::weights(h.grid, d).map(|w| w.to_vec()),
            };
            if let Some(w) = w {
                // Table bytes are π D × 255 for a unit sun.
                let scale = sun.irradiance.map(|e| e / (255.0 * std::f32::consts::PI));
                for (k, wk) in w {
                    if wk > 0.0 {
                        let at = k as usize * p;
                        terms.push((&table[at..at + p], wk, scale));
                    }
                }
            }
        }
        self.direct.par_iter_mut().enumerate().for_each(|(i, d)| {
            let mut v = [0.0f32; 3];
            for (t, wk, scale) in &terms {
                let x = t[i] as f32 * wk;
                for c in 0..3 {
                    v[c] += x * scale[c];
                }
            }
            *d = v;
        });
        Ok(())
    }

    /// Sets the patches' direct light D (irradiance / π) as given, in
    /// place of [`Live::set_suns`]' (a check against an exact D, or a run
    /// time that computes its own).
    ///
    /// # Errors
    /// [`LiveError::Input`] for a length other than the patch count or a
    /// value negative or not finite.
    pub fn set_direct(&mut self, direct: &[[f32; 3]]) -> Result<()> {
        if direct.len() != self.direct.len()
            || direct
                .iter()
                .flatten()
                .any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err(LiveError::Input(format!(
                "direct light: {} values for {} patches, each finite and ≥ 0",
                direct.len(),
                self.direct.len()
            )));
        }
        self.direct.copy_from_slice(direct);
        Ok(())
    }

    /// Jacobi iterations L ← ρ ⊙ (D + F L) from the current L until the
    /// relative change Σ|ΔL| / Σ|L| is below the bake's tolerance, at most
    /// `max_iterations`. Rows are summed in column order, so the result
    /// does not depend on the thread count.
    ///
    /// F L of the current L is kept between solves (`indirect`, zero with
    /// L at the start), so each iteration is one product: the first step
    /// of a solve reuses the last one's F L, and the bounce light of the
    /// final L is the last iteration's product.
    pub fn solve(&mut self, max_iterations: u32) -> Solve {
        let tolerance = self.data.header.tolerance;
        let mut out = Solve::default();
        while out.iterations < max_iterations {
            let next: Vec<[f32; 3]> = (self.direct.par_iter().zip(&self.indirect))
                .zip(&self.data.albedo)
                .map(|((d, f), a)| [0, 1, 2].map(|c| a[c] * (d[c] + f[c])))
                .collect();
            out.residual = relative_change(&next, &self.radiance);
            self.radiance = next;
            self.indirect = self.product(&self.radiance);
            out.iterations += 1;
            if out.residual < tolerance {
                break;
            }
        }
        out
    }

    /// F x, one row per task.
    fn product(&self, x: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let m = &self.data.matrix;
        (0..self.data.header.patches as usize)
            .into_par_iter()
            .map(|i| {
                let (lo, hi) = (m.rows[i] as usize, m.rows[i + 1] as usize);
                let mut acc = [0.0f32; 3];
                for (f, &j) in self.vals[lo..hi].iter().zip(&m.cols[lo..hi]) {
                    let v = x[j as usize];
                    acc[0] += f * v[0];
                    acc[1] += f * v[1];
                    acc[2] += f * v[2];
                }
                acc
            })
            .collect()
    }

    /// Per texel, the live lights' bounce light (irradiance / π): the
    /// patches' F L interpolated bilinearly between the centres of the
    /// patches at its corners (the weights from its pixel's place in its
    /// k × k block, as the bake computes them), shifted per patch to keep
    /// the patch's mean, clamped at 0 (the bake's first pass).
    pub fn texels(&self) -> Vec<[f32; 3]> {
        let (mut bil, mut out) = (Vec::new(), Vec::new());
        self.texels_into(&mut bil, &mut out);
        out
    }

    /// [`Live::texels`] into `out`, with `bil` for the bilinear values
    /// (both buffers reused: no texel-sized allocation per update).
    fn texels_into(&self, bil: &mut Vec<[f32; 3]>, out: &mut Vec<[f32; 3]>) {
        let t = &self.data.texels;
        let values = &self.indirect;
        bil.resize(t.patch.len(), [0.0; 3]);
        (bil.par_iter_mut().zip(&self.weights))
            .zip(t.corners.par_iter().zip(&t.patch))
            .for_each(|((b, w), (c, &own))| {
                let mut acc = [0.0f32; 3];
                let mut any = false;
                for (&q, &wt) in c.iter().zip(w) {
                    if q != u32::MAX && wt > 0.0 {
                        any = true;
                        let v = values[q as usize];
                        acc = [acc[0] + v[0] * wt, acc[1] + v[1] * wt, acc[2] + v[2] * wt];
                    }
                }
                *b = if any { acc } else { values[own as usize] };
            });
        // Each patch's shift: its value less its texels' area-weighted mean.
        let shift: Vec<[f32; 3]> = (0..values.len())
            .into_par_iter()
            .map(|p| {
                let ids = &self.by_patch[self.starts[p] as usize..self.starts[p + 1] as usize];
                let mut mean = [0.0f32; 3];
                for &i in ids {
                    let (b, s) = (bil[i as usize], t.share[i as usize]);
                    mean = [mean[0] + b[0] * s, mean[1] + b[1] * s, mean[2] + b[2] * s];
                }
                [0, 1, 2].map(|c| values[p][c] - mean[c])
            })
            .collect();
        out.resize(t.patch.len(), [0.0; 3]);
        (out.par_iter_mut().zip(&*bil))
            .zip(&t.patch)
            .for_each(|((o, b), &p)| {
                let s = shift[p as usize];
                *o = [0, 1, 2].map(|c| (b[c] + s[c]).max(0.0));
            });
    }

    /// The live layer's pages (row-major RGB per page, irradiance / π):
    /// each texel at its pixel, the padding rings copied from their
    /// neighbours (the bake's dilation, as copies), every other pixel 0.
    pub fn pages(&mut self) -> Vec<Vec<[f32; 3]>> {
        let mut pages = Vec::new();
        self.write_pages(&mut pages);
        pages
    }

    /// [`Live::pages`] into `pages`, reusing its buffers (an engine's
    /// frame loop: no page-sized allocation per update).
    pub fn write_pages(&mut self, pages: &mut Vec<Vec<[f32; 3]>>) {
        let (mut bil, mut texels) = std::mem::take(&mut self.scratch);
        self.texels_into(&mut bil, &mut texels);
        pages.resize_with(self.sources.len(), Vec::new);
        for (page, src) in pages.iter_mut().zip(&self.sources) {
            page.resize(src.len(), [0.0; 3]);
            page.par_iter_mut().zip(src).for_each(|(px, &t)| {
                *px = if t == u32::MAX {
                    [0.0; 3]
                } else {
                    texels[t as usize]
                };
            });
        }
        self.scratch = (bil, texels);
    }
}

/// Per texel, the bilinear weights of its corners (see [`Live::texels`]),
/// normalised over the corners present; all 0 where none is.
fn corner_weights(data: &LiveData) -> Vec<[f32; 4]> {
    let h = &data.header;
    let t = &data.texels;
    let k = h.block as f32;
    (0..t.patch.len())
        .map(|i| {
            let width = h.pages[t.page[i] as usize].width;
            let (x, y) = (t.pixel[i] % width, t.pixel[i] / width);
            // As the bake: f = (xy + ½) / k − ½, w = f − ⌊f⌋.
            let (fx, fy) = ((x as f32 + 0.5) / k - 0.5, (y as f32 + 0.5) / k - 0.5);
            let (wx, wy) = (fx - fx.floor(), fy - fy.floor());
            let w = [
                (1.0 - wx) * (1.0 - wy),
                wx * (1.0 - wy),
                (1.0 - wx) * wy,
                wx * wy,
            ];
            let mut sum = 0.0f32;
            for (c, wt) in t.corners[i].iter().zip(w) {
                if *c != u32::MAX {
                    sum += wt;
                }
            }
            let mut out = [0.0f32; 4];
            if sum > 0.0 {
                for ((o, c), wt) in out.iter_mut().zip(&t.corners[i]).zip(w) {
                    if *c != u32::MAX {
                        *o = wt / sum;
                    }
                }
            }
            out
        })
        .collect()
}

/// Texel ids grouped by patch (counting sort): (starts, ids).
fn texels_by_patch(data: &LiveData) -> (Vec<u32>, Vec<u32>) {
    let p = data.header.patches as usize;
    let mut starts = vec![0u32; p + 1];
    for &q in &data.texels.patch {
        starts[q as usize + 1] += 1;
    }
    for i in 0..p {
        starts[i + 1] += starts[i];
    }
    let mut next = starts.clone();
    let mut ids = vec![0u32; data.texels.patch.len()];
    for (t, &q) in data.texels.patch.iter().enumerate() {
        ids[next[q as usize] as usize] = t as u32;
        next[q as usize] += 1;
    }
    (starts, ids)
}

/// Per page and pixel, the texel it shows: its own, or for a padding
/// pixel its neighbour's, resolved in ring order.
fn pixel_sources(data: &LiveData) -> Vec<Vec<u32>> {
    let h = &data.header;
    let t = &data.texels;
    let mut out: Vec<Vec<u32>> = (h.pages.iter())
        .map(|s| vec![u32::MAX; s.width as usize * s.height as usize])
        .collect();
    for (texel, (&i, &page)) in t.pixel.iter().zip(&t.page).enumerate() {
        out[page as usize][i as usize] = texel as u32;
    }
    for ((page, list), size) in out.iter_mut().zip(&t.padding).zip(&h.pages) {
        let w = size.width as i64;
        for &(i, n) in list {
            let from = i as i64 + (n as i64 / 3 - 1) * w + (n as i64 % 3 - 1);
            page[i as usize] = page[from as usize];
        }
    }
    out
}

/// Σ|a − b| / Σ|a| (0 when a is all zero), summed in order.
fn relative_change(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    let (mut change, mut total) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            change += (x[c] - y[c]).abs() as f64;
            total += x[c].abs() as f64;
        }
    }
    if total > 0.0 {
        (change / total) as f32
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::{Header, LiveLight, Matrix, PageSize, TexelMap};

    /// Two facing patches (F₀₁ = F₁₀ = f), one texel each, a 2 × 1 page.
    fn two_patches(f: f32, rho: f32) -> LiveData {
        let grid = 3;
        let dirs = (grid * grid) as usize;
        // Patch 0 fully lit by every direction, patch 1 never.
        let mut sun = vec![0u8; dirs * 2];
        for k in 0..dirs {
            sun[k * 2] = 255;
        }
        LiveData {
            header: Header {
                version: crate::format::VERSION,
                patches: 2,
                texels: 2,
                entries: 2,
                block: 1,
                grid,
                pages: vec![PageSize {
                    width: 3,
                    height: 1,
                }],
                padding: vec![1],
                tolerance: 1e-6,
                max_iterations: 200,
                layer: "live".into(),
                lights: vec![LiveLight {
                    name: "sun".into(),
                    direction: [0.0, 1.0, 0.0],
                    irradiance: [1.0; 3],
                    path: None,
                }],
                sky: None,
                probes: None,
            },
            albedo: vec![[rho; 3]; 2],
            matrix: Matrix {
                rows: vec![0, 1, 2],
                cols: vec![1, 0],
                vals: vec![half::f16::from_f32(f).to_bits(); 2],
            },
            suns: vec![sun],
            texels: TexelMap {
                patch: vec![0, 1],
                share: vec![1.0, 1.0],
                corners: vec![
                    [0, u32::MAX, u32::MAX, u32::MAX],
                    [1, u32::MAX, u32::MAX, u32::MAX],
                ],
                pixel: vec![0, 1],
                page: vec![0, 0],
                // Pixel 2 copies its left neighbour (3 × 3 index 3).
                padding: vec![vec![(2, 3)]],
            },
            probes: None,
        }
    }

    #[test]
    fn two_patches_match_the_closed_form() {
        // D₀ = E/π, D₁ = 0; L₀ = ρ(D₀ + f L₁), L₁ = ρ f L₀ ⇒
        // L₀ = ρ D₀ / (1 − ρ² f²), and the texels get F L.
        let (f, rho) = (0.5f32, 0.8f32);
        let data = two_patches(f, rho);
        let f = half::f16::from_f32(f).to_f32();
        let mut live = Live::new(data);
        let s = live
            .update(&[Sun {
                direction: [0.2, 1.0, 0.1],
                irradiance: [3.0; 3],
            }])
            .unwrap();
        assert!(s.residual < 1e-6);
        let d0 = 3.0 / std::f32::consts::PI;
        let l0 = rho * d0 / (1.0 - rho * rho * f * f);
        let l1 = rho * f * l0;
        let t = live.texels();
        assert!((t[0][1] - f * l1).abs() < 1e-5 * l0, "{:?}", t[0]);
        assert!((t[1][2] - f * l0).abs() < 1e-5 * l0, "{:?}", t[1]);
        assert_eq!(live.pages()[0][1], t[1]);
        assert_eq!(live.pages()[0][2], t[1], "the padding copies its neighbour");
    }

    #[test]
    fn a_sun_below_the_horizon_lights_nothing_and_bad_suns_are_errors() {
        let mut live = Live::new(two_patches(0.5, 0.8));
        live.update(&[Sun {
            direction: [0.0, -1.0, 0.0],
            irradiance: [1.0; 3],
        }])
        .unwrap();
        assert_eq!(live.texels(), vec![[0.0; 3]; 2]);
        for d in [[0.0; 3], [f32::NAN, 1.0, 0.0]] {
            let e = live
                .update(&[Sun {
                    direction: d,
                    irradiance: [1.0; 3],
                }])
                .unwrap_err();
            assert!(e.to_string().contains("zero length or not finite"), "{e}");
        }
        assert!(live.update(&[]).is_err());
    }

    #[test]
    fn the_file_round_trips_and_damage_is_named() {
        let data = two_patches(0.5, 0.8);
        let bytes = data.to_bytes();
        assert_eq!(LiveData::from_bytes(&bytes).unwrap(), data);
        let msg = |b: &[u8]| LiveData::from_bytes(b).unwrap_err().to_string();
        assert!(msg(&bytes[..bytes.len() - 3]).contains("truncated"));
        assert!(msg(&bytes[..10]).contains("truncated"));
        let mut flipped = bytes.clone();
        *flipped.last_mut().unwrap() ^= 0x40;
        assert!(msg(&flipped).contains("checksum"));
        let mut magic = bytes.clone();
        magic[0] = b'X';
        assert!(msg(&magic).contains("magic"));
        // A valid checksum over an index out of range: named, not a panic.
        let mut bad = data.clone();
        bad.texels.patch[1] = 7;
        assert!(msg(&bad.to_bytes()).contains("patch out of range"));
        let mut bad = data.clone();
        bad.matrix.cols[0] = 2;
        assert!(msg(&bad.to_bytes()).contains("columns out of order or range"));
        let mut bad = data;
        bad.texels.padding[0][0].1 = 5; // right of the last pixel
        assert!(msg(&bad.to_bytes()).contains("neighbour out of its page"));
    }

    /// The two patches with two probes of two rays: the first sees
    /// patch 0 then patch 1, the second (invalid) is filled from it; the
    /// baked radiance the solution at the baked sun.
    fn with_probes(mut data: LiveData) -> LiveData {
        data.header.probes = Some(crate::format::ProbeHeader {
            count: 2,
            rays: 2,
            grids: vec![crate::format::ProbeGrid {
                first: 0,
                resolution: [2, 1, 1],
            }],
        });
        let mut live = Live::new(data.clone());
        live.update(&live.baked_suns()).unwrap();
        data.probes = Some(crate::format::ProbeHits {
            valid: vec![true, false],
            hits: vec![0, 1, u32::MAX, u32::MAX],
            baked: live.patch_radiance().to_vec(),
        });
        data
    }

    /// At the baked sun the probes do not change; at twice its
    /// irradiance they change by the baked patches' L projected along the
    /// rays (transport is linear), and the invalid probe takes its
    /// neighbour's change. The file keeps the hits, and a hit out of range
    /// is named.
    #[test]
    fn the_probes_follow_the_sun() {
        let data = with_probes(two_patches(0.5, 0.8));
        let bytes = data.to_bytes();
        assert_eq!(LiveData::from_bytes(&bytes).unwrap(), data);
        let mut live = Live::new(data.clone());
        let baked = live.baked_suns();
        live.update(&baked).unwrap();
        let zero = live.probe_delta().unwrap();
        assert!(
            zero.iter().flatten().flatten().all(|v| v.abs() < 1e-6),
            "{zero:?}"
        );
        let l = live.patch_radiance().to_vec();
        let twice = [Sun {
            irradiance: [2.0; 3],
            ..baked[0]
        }];
        live.update(&twice).unwrap();
        let d = live.probe_delta().unwrap();
        let y = crate::probes::weighted_basis(2);
        for k in 0..9 {
            let want = l[0][0] * y[0][k] + l[1][0] * y[1][k];
            assert!(
                (d[0][k][0] - want).abs() < 1e-4 * l[0][0],
                "{k}: {:?} {want}",
                d[0][k]
            );
            assert_eq!(d[1][k], d[0][k], "filled from its neighbour");
        }
        let mut bad = data;
        bad.probes.as_mut().unwrap().hits[1] = 9;
        let e = LiveData::from_bytes(&bad.to_bytes()).unwrap_err();
        assert!(
            e.to_string().contains("probe ray's patch out of range"),
            "{e}"
        );
    }
}
