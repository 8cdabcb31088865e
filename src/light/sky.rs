//! The sky: what rays that leave the scene see. Either a uniform
//! colour or an HDRI environment ("sky map", `--sky-map env.exr|env.hdr`,
//! turned by `--sky-rotation DEGREES`, scaled by `--sky-intensity`): an
//! infinite area light (Pharr, Jakob & Humphreys, *Physically Based
//! Rendering*, 3rd ed., §12.6 and §13.6.5) that the light transport looks
//! up for escaped rays ([`Sky::radiance`]) and importance-samples for
//! next-event estimation with MIS ([`SkyMap::sample`], [`SkyMap::pdf`]).
//!
//! **Projection.** Equirectangular, linear RGB, in Blender's convention
//! carried into glTF's axes (+Y up; Blender's −Y is glTF's +Z). A world
//! direction d (before rotation, see below) is the image point
//!
//! ```text
//! u = 0.5 + atan2(−d.z, −d.x) / (2π),   v = acos(d.y) / π
//! column = ⌊u·W⌋ (wrapping),  row = ⌊v·H⌋ (clamped),  row 0 = zenith
//! ```
//!
//! so the image centre (u, v) = (0.5, 0.5) is the direction −X, as in
//! Blender, and the left and right edges meet at +X. (θ is computed as
//! atan2(√(x² + z²), y), the same angle as acos(d.y) for a unit d, but
//! accurate near the poles and for directions that are not quite unit.)
//!
//! **Rotation and intensity.** `--sky-rotation` turns the map about +Y by
//! that many degrees, positive = counter-clockwise seen from above (a
//! right-handed rotation about +Y, `Quat::from_rotation_y`): a lookup maps
//! the world direction by −rotation into the image, a sample maps its image
//! direction by +rotation into the world. So at 90° the image centre lights
//! from +Z instead of −X. Radiance = pixel × intensity, stored
//! premultiplied.
//!
//! **Sampling** (PBRT §13.6.5). Each pixel weighs luminance (0.2126 R +
//! 0.7152 G + 0.0722 B) × sin θ of its row's centre, with no floor: a
//! black pixel is never sampled, and an all-black map is not sampled at all
//! ([`SkyMap::is_black`]; then `sample` and `pdf` give pdf 0). A pixel is
//! chosen from a piecewise-constant 2-D distribution — a marginal CDF over
//! rows, then the chosen row's conditional CDF over columns, each inverted
//! by binary search — and the point is uniform in (u, v) within it, so the
//! density per steradian is p_pixel · W · H / (2π² sin θ), with sin θ at
//! the direction itself (0 at the poles, where the density is 0). Lookups
//! take the nearest pixel (no filtering), so the radiance is exactly as
//! piecewise constant as the density. CDF inversion rather than an alias
//! table (Walker 1977; Vose 1991): it costs O(log W + log H) instead of
//! O(1), which is nothing next to a ray, but it is monotone in u, so
//! stratified or low-discrepancy sample points stay stratified over the
//! sky, and the remainder of each uniform places the point within the pixel
//! without another random number. Construction is serial and deterministic.

use crate::error::{Error, Result};
use glam::{DVec3, Mat3, Vec2, Vec3};
use std::f32::consts::{PI, TAU};
use std::fmt;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The most pixels a sky map may have (64 Mi, 768 MiB as linear RGB).
pub const MAX_PIXELS: u64 = 64 << 20;

/// The widest sky map accepted, in pixels.
pub const MAX_WIDTH: u64 = 32_768;

/// The largest `f32` below 1: where the uniforms of [`SkyMap::sample`] are
/// clamped to.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// Where escaped rays get their radiance: a constant colour (today's `sky`), or a map.
#[derive(Clone, Debug)]
pub enum Sky {
    /// The same radiance from every direction.
    Uniform(Vec3),
    /// An equirectangular environment map (shared: clones are cheap).
    Map(Arc<SkyMap>),
}

impl From<Vec3> for Sky {
    /// A uniform sky of that radiance.
    fn from(c: Vec3) -> Sky {
        Sky::Uniform(c)
    }
}

impl Default for Sky {
    fn default() -> Self {
        Sky::Uniform(Vec3::ZERO)
    }
}

impl Sky {
    /// Radiance arriving from world direction `dir` (normalised; +Y up).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match self {
            Sky::Uniform(c) => *c,
            Sky::Map(m) => m.radiance(dir),
        }
    }

    /// True when the sky gives no light: `Uniform(ZERO)` or an all-zero map.
    pub fn is_black(&self) -> bool {
        match self {
            Sky::Uniform(c) => *c == Vec3::ZERO,
            Sky::Map(m) => m.is_black(),
        }
    }

    /// The map, if the sky is one.
    pub fn map(&self) -> Option<&SkyMap> {
        match self {
            Sky::Uniform(_) => None,
            Sky::Map(m) => Some(m),
        }
    }

    /// Solid-angle-weighted mean radiance over the sphere (`Uniform`: the
    /// colour).
    pub fn mean(&self) -> Vec3 {
        match self {
            Sky::Uniform(c) => *c,
            Sky::Map(m) => m.mean(),
        }
    }
}

