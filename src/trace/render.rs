//! Images by path tracing from a pinhole camera: the reference (pure path
//! tracing or BDPT) and the final pass that reads the lightmaps. Each pixel
//! gets its own random stream, so images are identical whatever the thread
//! count; the per-pixel variance of the mean is kept for comparisons
//! (Mitsuba-style z-tests).

pub use super::view::View;
use super::Tracer;
use crate::error::Result;
use crate::layout::geometry::Geometry;
use crate::scene::texture::linear_to_srgb;
use crate::util::sampling::{stratified, Stream};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::path::Path;

/// Stream purpose id of camera paths.
const PURPOSE: u64 = crate::util::sampling::purpose::RENDER;

/// Which estimator renders an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Unidirectional path tracing with next-event estimation and MIS.
    Path,
    /// Bidirectional path tracing (Veach 1997) with balance-heuristic MIS.
    Bdpt,
    /// The final pass by sphere tracing the level's signed distance field
    /// ([`super::sphere`]; needs the field, so [`render`] takes it as
    /// `Path`).
    SphereTrace,
}

/// A rendered image: linear radiance and the variance of each pixel's mean.
#[derive(Clone, Debug, Default)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major radiance (top row first).
    pub pixels: Vec<Vec3>,
    /// Per-pixel variance of the mean, per channel.
    pub variance: Vec<Vec3>,
}

impl Image {
    /// Mean over all pixels.
    pub fn mean(&self) -> Vec3 {
        self.pixels.iter().copied().sum::<Vec3>() / self.pixels.len().max(1) as f32
    }

    /// Writes the linear image as float OpenEXR (atomically).
    ///
    /// # Errors
    /// [`crate::Error::Encode`] or [`crate::Error::Io`].
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        crate::util::files::write_exr_rgb(path, self.width, self.height, &self.pixels)
    }

    /// Writes an 8-bit sRGB PNG, exposed by 2^`exposure_ev` and tone-mapped
    /// with the ACES filmic fit of Narkowicz (2015).
    ///
    /// # Errors
    /// [`crate::Error::Encode`] or [`crate::Error::Io`].
    pub fn write_png(&self, path: &Path, exposure_ev: f32) -> Result<()> {
        let scale = 2f32.powf(exposure_ev);
        let aces = |x: f32| {
            let x = x * scale;
            ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
        };
        let img = image::RgbImage::from_fn(self.width, self.height, |x, y| {
            let v = self.pixels[(y * self.width + x) as usize];
            let c = |c: f32| (linear_to_srgb(aces(c)) * 255.0 + 0.5) as u8;
            image::Rgb([c(v.x), c(v.y), c(v.z)])
        });
        crate::util::files::write_png(path, &img)
    }
}

/// A finished bake read back for the final pass: the geometry with the
/// bake's lightmap coordinates (the unwrap is re-run with the bake's
/// settings, which reproduces its atlas exactly: the unwrap is
/// deterministic), the lightmap pages from its EXR files, and its sky.
pub struct BakedLightmaps {
    /// World triangles with the bake's lightmap coordinates.
    pub geometry: Geometry,
    /// Page size.
    pub width: u32,
    /// Page size.
    pub height: u32,
    /// Irradiance / π pages.
    pub pages: Vec<Vec<Vec3>>,
    /// The bake's settings.
    pub config: crate::BakeConfig,
}

