//! Offscreen rendering through the one render path
//! ([`Renderer::render`]), for `--headless`, the tests and the window's
//! screenshots.

use super::model::Model;
use super::options::{initial_camera, Options};
use super::renderer::{self, Renderer};
use crate::util::adapter::{describe, offscreen_device};
use anyhow::{anyhow, Context as _, Result};
use std::path::Path;
use std::time::Instant;

/// Writes RGBA8 rows as a PNG, atomically (temporary file + rename).
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    let img = image::RgbaImage::from_raw(width, height, rgba.to_vec())
        .ok_or_else(|| anyhow!("image size mismatch"))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    crate::output::write_png(path, &img)?;
    Ok(())
}

/// The result of a headless render.
pub struct Headless {
    /// RGBA8 rows (sRGB).
    pub rgba: Vec<u8>,
    /// Mean GPU frame time over the timed frames (ms), when more than one.
    pub ms_per_frame: Option<f64>,
    /// The adapter used.
    pub adapter: String,
}

/// Renders `opts.frames` (default 1) frames offscreen through
/// [`Renderer::render`] and returns the last one.
pub fn render_headless(model: &Model, opts: &Options) -> Result<Headless> {
    let (adapter, device, queue) = offscreen_device()?;
    let camera = initial_camera(model, &opts.viewpoint)?;
    // Not sRGB: the shader encodes (see `Renderer::new`).
    let format = wgpu::TextureFormat::Rgba8Unorm;
    let mut r = Renderer::new(&device, &queue, format, model, camera, opts.settings);
    let (w, h) = opts.size;
    r.resize(w, h);
    let frames = opts.frames.unwrap_or(1).max(1);
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
    let target = crate::util::adapter::render_target(&device, "headless", (w, h), format, usage);
    let view = target.create_view(&Default::default());
    // A warm-up frame (pipeline compilation, uploads), then the timed ones,
    // each waited for so the time is the GPU's, not the queue's.
    let wait = |device: &wgpu::Device| {
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("GPU wait failed: {e}"))
    };
    r.render(&view);
    wait(&device)?;
    let start = Instant::now();
    let timed = if frames > 1 { frames } else { 0 };
    for _ in 0..timed {
        r.render(&view);
        wait(&device)?;
    }
    let ms = (timed > 0).then(|| start.elapsed().as_secs_f64() * 1e3 / timed as f64);
    let rgba = renderer::read_back(&device, &queue, &target)?;
    Ok(Headless {
        rgba,
        ms_per_frame: ms,
        adapter: describe(&adapter),
    })
}