/// An equirectangular sky map with its sampling distribution; see the
/// module documentation for the conventions.
pub struct SkyMap {
    source: PathBuf,
    width: u32,
    height: u32,
    /// Linear RGB × intensity, row-major, row 0 at the zenith.
    pixels: Vec<Vec3>,
    rotation_degrees: f32,
    intensity: f32,
    /// Image frame → world: the rotation about +Y.
    to_world: Mat3,
    /// World → image frame.
    to_map: Mat3,
    mean: Vec3,
    /// None when the map is all black.
    distribution: Option<Distribution2d>,
}

impl fmt::Debug for SkyMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SkyMap")
            .field("source", &self.source)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("rotation_degrees", &self.rotation_degrees)
            .field("intensity", &self.intensity)
            .field("mean", &self.mean)
            .finish_non_exhaustive()
    }
}

impl SkyMap {
    /// Reads `.exr` (via the `exr` crate, already a dependency: first RGB(A) layer, f32) or `.hdr` (Radiance RGBE via `image` crate's hdr feature); by extension, case-insensitive; other extensions are an error.
    ///
    /// The header's size is checked before any pixel is decoded.
    ///
    /// # Errors
    /// [`Error::Config`] for a non-finite rotation or a non-finite or
    /// negative intensity; [`Error::Io`] when the file cannot be opened;
    /// [`Error::Limit`] for a map above [`MAX_WIDTH`] or [`MAX_PIXELS`];
    /// [`Error::Invalid`] for an unknown extension, a file the decoder
    /// rejects (corrupt, truncated), an empty or not 2:1 map, or a pixel
    /// that is not finite and non-negative. Each names the file.
    pub fn load(path: &Path, rotation_degrees: f32, intensity: f32) -> Result<SkyMap> {
        check_settings(path, rotation_degrees, intensity)?;
        let extension = path.extension().and_then(|e| e.to_str());
        let (width, height, pixels) = match extension.map(str::to_ascii_lowercase).as_deref() {
            Some("exr") => read_exr(path)?,
            Some("hdr") => read_hdr(path)?,
            _ => {
                return Err(invalid(
                    path,
                    "sky map",
                    "unknown format: expected an OpenEXR (.exr) or Radiance RGBE (.hdr) file",
                ))
            }
        };
        Self::from_pixels(path, width, height, pixels, rotation_degrees, intensity)
    }

    /// From linear RGB pixels, row-major, row 0 at the zenith (for tests and the library API). `source` is the name errors use.
    ///
    /// # Errors
    /// [`Error::Config`] for bad settings (as [`SkyMap::load`]);
    /// [`Error::Limit`] for a map that is too large; [`Error::Invalid`] for an
    /// empty or not 2:1 map, `pixels.len() != width × height`, or the first
    /// pixel that is not finite and non-negative (or overflows when scaled
    /// by `intensity`).
    pub fn from_pixels(
        source: &Path,
        width: u32,
        height: u32,
        mut pixels: Vec<Vec3>,
        rotation_degrees: f32,
        intensity: f32,
    ) -> Result<SkyMap> {
        check_settings(source, rotation_degrees, intensity)?;
        check_dimensions(source, width.into(), height.into())?;
        let (w, h) = (width as usize, height as usize);
        if pixels.len() != w * h {
            let message = format!("{} pixels for a {width} × {height} map", pixels.len());
            return Err(invalid(source, "sky map", message));
        }
        premultiply(source, w, &mut pixels, intensity)?;
        let to_world = Mat3::from_rotation_y(rotation_degrees.to_radians());
        Ok(SkyMap {
            source: source.to_path_buf(),
            width,
            height,
            mean: solid_angle_mean(&pixels, w, h),
            distribution: Distribution2d::new(&pixels, w, h),
            pixels,
            rotation_degrees,
            intensity,
            to_world,
            to_map: to_world.transpose(),
        })
    }

    /// Width in pixels (2 × height, ± 1).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The file (or name) the map came from.
    pub fn source(&self) -> &Path {
        &self.source
    }

    /// True when every pixel is zero: the map gives no light and is not
    /// sampled.
    pub fn is_black(&self) -> bool {
        self.distribution.is_none()
    }

    /// Solid-angle-weighted mean radiance over the sphere (× intensity).
    pub fn mean(&self) -> Vec3 {
        self.mean
    }