/// Reads the bake in `dir` (its `report.json` and `lightmap_<page>.exr`)
/// for `scene`.
///
/// # Errors
/// [`crate::Error::Io`] when a file is missing or unreadable,
/// [`crate::Error::Parse`]-like [`crate::Error::Invalid`] when the bake does
/// not match the scene (page count or size).
pub fn load_bake(scene: &crate::scene::Scene, dir: &Path) -> Result<BakedLightmaps> {
    use crate::Error;
    let report_path = dir.join("report.json");
    let text = std::fs::read_to_string(&report_path).map_err(|source| Error::Io {
        path: report_path.clone(),
        source,
    })?;
    let invalid = |location: &str, message: String| Error::Invalid {
        path: report_path.clone(),
        location: location.into(),
        message,
    };
    let report: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| invalid("report.json", e.to_string()))?;
    let config: crate::BakeConfig = serde_json::from_value(report["settings"].clone())
        .map_err(|e| invalid("settings", e.to_string()))?;
    let atlas = crate::layout::atlas::unwrap(scene, &config)?;
    let geometry = Geometry::new(scene, &atlas);
    let mut pages = Vec::new();
    for page in 0..atlas.page_count {
        let path = dir.join(format!("lightmap_{page}.exr"));
        let (w, h, values) = read_exr_rgb(&path)?;
        if (w, h) != (atlas.width, atlas.height) {
            return Err(Error::Invalid {
                path,
                location: format!("lightmap_{page}.exr"),
                message: format!(
                    "is {w}×{h} but this scene's atlas with the bake's settings is {}×{}: the bake is of another scene or version (bake again)",
                    atlas.width, atlas.height
                ),
            });
        }
        pages.push(values);
    }
    Ok(BakedLightmaps {
        geometry,
        width: atlas.width,
        height: atlas.height,
        pages,
        config,
    })
}

/// Reads the first RGB(A) layer of an OpenEXR file as linear RGB: (width,
/// height, pixels row by row).
///
/// # Errors
/// [`crate::Error::Invalid`] naming the file when it is not a readable EXR.
pub fn read_exr_rgb(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (
                resolution.width(),
                vec![Vec3::ZERO; resolution.width() * resolution.height()],
            )
        },
        |(w, pixels): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| crate::Error::Invalid {
        path: path.to_path_buf(),
        location: "exr".into(),
        message: e.to_string(),
    })?;
    let size = image.layer_data.size;
    let (_, pixels) = image.layer_data.channel_data.pixels;
    Ok((size.width() as u32, size.height() as u32, pixels))
}

/// Independent passes a BDPT image is made of: the per-pixel variance of
/// the mean comes from their spread (splatted light-tracing samples land in
/// any pixel, so per-sample variances are not at hand).
pub const BDPT_PASSES: u32 = 4;

