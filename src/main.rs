//! `radbake` command line: a thin layer over [`radbake::bake`].
//!
//! Exit codes: 0 success (or already up to date), 1 bad input (scene or
//! settings), 2 usage error, 3 I/O or internal error.

use anyhow::Context as _;
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radbake::config::{
    DirectionalMode, EmitterSampling, FormFactorMethod, Method, Packing, Preset, Solver, UvSource,
};
use radbake::report::StageTime;
use radbake::BakeConfig;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "radbake",
    version,
    about = "Radiosity lightmap baker for glTF 2.0 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake lightmaps for a .gltf/.glb scene.
    Bake(BakeArgs),
    /// Look at a baked .glb in a window (or render it offscreen with --headless).
    #[cfg(feature = "preview")]
    Preview(PreviewArgs),
    /// Path-trace an image of a scene: the reference, or the final pass over a bake's lightmaps.
    Render(RenderArgs),
}

/// Where `render` and `preview` look from.
#[derive(Args)]
struct ViewArgs {
    /// The glTF camera of this name [default: the first camera, or a framing of the scene].
    #[arg(long, conflicts_with = "look_from")]
    camera: Option<String>,
    /// Eye position `x,y,z` (world, metres).
    #[arg(long, value_parser = parse_vec3)]
    look_from: Option<[f32; 3]>,
    /// Look towards `x,y,z` [default: the centre of the scene].
    #[arg(long, value_parser = parse_vec3, requires = "look_from")]
    look_at: Option<[f32; 3]>,
}

#[derive(Args)]
struct RenderArgs {
    /// The scene (.gltf or .glb), as given to `radbake bake`.
    scene: PathBuf,
    /// Output image: `.exr` (linear; a tone-mapped `.png` is written beside it) or `.png`.
    #[arg(long, short)]
    out: PathBuf,
    /// Final pass: read this bake folder's lightmaps at the hits of the indirect rays.
    #[arg(long, value_name = "BAKE_DIR")]
    lightmaps: Option<PathBuf>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    size: (u32, u32),
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Estimator of the reference (the final pass always traces paths).
    #[arg(long, value_enum, default_value = "path")]
    integrator: radbake::trace::render::Integrator,
    #[command(flatten)]
    at: ViewArgs,
    /// Vertical field of view in degrees for --look-from and the framing.
    #[arg(long, default_value_t = 50.0)]
    fov: f32,
    /// Sky radiance `r,g,b` [default: the bake's with --lightmaps, else 0].
    #[arg(long, value_parser = parse_rgb)]
    sky: Option<[f32; 3]>,
    /// Exposure of the PNG in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Seed of the random sequences (images are deterministic for a seed).
    #[arg(long, default_value_t = 0x5eed)]
    seed: u64,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
}