    /// Radiance from world direction `dir`: the nearest pixel × intensity
    /// (zero for a zero or non-finite `dir`).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        self.locate(dir)
            .map_or(Vec3::ZERO, |(col, row, _)| self.pixel(col, row))
    }

    /// Importance sample by luminance × sin θ: returns (direction, pdf per steradian, radiance). u in [0,1)².
    ///
    /// The pdf and radiance are exactly [`SkyMap::pdf`] and
    /// [`SkyMap::radiance`] of the direction returned. An all-black map
    /// gives (+Y, 0, 0): a pdf of 0 means "no sample".
    pub fn sample(&self, u: Vec2) -> (Vec3, f32, Vec3) {
        let Some(distribution) = &self.distribution else {
            return (Vec3::Y, 0.0, Vec3::ZERO);
        };
        let (col, row, offset) = distribution.sample(u);
        let size = Vec2::new(self.width as f32, self.height as f32);
        let corner = Vec2::new(col as f32, row as f32);
        // Rounding can carry a point within ~1e-6 of its pixel's edge into
        // the neighbour (or onto a pole); then it is pulled towards the
        // pixel's centre, so that the direction's pdf and radiance are
        // those of the pixel chosen (a shift of < 1/64 pixel, rarely).
        let pulled = Vec2::splat(0.5) + (offset - 0.5) * (63.0 / 64.0);
        let mut found = (Vec3::Y, None);
        for offset in [offset, pulled, Vec2::splat(0.5)] {
            let dir = (self.to_world * direction((corner + offset) / size)).normalize();
            let at = self.locate(dir);
            found = (dir, at);
            if matches!(at, Some((c, r, s)) if c == col && r == row && s > 0.0) {
                break;
            }
        }
        match found {
            (dir, Some((c, r, sin_theta))) => (
                dir,
                self.density(distribution, c, r, sin_theta),
                self.pixel(c, r),
            ),
            (dir, None) => (dir, 0.0, Vec3::ZERO),
        }
    }

    /// Density per steradian with which [`SkyMap::sample`] returns world
    /// direction `dir` (0 for an all-black map, black pixels and the poles).
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match (&self.distribution, self.locate(dir)) {
            (Some(distribution), Some((col, row, sin_theta))) => {
                self.density(distribution, col, row, sin_theta)
            }
            _ => 0.0,
        }
    }

    /// p_pixel · W · H / (2π² sin θ), 0 where sin θ is.
    fn density(
        &self,
        distribution: &Distribution2d,
        col: usize,
        row: usize,
        sin_theta: f32,
    ) -> f32 {
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let pixels = self.width as f32 * self.height as f32;
        distribution.probability(col, row) * pixels / (2.0 * PI * PI * sin_theta)
    }

    fn pixel(&self, col: usize, row: usize) -> Vec3 {
        self.pixels[row * self.width as usize + col]
    }

    /// The pixel (column, row) seen in world direction `dir`, and sin θ
    /// there; None for a zero or non-finite direction.
    fn locate(&self, dir: Vec3) -> Option<(usize, usize, f32)> {
        let d = self.to_map * dir;
        let length = d.length();
        if !(length.is_finite() && length > 0.0) {
            return None;
        }
        let rho = d.x.hypot(d.z);
        let u = 0.5 + (-d.z).atan2(-d.x) / TAU;
        let v = rho.atan2(d.y) / PI;
        let (w, h) = (self.width as i64, self.height as i64);
        let col = ((u * w as f32).floor() as i64).rem_euclid(w);
        let row = ((v * h as f32).floor() as i64).clamp(0, h - 1);
        Some((col as usize, row as usize, rho / length))
    }
}

/// Image-frame direction of image point `uv` (the inverse of the
/// projection in the module documentation).
fn direction(uv: Vec2) -> Vec3 {
    let (sin_theta, cos_theta) = (uv.y * PI).sin_cos();
    let (sin_alpha, cos_alpha) = ((uv.x - 0.5) * TAU).sin_cos();
    Vec3::new(-sin_theta * cos_alpha, cos_theta, -sin_theta * sin_alpha)
}

/// Rec. 709 luminance.
fn luminance(c: Vec3) -> f64 {
    0.2126 * c.x as f64 + 0.7152 * c.y as f64 + 0.0722 * c.z as f64
}

/// Σ pixel × its solid angle / 4π; a pixel of row r spans
/// (2π / W) (cos θᵣ − cos θᵣ₊₁) steradians.
fn solid_angle_mean(pixels: &[Vec3], w: usize, h: usize) -> Vec3 {
    let mut sum = DVec3::ZERO;
    for (row, line) in pixels.chunks_exact(w).enumerate() {
        let cos = |r: usize| (std::f64::consts::PI * r as f64 / h as f64).cos();
        let share = (cos(row) - cos(row + 1)) / (2.0 * w as f64);
        sum += share * line.iter().map(|p| p.as_dvec3()).sum::<DVec3>();
    }
    sum.as_vec3()
}

/// The piecewise-constant 2-D distribution over pixels (PBRT's
/// `Distribution2D`): a CDF over rows and one over each row's columns.
struct Distribution2d {
    width: usize,
    /// height + 1 values from 0 to 1.
    marginal: Vec<f32>,
    /// height × (width + 1) values, each row from 0 to 1.
    conditional: Vec<f32>,
}

impl Distribution2d {
    /// None when every weight is zero.
    fn new(pixels: &[Vec3], w: usize, h: usize) -> Option<Self> {
        let mut conditional = Vec::with_capacity(h * (w + 1));
        let mut row_weights = Vec::with_capacity(h);
        let mut weights = Vec::with_capacity(w);
        for (row, line) in pixels.chunks_exact(w).enumerate() {
            let sin_theta = (std::f64::consts::PI * (row as f64 + 0.5) / h as f64).sin();
            weights.clear();
            weights.extend(line.iter().map(|p| luminance(*p)));
            row_weights.push(push_cdf(&mut conditional, &weights) * sin_theta);
        }
        let mut marginal = Vec::with_capacity(h + 1);
        let total = push_cdf(&mut marginal, &row_weights);
        (total > 0.0).then_some(Self {
            width: w,
            marginal,
            conditional,
        })
    }