/// Renders `width × height` pixels at `spp` stratified samples each.
/// `advance` is called with the number of rows done; a BDPT image counts
/// its rows [`BDPT_PASSES`] times.
pub fn render(
    tracer: &Tracer,
    view: &View,
    size: (u32, u32),
    spp: u32,
    integrator: Integrator,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Image {
    let spp = spp.max(1);
    if integrator == Integrator::Bdpt {
        return render_bdpt(tracer, view, size, spp, seed, advance);
    }
    render_pixels(view, size, spp, (seed, PURPOSE), advance, |dir, rng| {
        tracer.radiance(view.eye, dir, rng)
    })
}

/// Every pixel of `size` at `spp` stratified samples, each the camera ray
/// through its film point given to `radiance` with the pixel's own stream
/// (`seed`, purpose); the mean and the variance of the mean per pixel.
/// NaN and infinite samples are dropped ([`finite`]).
pub(crate) fn render_pixels(
    view: &View,
    (width, height): (u32, u32),
    spp: u32,
    (seed, purpose): (u64, u64),
    advance: &(dyn Fn(u64) + Sync),
    radiance: impl Fn(Vec3, &mut Stream) -> Vec3 + Sync,
) -> Image {
    let spp = spp.max(1);
    let aspect = width as f32 / height as f32;
    let rows: Vec<Vec<(Vec3, Vec3)>> = (0..height)
        .into_par_iter()
        .map(|y| {
            let row = (0..width)
                .map(|x| {
                    let pixel = (y * width + x) as u64;
                    let mut rng = Stream::new(seed, purpose, pixel);
                    let (mut sum, mut sq) = (Vec3::ZERO, Vec3::ZERO);
                    for k in 0..spp {
                        let j = stratified(k, spp, rng.next_vec2());
                        let dir = view.ray(film_point(x, y, j, (width, height)), aspect);
                        let l = finite(radiance(dir, &mut rng));
                        sum += l;
                        sq += l * l;
                    }
                    let n = spp as f32;
                    let mean = sum / n;
                    let var = ((sq / n - mean * mean).max(Vec3::ZERO)) / (n - 1.0).max(1.0);
                    (mean, var)
                })
                .collect();
            advance(1);
            row
        })
        .collect();
    let (pixels, variance) = rows.into_iter().flatten().unzip();
    Image {
        width,
        height,
        pixels,
        variance,
    }
}

/// Film point in [−1, 1]² (y up) of pixel (x, y) at sub-pixel `j`.
pub(crate) fn film_point(x: u32, y: u32, j: Vec2, (width, height): (u32, u32)) -> Vec2 {
    Vec2::new(
        2.0 * (x as f32 + j.x) / width as f32 - 1.0,
        1.0 - 2.0 * (y as f32 + j.y) / height as f32,
    )
}

/// A NaN or infinite sample would poison its pixel: dropped.
fn finite(l: Vec3) -> Vec3 {
    if l.is_finite() {
        l
    } else {
        Vec3::ZERO
    }
}

/// BDPT: [`BDPT_PASSES`] passes of ⌈spp / passes⌉ samples; rows in a fixed
/// number of chunks, each with its own splat film, summed in chunk order
/// (deterministic whatever the thread count).
fn render_bdpt(
    tracer: &Tracer,
    view: &View,
    size: (u32, u32),
    spp: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Image {
    const CHUNKS: u32 = 8;
    let (width, height) = size;
    let aspect = width as f32 / height as f32;
    let bdpt = super::bdpt::Bdpt::new(tracer);
    let per = spp.div_ceil(BDPT_PASSES).max(1);
    let n = (width * height) as usize;
    let rows_per = height.div_ceil(CHUNKS);
    let mut passes: Vec<Vec<Vec3>> = Vec::new();
    for pass in 0..BDPT_PASSES {
        let parts: Vec<(Vec<Vec3>, Vec<Vec3>)> = (0..CHUNKS)
            .into_par_iter()
            .map(|c| {
                let mut film = vec![Vec3::ZERO; n];
                let mut own = Vec::new();
                let mut splats = Vec::new();
                for y in c * rows_per..((c + 1) * rows_per).min(height) {
                    for x in 0..width {
                        let pixel = (y * width + x) as u64;
                        let mut rng = Stream::new(seed, PURPOSE + 16 * (pass as u64 + 1), pixel);
                        let mut sum = Vec3::ZERO;
                        for k in 0..per {
                            let j = stratified(k, per, rng.next_vec2());
                            let dir = view.ray(film_point(x, y, j, size), aspect);
                            splats.clear();
                            sum += finite(bdpt.radiance(view, aspect, dir, &mut rng, &mut splats));
                            for (f, v) in &splats {
                                let px = (((f.x + 1.0) * 0.5 * width as f32) as u32).min(width - 1);
                                let py =
                                    (((1.0 - f.y) * 0.5 * height as f32) as u32).min(height - 1);
                                film[(py * width + px) as usize] += finite(*v);
                            }
                        }
                        own.push(sum);
                    }
                    advance(1);
                }
                (own, film)
            })
            .collect();
        let mut image = Vec::with_capacity(n);
        let mut film = vec![Vec3::ZERO; n];
        for (own, f) in parts {
            image.extend(own);
            for (a, b) in film.iter_mut().zip(f) {
                *a += b;
            }
        }
        passes.push(
            image
                .into_iter()
                .zip(film)
                .map(|(a, b)| (a + b) / per as f32)
                .collect(),
        );
    }
    let k = BDPT_PASSES as f32;
    let pixels: Vec<Vec3> = (0..n)
        .map(|i| passes.iter().map(|p| p[i]).sum::<Vec3>() / k)
        .collect();
    let variance = (0..n)
        .map(|i| {
            let m = pixels[i];
            passes.iter().map(|p| (p[i] - m) * (p[i] - m)).sum::<Vec3>() / (k * (k - 1.0))
        })
        .collect();
    Image {
        width,
        height,
        pixels,
        variance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_centre_ray_is_forward() {
        let v = View::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 1.0);
        assert!((v.ray(Vec2::ZERO, 1.5) - Vec3::NEG_Z).length() < 1e-6);
        // The top edge of the film is yfov/2 above the axis.
        let top = v.ray(Vec2::new(0.0, 1.0), 1.0);
        assert!((top.dot(Vec3::NEG_Z).acos() - 0.5).abs() < 1e-5);
        assert!(top.y > 0.0);
    }
}
