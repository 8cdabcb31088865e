//! `radbake preview`: a wgpu viewer for baked scenes (feature `preview`).
//!
//! - [`model`] turns a baked `.glb` into world-space triangles, materials
//!   and lightmap pages (lightmaps come from the `.glb`'s `MOZ_lightmap`),
//!   and reads the light probes beside it (`probes.json`, `probes.bin`).
//! - [`probe_light`] lights dynamic nodes from the probes and builds the
//!   probes view's spheres.
//! - [`renderer`] holds the GPU resources and the one render path,
//!   [`renderer::Renderer::render`], used by the window and `--headless`.
//! - [`camera`] has the orbit and fly cameras, [`window`] the winit loop.
//! - [`gpu`] has every struct the shaders read (`shaders/*.wgsl`).
//!
//! Shading, as three.js r187 draws a baked `.glb` with Lambert materials
//! and the lightmap as its only light (`meshlambert.glsl.js`): outgoing
//! radiance = base colour (`baseColorFactor` × texture × `COLOR_0`) ×
//! lightmap (irradiance / π) + emissive (`emissiveFactor` × strength ×
//! texture), times 2^EV, tone mapped (ACES fitted, or none), sRGB-encoded
//! in the shader. Base colour and emissive textures have full mip chains
//! ([`mips`]) and are filtered trilinearly as the glTF sampler says;
//! lightmaps are read at level 0 (three.js does not mipmap radbake's pages,
//! whose sampler is `LINEAR`/`LINEAR`). `MASK` is cut out at
//! `alphaCutoff`; `BLEND` objects are alpha blended after the opaque ones,
//! back to front, on the encoded values, as in three.js's canvas. Dynamic nodes (glTF
//! `extras.radbake.dynamic`, not baked) take the probes' irradiance / π in
//! place of the lightmap: trilinear between the eight probes around each
//! vertex (L2 SH, Ramamoorthi & Hanrahan 2001), evaluated on the CPU **per
//! vertex** and interpolated across triangles; without probes beside the
//! `.glb` they are drawn unlit (black but for emission), with a warning.
//! The probes view adds a white sphere per probe shaded by that probe's
//! irradiance / π for the sphere's normal (also per vertex), red where the
//! probe was found inside a solid.

pub mod camera;
pub mod field;
pub mod gpu;
pub mod headless;
pub mod live;
pub mod mips;
pub mod model;
pub mod options;
pub mod probe_light;
pub mod renderer;
pub mod watch;
pub mod window;

pub use crate::util::adapter::{describe, device, instance, offscreen_device};
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
    let dfao = opts.settings.dfao_reach;
    if !(dfao.is_finite() && (0.0..=1e4).contains(&dfao)) {
        bail!("--dfao-reach must be between 0 and 10000 metres");
    }
    let mut watch = opts.watch.then(|| watch::Watch::new(&opts.scene));
    let mut opts = opts.clone();
    if let Some(w) = &mut watch {
        opts.scene = first_file(w)?;
    }
    let opts = &opts;
    let t = Instant::now();
    if opts.live && opts.headless {
        bail!("--live turns the sun in the window: with --headless give --sun-direction");
    }
    if opts.live && opts.sun.is_none() {
        bail!("--live needs the sun to start from (live::baked_direction)");
    }
    let mut model = Model::load_relit(&opts.scene, &opts.layers, opts.sun.as_ref())?;
    if let Some(path) = &opts.sdf {
        model.field = Some(field::open(path)?);
    }
    if model.field.is_none() && opts.settings.view == ViewMode::Sdf {
        eprintln!(
            "warning: no distance field ({} has no `sdf`; bake with --sdf N or pass --sdf <file.ktx2>): the sdf view has nothing to show",
            field::manifest_path(&opts.scene).display()
        );
    }
    for warning in &model.scene.warnings {
        eprintln!("warning: {warning}");
    }
    let dynamic = model.scene.dynamic.len();
    if model.probes.is_none() && (dynamic > 0 || opts.settings.view == ViewMode::Probes) {
        let consequence = if dynamic > 0 {
            format!("{dynamic} dynamic node(s) are drawn unlit (black)")
        } else {
            "the probes view has nothing to show".to_owned()
        };
        eprintln!(
            "warning: light probes not found ({} does not exist): {consequence}",
            model::probes_path(&opts.scene).display()
        );
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
                model.triangles()
            );
        }
        eprintln!("wrote {}", out.display());
        Ok(())
    } else {
        window::run(model, opts, watch)
    }
}

/// `--watch`: the first file to show, waiting (politely, every 250 ms)
/// until a bake has written one.
fn first_file(w: &mut watch::Watch) -> Result<std::path::PathBuf> {
    let target = w.target();
    let folder = if target.extension().is_some() {
        target.parent().unwrap_or(std::path::Path::new("."))
    } else {
        target
    };
    if !folder.is_dir() {
        bail!(
            "--watch {}: no such folder (start the bake first, or give its --out folder)",
            folder.display()
        );
    }
    let mut told = false;
    loop {
        if let Some(path) = w.changed() {
            return Ok(path);
        }
        if !told {
            eprintln!("waiting for a .baked.glb or .snapshot.glb to appear (Ctrl-C to stop)");
            told = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(250));
    }
}