    fn row(&self, row: usize) -> &[f32] {
        &self.conditional[row * (self.width + 1)..(row + 1) * (self.width + 1)]
    }

    /// (column, row, place within the pixel in [0, 1)²) for uniforms `u`.
    fn sample(&self, u: Vec2) -> (usize, usize, Vec2) {
        let (row, dv) = invert_cdf(&self.marginal, unit(u.y));
        let (col, du) = invert_cdf(self.row(row), unit(u.x));
        (col, row, Vec2::new(du, dv))
    }

    /// The probability of choosing pixel (col, row).
    fn probability(&self, col: usize, row: usize) -> f32 {
        let cdf = self.row(row);
        (self.marginal[row + 1] - self.marginal[row]) * (cdf[col + 1] - cdf[col])
    }
}

/// `u` clamped into [0, 1) (NaN → 0).
fn unit(u: f32) -> f32 {
    if u >= 0.0 {
        u.min(ONE_BELOW)
    } else {
        0.0
    }
}

/// Appends the normalised CDF of `weights` (n + 1 values rising from 0 to
/// exactly 1; uniform when all are zero) and returns their sum. A zero
/// weight gets a bucket of width exactly zero.
fn push_cdf(cdf: &mut Vec<f32>, weights: &[f64]) -> f64 {
    let total: f64 = weights.iter().sum();
    let n = weights.len();
    cdf.push(0.0);
    let mut acc = 0.0;
    for (i, w) in weights.iter().enumerate() {
        acc += w;
        cdf.push(if i + 1 == n {
            1.0
        } else if total > 0.0 {
            (acc / total) as f32
        } else {
            (i + 1) as f32 / n as f32
        });
    }
    total
}

/// The bucket i of `cdf` with cdf[i] ≤ u < cdf[i + 1] (never an empty
/// one, for u in [0, 1)) and u's place within it, in [0, 1).
fn invert_cdf(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len() - 1;
    let i = cdf
        .partition_point(|&c| c <= u)
        .saturating_sub(1)
        .min(n - 1);
    let (lo, hi) = (cdf[i], cdf[i + 1]);
    let t = if hi > lo { (u - lo) / (hi - lo) } else { 0.0 };
    (i, t.clamp(0.0, ONE_BELOW))
}

/// An [`Error::Invalid`] for `path`, its message on one line.
fn invalid(path: &Path, location: &str, message: impl fmt::Display) -> Error {
    Error::Invalid {
        path: path.to_path_buf(),
        location: location.into(),
        message: message.to_string().replace(['\n', '\r'], " "),
    }
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    |source| Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A finite rotation and a finite, non-negative intensity.
fn check_settings(source: &Path, rotation_degrees: f32, intensity: f32) -> Result<()> {
    if !rotation_degrees.is_finite() {
        return Err(Error::Config {
            key: "sky_rotation".into(),
            message: format!(
                "{}: sky rotation {rotation_degrees}° is not a finite number of degrees",
                source.display()
            ),
        });
    }
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(Error::Config {
            key: "sky_intensity".into(),
            message: format!(
                "{}: sky intensity {intensity} is not a finite number ≥ 0",
                source.display()
            ),
        });
    }
    Ok(())
}

/// Not empty, within [`MAX_WIDTH`] and [`MAX_PIXELS`], and 2:1 (± 1 pixel).
fn check_dimensions(source: &Path, w: u64, h: u64) -> Result<()> {
    if w == 0 || h == 0 {
        return Err(invalid(
            source,
            "sky map",
            format!("empty sky map ({w} × {h} pixels)"),
        ));
    }
    if w > MAX_WIDTH || w.saturating_mul(h) > MAX_PIXELS {
        return Err(Error::Limit(format!(
            "{}: sky map is {w} × {h}, above the limit of {MAX_WIDTH} pixels wide and \
             {MAX_PIXELS} pixels in all",
            source.display()
        )));
    }
    if w.abs_diff(h.saturating_mul(2)) > 1 {
        let message = format!("not equirectangular: {w} × {h} is not 2:1");
        return Err(invalid(source, "sky map", message));
    }
    Ok(())
}

/// Checks every pixel is finite and non-negative, then scales it by
/// `intensity`.
fn premultiply(source: &Path, w: usize, pixels: &mut [Vec3], intensity: f32) -> Result<()> {
    for (i, p) in pixels.iter_mut().enumerate() {
        let bad = |what: &str| {
            let location = format!("pixel ({}, {})", i % w, i / w);
            invalid(
                source,
                &location,
                format!("radiance ({}, {}, {}) {what}", p.x, p.y, p.z),
            )
        };
        if !(p.is_finite() && p.cmpge(Vec3::ZERO).all()) {
            return Err(bad("is not finite and non-negative"));
        }
        if !(*p * intensity).is_finite() {
            return Err(bad(&format!("× intensity {intensity} overflows")));
        }
        *p *= intensity;
    }
    Ok(())
}

