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
pub mod model;
pub mod renderer;
pub mod window;

pub use crate::adapter::{describe, device, instance, offscreen_device, NoAdapter};

use anyhow::{anyhow, bail, Context as _, Result};
use camera::Camera;
use glam::Vec3;
use model::Model;
use renderer::Renderer;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the fragment shader shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
#[repr(u32)]
pub enum ViewMode {
    /// Base colour × lightmap + emissive, tone mapped.
    Lit = 0,
    /// The lightmap alone (irradiance / π), tone mapped.
    Lightmap = 1,
    /// Base colour alone (no lighting, no tone map).
    Albedo = 2,
    /// A checker of the lightmap texels over the lit scene (texel density).
    Checker = 3,
    /// Chart borders / UV seams of `TEXCOORD_1` drawn in red over the lit scene.
    Charts = 4,
    /// Each radiosity patch in its own colour (needs `bake --debug-maps`).
    Patches = 5,
    /// Texels found inside or under geometry (filled from neighbours) in
    /// red over the lit scene (needs `bake --debug-maps`).
    Invalid = 6,
}

impl ViewMode {
    /// All views, in key order (1–7).
    pub const ALL: [ViewMode; 7] = [
        ViewMode::Lit,
        ViewMode::Lightmap,
        ViewMode::Albedo,
        ViewMode::Checker,
        ViewMode::Charts,
        ViewMode::Patches,
        ViewMode::Invalid,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            ViewMode::Lit => "lit",
            ViewMode::Lightmap => "lightmap",
            ViewMode::Albedo => "albedo",
            ViewMode::Checker => "texel checker",
            ViewMode::Charts => "chart borders",
            ViewMode::Patches => "patches",
            ViewMode::Invalid => "invalid texels",
        }
    }
}

/// The tone map applied to HDR values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
#[repr(u32)]
pub enum ToneMap {
    /// ACES filmic (Stephen Hill's fit).
    Aces = 0,
    /// None: values clamped to [0, 1].
    None = 1,
}

/// Display settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Debug view.
    pub view: ViewMode,
    /// Bicubic (B-spline) instead of bilinear lightmap filtering.
    pub bicubic: bool,
    /// Exposure in stops (EV): values are multiplied by 2^EV before the tone map.
    pub exposure_ev: f32,
    /// Tone map.
    pub tone_map: ToneMap,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            view: ViewMode::Lit,
            bicubic: false,
            exposure_ev: 0.0,
            tone_map: ToneMap::Aces,
        }
    }
}

/// Where the first frame is seen from.
#[derive(Clone, Debug, Default)]
pub enum Viewpoint {
    /// The scene's first glTF camera, or a framing of its bounds.
    #[default]
    Auto,
    /// The glTF camera of this name.
    Camera(String),
    /// From a point towards another.
    LookAt {
        /// Eye.
        from: Vec3,
        /// Target (the centre of the scene's bounds when None).
        at: Option<Vec3>,
    },
}

/// `radbake preview` options.
#[derive(Clone, Debug)]
pub struct Options {
    /// The baked `.glb`.
    pub scene: PathBuf,
    /// Render offscreen, write [`Options::out`], no window.
    pub headless: bool,
    /// Headless output PNG.
    pub out: Option<PathBuf>,
    /// Image (headless) or initial window size.
    pub size: (u32, u32),
    /// First viewpoint.
    pub viewpoint: Viewpoint,
    /// Headless: frames to render and time (prints ms/frame when > 1).
    /// Window: render this many frames, then (with `screenshot`) save one and exit.
    pub frames: Option<u32>,
    /// Window: where to save a screenshot after `frames` frames.
    pub screenshot: Option<PathBuf>,
    /// Initial display settings.
    pub settings: Settings,
}

/// Picks the first viewpoint for `model` in an image of `aspect`.
pub fn initial_camera(model: &Model, viewpoint: &Viewpoint) -> Result<Camera> {
    let (lo, hi) = model.bounds;
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let default_fov = 50f32.to_radians();
    let from_gltf = |c: &crate::scene::Camera| {
        let eye = c.world_from_camera.transform_point3(Vec3::ZERO);
        let fwd = c
            .world_from_camera
            .transform_vector3(Vec3::NEG_Z)
            .normalize_or(Vec3::NEG_Z);
        let distance = (center - eye).dot(fwd).max(radius * 0.1);
        Camera::from_world(c.world_from_camera, c.yfov, distance, radius)
    };
    Ok(match viewpoint {
        Viewpoint::LookAt { from, at } => {
            Camera::look_at(*from, at.unwrap_or(center), default_fov, radius)
        }
        Viewpoint::Camera(name) => {
            let cams = &model.scene.cameras;
            let c = cams.iter().find(|c| &c.name == name).ok_or_else(|| {
                let names: Vec<&str> = cams.iter().map(|c| c.name.as_str()).collect();
                anyhow!(
                    "no camera named `{name}` (the scene has: {})",
                    if names.is_empty() {
                        "none".into()
                    } else {
                        names.join(", ")
                    }
                )
            })?;
            from_gltf(c)
        }
        Viewpoint::Auto => match model.scene.cameras.first() {
            Some(c) => from_gltf(c),
            None => Camera::frame(lo, hi, default_fov),
        },
    })
}

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
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let mut r = Renderer::new(&device, &queue, format, model, camera, opts.settings);
    let (w, h) = opts.size;
    r.resize(w, h);
    let frames = opts.frames.unwrap_or(1).max(1);
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("headless"),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
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