fn run_render(args: &RenderArgs) -> Result<(), (u8, String)> {
    use radbake::trace::render::{self, Integrator, View};
    let start = Instant::now();
    let scene = radbake::scene::load(&args.scene, &Default::default()).map_err(lib_err)?;
    let baked = match &args.lightmaps {
        Some(dir) => Some(render::load_bake(&scene, dir).map_err(lib_err)?),
        None => None,
    };
    let unmapped;
    let geometry = match &baked {
        Some(b) => &b.geometry,
        None => {
            unmapped = radbake::geometry::Geometry::unmapped(&scene);
            &unmapped
        }
    };
    let sky = args
        .sky
        .or(baked.as_ref().map(|b| b.config.sky))
        .unwrap_or([0.0; 3]);
    let rays = radbake::raycast::RayCaster::new(&scene, geometry);
    let mut tracer = radbake::trace::Tracer::new(&scene, geometry, &rays, sky.into());
    if let Some(b) = &baked {
        tracer.lightmaps = Some(radbake::trace::LightmapLookup {
            width: b.width,
            height: b.height,
            pages: &b.pages,
        });
    }
    let mut integrator = args.integrator;
    if integrator == Integrator::Bdpt
        && (baked.is_some() || !radbake::trace::bdpt::supports(&tracer))
    {
        if !args.quiet {
            eprintln!("warning: BDPT covers Lambertian scenes without lightmaps; rendering with the path tracer");
        }
        integrator = Integrator::Path;
    }
    let yfov = args.fov.to_radians();
    let view = match (&args.at.camera, args.at.look_from) {
        (Some(name), _) => {
            let cam = scene
                .cameras
                .iter()
                .find(|c| &c.name == name)
                .ok_or_else(|| {
                    (
                        1,
                        format!("{}: no camera named `{name}`", args.scene.display()),
                    )
                })?;
            View::from_camera(cam)
        }
        (None, Some(from)) => {
            let at = args
                .at
                .look_at
                .map(Into::into)
                .unwrap_or_else(|| centre(geometry));
            View::look_at(from.into(), at, yfov)
        }
        (None, None) => match scene.cameras.first() {
            Some(cam) => View::from_camera(cam),
            None => View::framing(geometry, yfov),
        },
    };
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        let passes = match integrator {
            Integrator::Bdpt => render::BDPT_PASSES as u64,
            Integrator::Path => 1,
        };
        ProgressBar::new(args.size.1 as u64 * passes).with_style(
            ProgressStyle::with_template(
                "{msg:>13} [{bar:30}] {pos}/{len} rows {elapsed} (eta {eta})",
            )
            .expect("static template")
            .progress_chars("=> "),
        )
    };
    bar.set_message(if baked.is_some() {
        "final pass"
    } else {
        "reference"
    });
    let image = render::render(
        &tracer,
        &view,
        args.size,
        args.spp,
        integrator,
        args.seed,
        &|n| bar.inc(n),
    );
    bar.finish_and_clear();
    let io = |e: radbake::Error| (3u8, e.to_string());
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| (3u8, format!("{}: {e}", dir.display())))?;
    }
    let is_exr = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        image.write_exr(&args.out).map_err(io)?;
        image
            .write_png(&args.out.with_extension("png"), args.exposure)
            .map_err(io)?;
    } else {
        image.write_png(&args.out, args.exposure).map_err(io)?;
    }
    if !args.quiet {
        let m = image.mean();
        eprintln!(
            "rendered {}x{} at {} spp ({:?}) in {:.2} s, mean radiance {:.4} {:.4} {:.4} → {}",
            args.size.0,
            args.size.1,
            args.spp,
            integrator,
            start.elapsed().as_secs_f64(),
            m.x,
            m.y,
            m.z,
            args.out.display()
        );
    }
    Ok(())
}

/// Centre of the scene's bounding box.
fn centre(geometry: &radbake::geometry::Geometry) -> glam::Vec3 {
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
    for p in geometry.p_ws.iter().flatten() {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if lo.x > hi.x {
        glam::Vec3::ZERO
    } else {
        (lo + hi) * 0.5
    }
}

#[cfg(feature = "preview")]
#[derive(Args)]
struct PreviewArgs {
    /// The baked scene (`<stem>.baked.glb` from `radbake bake`).
    scene: PathBuf,
    /// Render offscreen to --out instead of opening a window.
    #[arg(long, requires = "out")]
    headless: bool,
    /// Output PNG of --headless (written atomically).
    #[arg(long, short, requires = "headless")]
    out: Option<PathBuf>,
    /// Image (headless) or window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    size: (u32, u32),
    #[command(flatten)]
    at: ViewArgs,
    /// Headless: render N frames and print ms/frame. Window: render N frames, then exit.
    #[arg(long)]
    frames: Option<u32>,
    /// Window: after --frames frames, save the last view here (PNG) and exit.
    #[arg(long, requires = "frames", conflicts_with = "headless")]
    screenshot: Option<PathBuf>,
    /// First debug view.
    #[arg(long, value_enum, default_value = "lit")]
    view: radbake::preview::ViewMode,
    /// Bicubic (B-spline) lightmap filtering instead of bilinear.
    #[arg(long)]
    bicubic: bool,
    /// Exposure in stops (EV).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Tone map of the HDR values.
    #[arg(long, value_enum, default_value = "aces")]
    tone_map: radbake::preview::ToneMap,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| "expected WIDTHxHEIGHT, e.g. 1280x720".to_string())?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("`{v}`: {e}"));
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err("width and height must be 1..=16384".into());
    }
    Ok((w, h))
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    match parse_rgb(s)? {
        v if s.split(',').count() == 3 => Ok(v),
        _ => Err("expected x,y,z".into()),
    }
}