/// Radiance RGBE: the header's size is checked before the pixels are
/// decoded.
fn read_hdr(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    use image::ImageDecoder as _;
    let file = File::open(path).map_err(io_error(path))?;
    let reader = radiance_signature(BufReader::new(file)).map_err(io_error(path))?;
    let decoder = image::codecs::hdr::HdrDecoder::new(reader).map_err(|e| {
        invalid(
            path,
            "header",
            format!("not a readable Radiance HDR file: {e}"),
        )
    })?;
    let (w, h) = decoder.dimensions();
    check_dimensions(path, w.into(), h.into())?;
    let mut bytes = vec![0u8; w as usize * h as usize * 12];
    decoder.read_image(&mut bytes).map_err(|e| {
        invalid(
            path,
            "sky map",
            format!("could not decode Radiance HDR: {e}"),
        )
    })?;
    let pixels = bytes
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f32::from_ne_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
            Vec3::new(f(0), f(4), f(8))
        })
        .collect();
    Ok((w, h, pixels))
}

/// Radiance files open with `#?` and the writing program's name
/// (`#?RADIANCE`, `#?RGBE`...); `image` accepts only `#?RADIANCE`, so any
/// other `#?` line is passed on as that.
fn radiance_signature(mut reader: impl BufRead) -> std::io::Result<impl Read> {
    let mut first = Vec::new();
    reader.by_ref().take(64).read_until(b'\n', &mut first)?;
    if first.starts_with(b"#?") && first.ends_with(b"\n") {
        first = b"#?RADIANCE\n".to_vec();
    }
    Ok(std::io::Cursor::new(first).chain(reader))
}

/// An OpenEXR sky map ([`crate::util::files::read_exr_rgb`]), 2:1.
fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    let (w, h, pixels) = crate::util::files::read_exr_rgb(path, "sky map", MAX_WIDTH, MAX_PIXELS)?;
    check_dimensions(path, w.into(), h.into())?;
    Ok((w, h, pixels))
}

