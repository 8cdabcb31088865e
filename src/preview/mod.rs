//! `radbake preview`: a wgpu viewer for baked scenes (feature `preview`).
//!
//! - [`model`] turns a baked `.glb` into world-space triangles, materials
//!   and lightmap pages (lightmaps come from the `.glb`'s `MOZ_lightmap`).
//! - [`renderer`] holds the GPU resources and the one render path,
//!   [`renderer::Renderer::render`], used by the window and `--headless`.
//! - [`camera`] has the orbit and fly cameras, [`window`] the winit loop.
//! - [`gpu`] has every struct the shaders read (`shaders/*.wgsl`).
//!
//! Shading: outgoing radiance = base colour × lightmap + emissive (the
//! lightmap holds irradiance / π), times 2^EV, tone mapped (ACES fitted),
//! written to an sRGB target.

pub mod camera;
pub mod gpu;
pub mod headless;
pub mod model;
pub mod options;
pub mod renderer;
pub mod window;

pub use crate::adapter::{describe, device, instance, offscreen_device, NoAdapter};
pub use headless::{render_headless, write_png, Headless};
pub use options::{initial_camera, Options, Settings, ToneMap, ViewMode, Viewpoint};

use anyhow::{anyhow, bail, Result};
use model::Model;
use std::time::Instant;

/// Runs `radbake preview`.
pub fn run(opts: &Options) -> Result<()> {
    let (w, h) = opts.size;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("--size must be between 1x1 and 16384x16384");
    }
    let t = Instant::now();
    let model = Model::load(&opts.scene)?;
    for warning in &model.scene.warnings {
        eprintln!("warning: {warning}");
    }
    if model.lightmaps.is_empty() {
        eprintln!(
            "warning: {} has no MOZ_lightmap: is it a radbake .baked.glb? (surfaces show emission only)",
            opts.scene.display()
        );
    }
    let load_s = t.elapsed().as_secs_f64();
    // Resolve the viewpoint before any GPU work, so a bad --camera is
    // reported as such everywhere.
    initial_camera(&model, &opts.viewpoint)?;
    if opts.headless {
        let out = opts
            .out
            .as_ref()
            .ok_or_else(|| anyhow!("--headless needs --out <image.png>"))?;
        let result = render_headless(&model, opts)?;
        write_png(out, w, h, &result.rgba)?;
        if let Some(ms) = result.ms_per_frame {
            println!(
                "{} frames at {w}x{h}: {ms:.3} ms/frame ({:.1} fps) on {}; {} triangles, loaded in {load_s:.2} s",
                opts.frames.unwrap_or(1),
                1e3 / ms,
                result.adapter,
                model.vertices.len() / 3
            );
        }
        eprintln!("wrote {}", out.display());
        Ok(())
    } else {
        window::run(model, opts)
    }
}