#[cfg(feature = "preview")]
fn run_preview(args: &PreviewArgs) -> Result<(), (u8, String)> {
    use radbake::preview::{Options, Settings, Viewpoint};
    let viewpoint = match (&args.at.camera, args.at.look_from) {
        (Some(name), _) => Viewpoint::Camera(name.clone()),
        (None, Some(from)) => Viewpoint::LookAt {
            from: from.into(),
            at: args.at.look_at.map(Into::into),
        },
        (None, None) => Viewpoint::Auto,
    };
    let opts = Options {
        scene: args.scene.clone(),
        headless: args.headless,
        out: args.out.clone(),
        size: args.size,
        viewpoint,
        frames: args.frames,
        screenshot: args.screenshot.clone(),
        settings: Settings {
            view: args.view,
            bicubic: args.bicubic,
            exposure_ev: args.exposure,
            tone_map: args.tone_map,
        },
    };
    radbake::preview::run(&opts).map_err(|e| {
        let code = match e.downcast_ref::<radbake::Error>() {
            Some(le) if le.is_input_error() => 1,
            _ => 3,
        };
        (code, format!("{e:#}"))
    })
}

#[derive(Args)]
struct BakeArgs {
    /// The scene (.gltf or .glb).
    scene: PathBuf,
    /// Output folder (created if missing): lightmap_<page>.exr/.png, report.json.
    #[arg(long, short)]
    out: PathBuf,
    /// Settings file (TOML, keys as in report.json's "settings"); flags override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Lightmap texels per metre [default: 116].
    #[arg(long)]
    texels_per_meter: Option<f32>,
    /// Empty texels around each chart [default: 4].
    #[arg(long)]
    padding: Option<u32>,
    /// Patch size k: patches are k×k texel blocks [default: 4].
    #[arg(long)]
    patch_texels: Option<u32>,
    /// Form-factor rays per patch [default: 1024].
    #[arg(long)]
    rays_per_patch: Option<u32>,
    /// Solver stops when the relative change of radiance is below this [default: 1e-4].
    #[arg(long)]
    tolerance: Option<f32>,
    /// Solver iteration limit [default: 200].
    #[arg(long)]
    max_iterations: Option<u32>,
    /// Lightmap UVs: unwrap, or repack the input's TEXCOORD_1 [default: unwrap].
    #[arg(long, value_enum)]
    uv: Option<UvSource>,
    /// Chart packing: fast (rows), or shape (nested shapes, slower) [default: fast].
    #[arg(long, value_enum)]
    packing: Option<Packing>,
    /// Form-factor method [default: raycast].
    #[arg(long, value_enum)]
    form_factors: Option<FormFactorMethod>,
    /// Hemicube top-face resolution in pixels [default: 128].
    #[arg(long)]
    hemicube_resolution: Option<u32>,
    /// Solver [default: jacobi].
    #[arg(long, value_enum)]
    solver: Option<Solver>,
    /// Largest patch count the direct solver accepts [default: 4096].
    #[arg(long)]
    direct_max_patches: Option<u32>,
    /// Seed of all random sequences [default: 24301].
    #[arg(long)]
    seed: Option<u64>,
    /// Texel budget: where the scene would need more texels, the density is lowered to fit [default: 1048576; preview 262144, production 4194304].
    #[arg(long)]
    max_texels: Option<u64>,
    /// Direct-light samples per texel (emitter samples and hemisphere rays each) [default: 64].
    #[arg(long)]
    direct_samples: Option<u32>,
    /// Sky radiance `r,g,b` (W·sr⁻¹·m⁻², linear) seen by rays leaving the scene [default: 0,0,0].
    #[arg(long, value_parser = parse_rgb)]
    sky: Option<[f32; 3]>,
    /// Directional lightmaps: `sh` writes L1 spherical-harmonic pages [default: none].
    #[arg(long, value_enum)]
    directional: Option<DirectionalMode>,
    /// Write an ambient-occlusion map for occluders within this distance (metres) [default: off].
    #[arg(long = "ao", value_name = "METRES")]
    ao_distance: Option<f32>,
    /// Evaluate punctual lights at s × s points per texel (antialiased shadow edges) [default: 1].
    #[arg(long)]
    supersample: Option<u32>,
    /// Denoise the gathered indirect light (edge-aware à-trous): true or false [default: true].
    #[arg(long)]
    denoise: Option<bool>,
    /// Stitch UV seams of continuous surfaces: true or false [default: true].
    #[arg(long)]
    stitch_seams: Option<bool>,
    /// Final-gather rays per texel; 0 turns the final gather off [default: 128].
    #[arg(long)]
    final_gather: Option<u32>,
    /// Emissive surfaces: sampled per texel (`direct`), through the radiosity solve (`radiosity`),
    /// or `auto`: direct when a material covers ≤ 2 % of the surface [default: auto].
    #[arg(long, value_enum)]
    emitters: Option<EmitterSampling>,
    /// Where form-factor rays are cast: cpu, or gpu (wgpu compute; CPU fallback with a warning) [default: cpu].
    #[arg(long, value_enum)]
    device: Option<radbake::config::Device>,
    /// Light transport: radiosity, or the pathtrace / photon references [default: radiosity].
    #[arg(long, value_enum)]
    method: Option<Method>,
    /// Paths per texel with --method pathtrace [default: 1024].
    #[arg(long)]
    path_samples: Option<u32>,
    /// Photons emitted with --method photon [default: 1048576].
    #[arg(long)]
    photons: Option<u64>,
    /// Nearest photons per estimate with --method photon [default: 128].
    #[arg(long)]
    photon_neighbours: Option<u32>,
    /// Also write lightmap_<page>_debug.png (patches, texel validity) for the preview's debug views.
    #[arg(long)]
    debug_maps: bool,
    /// Starting settings, below the config file and flags [default: medium].
    #[arg(long, value_enum)]
    preset: Option<Preset>,
    /// Refuse scenes whose estimated bake memory exceeds this many megabytes (checked before reading geometry).
    #[arg(long, value_name = "MB")]
    max_memory: Option<u64>,
    /// Give up after this many seconds (exit code 3, temporaries removed).
    #[arg(long, value_name = "SECONDS")]
    timeout: Option<f64>,
    /// Bake even if the outputs are up to date.
    #[arg(long)]
    force: bool,
    /// Progress: `bars` (on a terminal) or `json` (one object per line on stderr).
    #[arg(long, value_enum, default_value = "bars")]
    progress: ProgressMode,
    /// Print nothing but errors.
    #[arg(long, short, conflicts_with = "verbose")]
    quiet: bool,
    /// Also print per-stage times and counters.
    #[arg(long, short)]
    verbose: bool,
    /// After the bake, print a table of per-stage times, rays, rays/s and peak memory (stderr).
    #[arg(long)]
    stats: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ProgressMode {
    Bars,
    Json,
}

impl BakeArgs {
    /// Defaults < preset < config file < flags.
    fn config(&self) -> anyhow::Result<BakeConfig> {
        let base = BakeConfig::preset(self.preset.unwrap_or(Preset::Medium));
        let mut c = match &self.config {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("cannot read config {}", path.display()))?;
                BakeConfig::from_toml_over(&base, &text)?
            }
            None => base,
        };
        macro_rules! set {
            ($($f:ident),*) => { $( if let Some(v) = self.$f { c.$f = v; } )* };
        }
        set!(
            texels_per_meter,
            padding,
            patch_texels,
            rays_per_patch,
            tolerance,
            max_iterations,
            uv,
            packing,
            form_factors,
            hemicube_resolution,
            solver,
            direct_max_patches,
            seed,
            max_texels,
            direct_samples,
            sky,
            emitters,
            final_gather,
            stitch_seams,
            denoise,
            directional,
            ao_distance,
            supersample,
            method,
            path_samples,
            photons,
            photon_neighbours,
            device
        );
        if self.debug_maps {
            c.debug_maps = true;
        }
        c.validate()?;
        Ok(c)
    }
}