impl crate::config::BakeConfig {
    /// The sky that rays leaving the scene see: `sky_map` loaded (turned
    /// by `sky_rotation`, scaled by `sky_intensity`), else the uniform
    /// `sky`.
    ///
    /// # Errors
    /// The map's one-line errors ([`crate::light::sky::SkyMap::load`]).
    pub fn load_sky(&self) -> Result<crate::light::sky::Sky> {
        match &self.sky_map {
            None => Ok(Sky::Uniform(glam::Vec3::from(self.sky))),
            Some(path) => Ok(Sky::Map(std::sync::Arc::new(SkyMap::load(
                path,
                self.sky_rotation,
                self.sky_intensity,
            )?))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::sampling::Stream;
    use glam::Quat;
    use std::fs;

    /// A scratch folder, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(name: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("radbake-sky-{}-{name}", std::process::id()));
            let _ = fs::remove_dir_all(&dir);
            fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }

        fn join(&self, file: &str) -> PathBuf {
            self.0.join(file)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    fn write_hdr(path: &Path, w: u32, h: u32, pixels: &[Vec3]) {
        let rgb: Vec<image::Rgb<f32>> = pixels.iter().map(|p| image::Rgb(p.to_array())).collect();
        let file = std::io::BufWriter::new(File::create(path).unwrap());
        image::codecs::hdr::HdrEncoder::new(file)
            .encode(&rgb, w as usize, h as usize)
            .unwrap();
    }

    fn write_exr(path: &Path, w: u32, h: u32, pixels: &[Vec3]) {
        use exr::prelude::{Image, SpecificChannels, WritableImage as _};
        let channels = SpecificChannels::rgb(|at: exr::math::Vec2<usize>| {
            let p = pixels[at.y() * w as usize + at.x()];
            (p.x, p.y, p.z)
        });
        Image::from_channels((w as usize, h as usize), channels)
            .write()
            .non_parallel()
            .to_file(path)
            .unwrap();
    }

    /// The error is one line that names the file.
    fn assert_one_line(err: &Error, path: &Path) {
        let text = err.to_string();
        assert!(!text.contains('\n'), "{text}");
        let name = path.file_name().unwrap().to_str().unwrap();
        assert!(text.contains(name), "{text} does not name {name}");
    }

    fn uniform_sphere(u: Vec2) -> Vec3 {
        let y = 1.0 - 2.0 * u.x;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let (s, c) = (TAU * u.y).sin_cos();
        Vec3::new(r * c, y, r * s)
    }

    fn map(w: u32, h: u32, pixels: Vec<Vec3>, rotation: f32) -> SkyMap {
        SkyMap::from_pixels(Path::new("test.hdr"), w, h, pixels, rotation, 1.0).unwrap()
    }

    /// A gradient with a bright patch, 64 × 32.
    fn gradient_patch() -> Vec<Vec3> {
        (0..32u32 * 64)
            .map(|i| {
                let (x, y) = ((i % 64) as f32, (i / 64) as f32);
                let patch = (40.0..44.0).contains(&x) && (10.0..13.0).contains(&y);
                Vec3::new(0.1 + x / 64.0, 0.2 + y / 64.0, 0.05)
                    + if patch {
                        Vec3::new(20.0, 15.0, 10.0)
                    } else {
                        Vec3::ZERO
                    }
            })
            .collect()
    }

    fn relative(a: f32, b: f32) -> f32 {
        (a - b).abs() / b.abs().max(1e-30)
    }

    #[test]
    fn constant_map_is_uniform_and_normalised() {
        let c = Vec3::new(0.5, 1.0, 2.0);
        for rotation in [0.0, 37.0] {
            let m = map(64, 32, vec![c; 64 * 32], rotation);
            assert!(!m.is_black());
            assert!((m.mean() - c).abs().max_element() < 1e-5, "{}", m.mean());
            let mut s = Stream::new(1, 2, 3);
            let n = 200_000;
            let mut integral = 0.0f64;
            for _ in 0..n {
                let d = uniform_sphere(s.next_vec2());
                assert_eq!(m.radiance(d), c);
                integral += m.pdf(d) as f64;
            }
            integral *= 4.0 * std::f64::consts::PI / n as f64;
            assert!((integral - 1.0).abs() < 0.01, "∫ pdf = {integral}");
            // ∫ L cos θ dω over the hemisphere about +Y = π L.
            let mut e = DVec3::ZERO;
            for _ in 0..100_000 {
                let (d, pdf, l) = m.sample(s.next_vec2());
                assert!(pdf > 0.0 && l == c);
                e += (l * d.y.max(0.0) / pdf).as_dvec3();
            }
            let e = (e / 100_000.0).as_vec3();
            for k in 0..3 {
                assert!(relative(e[k], PI * c[k]) < 0.01, "{e} vs π {c}");
            }
        }
    }

    #[test]
    fn sample_agrees_with_pdf_and_radiance() {
        let m =
            SkyMap::from_pixels(Path::new("g.exr"), 64, 32, gradient_patch(), 30.0, 2.0).unwrap();
        let mut s = Stream::new(7, 0, 0);
        let mut us: Vec<Vec2> = (0..20_000).map(|_| s.next_vec2()).collect();
        us.extend([
            Vec2::ZERO,
            Vec2::splat(ONE_BELOW),
            Vec2::new(0.0, ONE_BELOW),
            Vec2::X,
        ]);
        for u in us {
            let (d, pdf, l) = m.sample(u);
            assert!((d.length() - 1.0).abs() < 1e-5);
            assert!(pdf > 0.0);
            assert!(relative(m.pdf(d), pdf) < 1e-3, "pdf {} vs {pdf}", m.pdf(d));
            assert_eq!(l, m.radiance(d));
        }
    }

    #[test]
    fn black_pixels_are_never_sampled_and_the_estimate_matches() {
        let (w, h) = (64u32, 32u32);
        let bright = Vec3::new(10.0, 5.0, 2.0);
        let in_patch = |x: usize, y: usize| (20..24).contains(&x) && (8..11).contains(&y);
        let pixels = (0..(w * h) as usize)
            .map(|i| {
                if in_patch(i % 64, i / 64) {
                    bright
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let m = map(w, h, pixels, 0.0);
        // Brute force: ∫ cos θ dω over a pixel of rows θ₀..θ₁ (all above
        // the horizon) is (2π / W) (sin² θ₁ − sin² θ₀) / 2.
        let mut brute = DVec3::ZERO;
        for y in 8..11 {
            let sin2 = |r: f64| (std::f64::consts::PI * r / h as f64).sin().powi(2);
            let per_pixel =
                std::f64::consts::TAU / w as f64 * (sin2(y as f64 + 1.0) - sin2(y as f64)) / 2.0;
            brute += 4.0 * per_pixel * bright.as_dvec3();
        }
        let mut s = Stream::new(3, 1, 4);
        let n = 100_000;
        let mut e = DVec3::ZERO;
        for _ in 0..n {
            let (d, pdf, l) = m.sample(s.next_vec2());
            let (col, row, _) = m.locate(d).unwrap();
            assert!(in_patch(col, row) && l == bright, "sampled ({col}, {row})");
            e += (l * d.y.max(0.0) / pdf).as_dvec3();
        }
        e /= n as f64;
        for k in 0..3 {
            assert!(
                ((e[k] - brute[k]) / brute[k]).abs() < 0.005,
                "{e} vs {brute}"
            );
        }
        // Where the map is black, the pdf is zero.
        assert_eq!(m.pdf(Vec3::Y), 0.0);
        assert_eq!(m.pdf(Vec3::NEG_Y), 0.0);
    }

    #[test]
    fn rotation_turns_the_map_counter_clockwise_about_y() {
        // 65 × 33: the centre pixel (32, 16) has −X at its centre.
        let (w, h) = (65u32, 33u32);
        let mut pixels = vec![Vec3::ZERO; (w * h) as usize];
        pixels[16 * 65 + 32] = Vec3::splat(100.0);
        let turned = Quat::from_rotation_y(90f32.to_radians()) * Vec3::NEG_X;
        assert!((turned - Vec3::Z).length() < 1e-6);
        for (rotation, from, not_from) in [(0.0, Vec3::NEG_X, Vec3::Z), (90.0, turned, Vec3::NEG_X)]
        {
            let m = map(w, h, pixels.clone(), rotation);
            assert_eq!(m.radiance(from), Vec3::splat(100.0));
            assert_eq!(m.radiance(not_from), Vec3::ZERO);
            assert!(m.pdf(from) > 0.0 && m.pdf(not_from) == 0.0);
            let mut s = Stream::new(5, 0, 0);
            for _ in 0..1000 {
                let (d, _, _) = m.sample(s.next_vec2());
                assert!(d.dot(from) > 0.08f32.cos(), "{d} at {rotation}°");
            }
        }
    }

    #[test]
    fn files_round_trip() {
        let dir = TempDir::new("round-trip");
        let (w, h) = (16u32, 8u32);
        let mut s = Stream::new(9, 9, 9);
        let pixels: Vec<Vec3> = (0..w * h)
            .map(|_| Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 50.0 + 0.01)
            .collect();
        let exr = dir.join("env.exr");
        write_exr(&exr, w, h, &pixels);
        let m = SkyMap::load(&exr, 0.0, 1.0).unwrap();
        assert_eq!((m.width(), m.height(), m.source()), (w, h, exr.as_path()));
        assert_eq!(m.pixels, pixels);
        // Upper-case extension, intensity premultiplied; RGBE keeps 8 bits
        // of mantissa under a shared exponent.
        let hdr = dir.join("ENV.HDR");
        write_hdr(&hdr, w, h, &pixels);
        let m = SkyMap::load(&hdr, 0.0, 2.0).unwrap();
        assert_eq!((m.width(), m.height()), (w, h));
        for (a, b) in m.pixels.iter().zip(&pixels) {
            let b = *b * 2.0;
            assert!(
                (*a - b).abs().max_element() <= b.max_element() / 128.0,
                "{a} vs {b}"
            );
        }
        // Any `#?` program name, as other writers put it.
        let mut bytes = fs::read(&hdr).unwrap();
        bytes.splice(0..10, b"#?RGBE".iter().copied());
        let rgbe = dir.join("rgbe.hdr");
        fs::write(&rgbe, bytes).unwrap();
        assert_eq!(SkyMap::load(&rgbe, 0.0, 2.0).unwrap().pixels, m.pixels);
    }

    #[test]
    fn sky_enum() {
        assert!(Sky::default().is_black());
        let uniform = Sky::Uniform(Vec3::ONE);
        assert!(!uniform.is_black() && uniform.map().is_none());
        assert_eq!(
            (uniform.radiance(Vec3::Y), uniform.mean()),
            (Vec3::ONE, Vec3::ONE)
        );
        let black = Sky::Map(Arc::new(map(4, 2, vec![Vec3::ZERO; 8], 0.0)));
        assert!(black.is_black());
        assert_eq!(black.map().unwrap().sample(Vec2::splat(0.5)).1, 0.0);
        assert_eq!(black.map().unwrap().pdf(Vec3::X), 0.0);
        let sky = Sky::Map(Arc::new(map(64, 32, gradient_patch(), 0.0)));
        let copy = sky.clone();
        assert!(std::ptr::eq(sky.map().unwrap(), copy.map().unwrap()));
        assert_eq!(sky.mean(), sky.map().unwrap().mean());
        assert_eq!(sky.radiance(Vec3::NAN), Vec3::ZERO);
        assert!(format!("{:?}", sky).len() < 300);
        fn send_sync<T: Send + Sync>() {}
        send_sync::<Sky>();
    }

    /// A header-only Radiance file of the given size.
    fn hdr_header(path: &Path, w: u32, h: u32) {
        let header = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n");
        fs::write(path, header).unwrap();
    }

    #[test]
    fn too_large_maps_are_refused_from_the_header() {
        let dir = TempDir::new("limit");
        for (w, h) in [(40_000, 20_000), (40_000, 10)] {
            let path = dir.join("big.hdr");
            hdr_header(&path, w, h);
            let err = SkyMap::load(&path, 0.0, 1.0).unwrap_err();
            assert!(matches!(err, Error::Limit(_)), "{err}");
            assert!(err.to_string().contains(&format!("{w} × {h}")), "{err}");
            assert_one_line(&err, &path);
        }
        // An EXR whose data window claims 40000 × 20000.
        let path = dir.join("big.exr");
        write_exr(&path, 4, 2, &[Vec3::ONE; 8]);
        let mut bytes = fs::read(&path).unwrap();
        let key = b"dataWindow\0box2i\0\x10\0\0\0";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len();
        bytes[at + 8..at + 12].copy_from_slice(&39_999i32.to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&19_999i32.to_le_bytes());
        fs::write(&path, bytes).unwrap();
        let err = SkyMap::load(&path, 0.0, 1.0).unwrap_err();
        assert!(matches!(err, Error::Limit(_)), "{err}");
        assert_one_line(&err, &path);
    }

    #[test]
    fn maps_must_be_two_to_one() {
        let dir = TempDir::new("aspect");
        let path = dir.join("square.hdr");
        write_hdr(&path, 6, 2, &[Vec3::ONE; 12]);
        let err = SkyMap::load(&path, 0.0, 1.0).unwrap_err();
        assert!(
            err.to_string()
                .contains("not equirectangular: 6 × 2 is not 2:1"),
            "{err}"
        );
        assert_one_line(&err, &path);
        let path = Path::new("square.exr");
        let err = SkyMap::from_pixels(path, 4, 4, vec![Vec3::ONE; 16], 0.0, 1.0).unwrap_err();
        assert!(matches!(err, Error::Invalid { .. }));
        assert_one_line(&err, path);
        // ± 1 pixel is rounding.
        SkyMap::from_pixels(path, 5, 2, vec![Vec3::ONE; 10], 0.0, 1.0).unwrap();
    }

    #[test]
    fn truncated_and_corrupt_files_are_invalid() {
        let dir = TempDir::new("truncated");
        let mut s = Stream::new(1, 1, 1);
        let pixels: Vec<Vec3> = (0..64 * 32)
            .map(|_| Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()))
            .collect();
        for name in ["env.hdr", "env.exr"] {
            let path = dir.join(name);
            if name.ends_with("hdr") {
                write_hdr(&path, 64, 32, &pixels);
            } else {
                write_exr(&path, 64, 32, &pixels);
            }
            let bytes = fs::read(&path).unwrap();
            let cut = dir.join(&format!("cut-{name}"));
            fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
            let err = SkyMap::load(&cut, 0.0, 1.0).unwrap_err();
            assert!(matches!(err, Error::Invalid { .. }), "{err}");
            assert_one_line(&err, &cut);
            let junk = dir.join(&format!("junk-{name}"));
            fs::write(&junk, b"not an image at all\n\n").unwrap();
            let err = SkyMap::load(&junk, 0.0, 1.0).unwrap_err();
            assert!(matches!(err, Error::Invalid { .. }), "{err}");
            assert_one_line(&err, &junk);
        }
    }

    #[test]
    fn bad_pixels_name_the_first_one() {
        let path = Path::new("bad.exr");
        for (value, shown) in [
            (Vec3::new(1.0, f32::NAN, 1.0), "NaN"),
            (Vec3::new(f32::INFINITY, 1.0, 1.0), "inf"),
            (Vec3::new(1.0, 1.0, -0.5), "-0.5"),
        ] {
            let mut pixels = vec![Vec3::ONE; 8 * 4];
            pixels[8 + 3] = value;
            pixels[3 * 8 + 5] = value;
            let err = SkyMap::from_pixels(path, 8, 4, pixels, 0.0, 1.0).unwrap_err();
            let text = err.to_string();
            assert!(
                text.contains("pixel (3, 1)") && text.contains(shown),
                "{text}"
            );
            assert_one_line(&err, path);
        }
        let err =
            SkyMap::from_pixels(path, 8, 4, vec![Vec3::splat(1e30); 32], 0.0, 1e10).unwrap_err();
        assert!(err.to_string().contains("pixel (0, 0)"), "{err}");
        // And from a file.
        let dir = TempDir::new("bad-pixels");
        let file = dir.join("nan.exr");
        let mut pixels = vec![Vec3::ONE; 8 * 4];
        pixels[2 * 8 + 5] = Vec3::NAN;
        write_exr(&file, 8, 4, &pixels);
        let err = SkyMap::load(&file, 0.0, 1.0).unwrap_err();
        assert!(err.to_string().contains("pixel (5, 2)"), "{err}");
        assert_one_line(&err, &file);
    }

    #[test]
    fn empty_maps_are_invalid() {
        let path = Path::new("empty.hdr");
        let err = SkyMap::from_pixels(path, 0, 0, Vec::new(), 0.0, 1.0).unwrap_err();
        assert!(matches!(err, Error::Invalid { .. }) && err.to_string().contains("empty"));
        assert_one_line(&err, path);
        let dir = TempDir::new("empty");
        let file = dir.join("empty.hdr");
        hdr_header(&file, 0, 0);
        let err = SkyMap::load(&file, 0.0, 1.0).unwrap_err();
        assert!(err.to_string().contains("empty"), "{err}");
        assert_one_line(&err, &file);
        let err = SkyMap::from_pixels(path, 4, 2, vec![Vec3::ONE; 7], 0.0, 1.0).unwrap_err();
        assert!(
            err.to_string().contains("7 pixels for a 4 × 2 map"),
            "{err}"
        );
    }

    #[test]
    fn bad_names_and_settings() {
        let dir = TempDir::new("names");
        let png = dir.join("env.png");
        fs::write(&png, b"").unwrap();
        let err = SkyMap::load(&png, 0.0, 1.0).unwrap_err();
        assert!(matches!(err, Error::Invalid { .. }), "{err}");
        assert_one_line(&err, &png);
        let missing = dir.join("missing.exr");
        let err = SkyMap::load(&missing, 0.0, 1.0).unwrap_err();
        assert!(matches!(err, Error::Io { .. }), "{err}");
        assert_one_line(&err, &missing);
        let path = Path::new("env.hdr");
        for (rotation, intensity, key) in [
            (f32::NAN, 1.0, "sky_rotation"),
            (f32::INFINITY, 1.0, "sky_rotation"),
            (0.0, -1.0, "sky_intensity"),
            (0.0, f32::NAN, "sky_intensity"),
        ] {
            let err = SkyMap::from_pixels(path, 4, 2, vec![Vec3::ONE; 8], rotation, intensity)
                .unwrap_err();
            assert!(
                matches!(&err, Error::Config { key: k, .. } if k == key),
                "{err}"
            );
            assert_one_line(&err, path);
            let err = SkyMap::load(path, rotation, intensity).unwrap_err();
            assert!(matches!(err, Error::Config { .. }), "{err}");
        }
    }
}