/// Parses `r,g,b` (or one number for grey).
fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [g] => Ok([*g; 3]),
        [r, g, b] => Ok([*r, *g, *b]),
        _ => Err("expected r,g,b".into()),
    }
}

/// indicatif bars, one per stage.
struct Bars {
    bar: Mutex<Option<ProgressBar>>,
    hidden: bool,
}

impl radbake::Progress for Bars {
    fn begin(&self, stage: &str, total: u64) {
        let bar = if total > 0 {
            ProgressBar::new(total).with_style(
                ProgressStyle::with_template(
                    "{msg:>13} [{bar:30}] {pos}/{len} {elapsed} (eta {eta})",
                )
                .expect("static template")
                .progress_chars("=> "),
            )
        } else {
            ProgressBar::new_spinner().with_style(
                ProgressStyle::with_template("{msg:>13} {spinner} {elapsed}")
                    .expect("static template"),
            )
        };
        if self.hidden {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        } else {
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        bar.set_message(stage.to_owned());
        *self.bar.lock().expect("progress lock") = Some(bar);
    }
    fn advance(&self, n: u64) {
        if let Some(b) = self.bar.lock().expect("progress lock").as_ref() {
            b.inc(n);
        }
    }
    fn end(&self) {
        if let Some(b) = self.bar.lock().expect("progress lock").take() {
            b.finish();
        }
    }
}

/// One JSON object per line on stderr: {"stage","done","total","elapsed","eta"}
/// at most every 100 ms, and at each stage's start and end.
struct JsonProgress {
    state: Mutex<(String, u64, u64, Instant, Instant)>,
}

impl JsonProgress {
    fn emit(stage: &str, done: u64, total: u64, started: Instant) {
        let elapsed = started.elapsed().as_secs_f64();
        let eta = if done > 0 && total >= done {
            serde_json::json!(elapsed * (total - done) as f64 / done as f64)
        } else {
            serde_json::Value::Null
        };
        eprintln!(
            "{}",
            serde_json::json!({"stage": stage, "done": done, "total": total, "elapsed": elapsed, "eta": eta})
        );
    }
}

impl radbake::Progress for JsonProgress {
    fn begin(&self, stage: &str, total: u64) {
        let now = Instant::now();
        *self.state.lock().expect("progress lock") = (stage.to_owned(), 0, total, now, now);
        Self::emit(stage, 0, total, now);
    }
    fn advance(&self, n: u64) {
        let mut s = self.state.lock().expect("progress lock");
        s.1 += n;
        if s.4.elapsed().as_millis() >= 100 {
            s.4 = Instant::now();
            Self::emit(&s.0, s.1, s.2, s.3);
        }
    }
    fn end(&self) {
        let s = self.state.lock().expect("progress lock");
        Self::emit(&s.0, s.1.max(s.2), s.2, s.3);
    }
}

fn run_bake(args: &BakeArgs) -> Result<(), (u8, String)> {
    let config = args
        .config()
        .map_err(|e| (classify(&e), format!("{e:#}")))?;
    // Ctrl-C and --timeout: nothing but temporaries can be half-written
    // (outputs are renamed into place), so remove ours and leave at once.
    let out_dir = args.out.clone();
    let _ = ctrlc::set_handler(move || {
        radbake::output::remove_temporaries(&out_dir, Some(std::process::id()));
        eprintln!("error: interrupted");
        std::process::exit(130);
    });
    if let Some(secs) = args.timeout.filter(|s| s.is_finite() && *s > 0.0) {
        let out_dir = args.out.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs_f64(secs));
            radbake::output::remove_temporaries(&out_dir, Some(std::process::id()));
            eprintln!("error: the bake took longer than --timeout {secs} s");
            std::process::exit(3);
        });
    }
    let start = Instant::now();
    let load_options = radbake::scene::LoadOptions {
        max_memory: args.max_memory.map(|mb| mb.saturating_mul(1 << 20)),
        ..Default::default()
    };
    let scene = radbake::scene::load(&args.scene, &load_options).map_err(lib_err)?;
    let import = StageTime {
        stage: "import".into(),
        seconds: start.elapsed().as_secs_f64(),
    };
    let stem = args
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let hash = radbake::incremental::content_hash(&scene, &config);
    let glb = format!("{stem}.baked.glb");
    let expected = [
        "report.json",
        "manifest.json",
        "lightmap_0.exr",
        glb.as_str(),
    ];
    if !args.force && radbake::incremental::up_to_date(&args.out, &hash, &expected) {
        if !args.quiet {
            eprintln!(
                "{}: up to date (use --force to bake again)",
                args.out.display()
            );
        }
        return Ok(());
    }
    let progress: Box<dyn radbake::Progress> = match args.progress {
        ProgressMode::Json => Box::new(JsonProgress {
            state: Mutex::new((String::new(), 0, 0, Instant::now(), Instant::now())),
        }),
        ProgressMode::Bars => Box::new(Bars {
            bar: Mutex::new(None),
            hidden: args.quiet,
        }),
    };
    // Errors from the bake's stages name what is wrong but not the file.
    let bake = radbake::bake(&scene, &config, progress.as_ref()).map_err(|e| {
        let (code, message) = lib_err(e);
        (code, format!("{}: {message}", args.scene.display()))
    })?;
    let mut report = bake.report(&args.scene.display().to_string());
    report.stages.insert(0, import);
    let t = Instant::now();
    let mut written =
        radbake::output::write_lightmaps(&args.out, &bake.lightmaps).map_err(lib_err)?;
    written.extend(radbake::output::write_extra_maps(&args.out, &bake).map_err(lib_err)?);
    if config.debug_maps {
        written.extend(radbake::output::write_debug_maps(&args.out, &bake).map_err(lib_err)?);
    }
    written.extend(
        radbake::output::write_engine_outputs(
            &args.out,
            &stem,
            &scene,
            &bake.atlas,
            &bake.lightmaps,
        )
        .map_err(lib_err)?,
    );
    report.stages.push(StageTime {
        stage: "write".into(),
        seconds: t.elapsed().as_secs_f64(),
    });
    written.push(radbake::output::write_report(&args.out, &report).map_err(lib_err)?);
    radbake::incremental::record(&args.out, &hash).map_err(lib_err)?;
    if args.verbose {
        for s in &report.stages {
            eprintln!("{:>13}: {:8.3} s", s.stage, s.seconds);
        }
        if let Ok(counts) = serde_json::to_string_pretty(&report.counts) {
            eprintln!("{counts}");
        }
    }
    if args.stats {
        eprint!("{}", report.stats_table(radbake::report::peak_rss_bytes()));
    }
    if !args.quiet {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        let c = &report.counts;
        eprintln!(
            "baked {} triangles, {} texels, {} patches, {} rays, {} iterations in {:.2} s → {} files in {}",
            c.triangles,
            c.texels,
            c.patches,
            c.rays,
            c.iterations,
            start.elapsed().as_secs_f64(),
            written.len(),
            args.out.display()
        );
    }
    Ok(())
}

fn lib_err(e: radbake::Error) -> (u8, String) {
    (if e.is_input_error() { 1 } else { 3 }, e.to_string())
}

fn classify(e: &anyhow::Error) -> u8 {
    match e.downcast_ref::<radbake::Error>() {
        Some(le) if le.is_input_error() => 1,
        Some(_) => 3,
        None => 1,
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    // A panic is a bug, never the input's fault: report it in one line, exit 3.
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("error: internal error (a bug in radbake){at}: {msg}");
    }));
    let result = std::panic::catch_unwind(|| match &cli.command {
        Command::Bake(args) => run_bake(args),
        Command::Render(args) => run_render(args),
        #[cfg(feature = "preview")]
        Command::Preview(args) => run_preview(args),
    });
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err((code, msg))) => {
            eprintln!("error: {msg}");
            ExitCode::from(code)
        }
        Err(_) => ExitCode::from(3),
    }
}
