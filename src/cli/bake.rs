//! `radbake bake`: settings from defaults < preset < config file < flags,
//! the up-to-date check, the bake, and its outputs written atomically.

use super::progress::{Bars, JsonProgress, SnapshotWriter};
use super::{classify, lib_err, parse_rgb, Outcome};
use anyhow::Context as _;
use clap::Args;
use radbake::config::{
    DirectionalMode, EmitterSampling, FormFactorMethod, Method, Packing, Preset, Solver, UvSource,
};
use radbake::pipeline::report::StageTime;
use radbake::BakeConfig;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

#[derive(Args)]
pub struct BakeArgs {
    /// The scene (.gltf or .glb).
    pub scene: PathBuf,
    /// Output folder (created if missing): lightmap_<page>.exr/.png, report.json.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Settings file (TOML, keys as in report.json's "settings"); flags override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Lightmap texels per metre [default: 116].
    #[arg(long)]
    pub texels_per_meter: Option<f32>,
    /// Empty texels around each chart [default: 4].
    #[arg(long)]
    pub padding: Option<u32>,
    /// Patch size k: patches are k×k texel blocks [default: 4].
    #[arg(long)]
    pub patch_texels: Option<u32>,
    /// Form-factor rays per patch [default: 256; preview 128, production 1024].
    #[arg(long)]
    pub rays_per_patch: Option<u32>,
    /// Solver stops when the relative change of radiance is below this [default: 1e-4].
    #[arg(long)]
    pub tolerance: Option<f32>,
    /// Solver iteration limit [default: 200].
    #[arg(long)]
    pub max_iterations: Option<u32>,
    /// Lightmap UVs: unwrap, or repack the input's TEXCOORD_1 [default: unwrap].
    #[arg(long, value_enum)]
    pub uv: Option<UvSource>,
    /// Chart packing: fast (rows), or shape (nested shapes, slower) [default: fast].
    #[arg(long, value_enum)]
    pub packing: Option<Packing>,
    /// Form-factor method [default: raycast].
    #[arg(long, value_enum)]
    pub form_factors: Option<FormFactorMethod>,
    /// Hemicube top-face resolution in pixels [default: 128].
    #[arg(long)]
    pub hemicube_resolution: Option<u32>,
    /// Solver [default: jacobi].
    #[arg(long, value_enum)]
    pub solver: Option<Solver>,
    /// Largest patch count the direct solver accepts [default: 4096].
    #[arg(long)]
    pub direct_max_patches: Option<u32>,
    /// Seed of all random sequences [default: 24301].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Texel budget: where the scene would need more texels, the density is lowered to fit [default: 1048576; preview 262144, production 4194304].
    #[arg(long)]
    pub max_texels: Option<u64>,
    /// Direct-light samples per texel (emitter samples and hemisphere rays each) [default: 64].
    #[arg(long)]
    pub direct_samples: Option<u32>,
    /// Sky radiance `r,g,b` (W·sr⁻¹·m⁻², linear) seen by rays leaving the scene [default: 0,0,0].
    #[arg(long, value_parser = parse_rgb)]
    pub sky: Option<[f32; 3]>,
    /// Equirectangular HDRI (.exr or .hdr, linear RGB; row 0 the zenith, centre −X as in Blender) seen by rays leaving the scene, instead of --sky [default: none].
    #[arg(long, value_name = "FILE")]
    pub sky_map: Option<PathBuf>,
    /// Turns the sky map about +Y, degrees counter-clockwise seen from above [default: 0].
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true)]
    pub sky_rotation: Option<f32>,
    /// Scales the sky map's radiance [default: 1].
    #[arg(long)]
    pub sky_intensity: Option<f32>,
    /// Sky-map light samples per texel and per probe, combined with the cosine rays by MIS [default: 16].
    #[arg(long)]
    pub sky_samples: Option<u32>,
    /// Directional lightmaps: `sh` writes L1 spherical-harmonic pages [default: none].
    #[arg(long, value_enum)]
    pub directional: Option<DirectionalMode>,
    /// Write an ambient-occlusion map for occluders within this distance (metres) [default: off].
    #[arg(long = "ao", value_name = "METRES")]
    pub ao_distance: Option<f32>,
    /// Evaluate punctual lights at s × s points per texel (antialiased shadow edges) [default: 1].
    #[arg(long)]
    pub supersample: Option<u32>,
    /// Denoise the gathered indirect light (edge-aware à-trous): true or false [default: true].
    #[arg(long)]
    pub denoise: Option<bool>,
    /// Stitch UV seams of continuous surfaces: true or false [default: true].
    #[arg(long)]
    pub stitch_seams: Option<bool>,
    /// Fold texels' sample points out of walls and solids crossing them: true or false [default: true].
    #[arg(long)]
    pub burial_planes: Option<bool>,
    /// A texel is invalid when more than this fraction of its rays meet back faces (Unity: 0.1) [default: 0.5].
    #[arg(long)]
    pub backface_tolerance: Option<f32>,
    /// Final-gather rays per texel; 0 turns the final gather off [default: 128].
    #[arg(long)]
    pub final_gather: Option<u32>,
    /// HDR lightmap pages as KTX2 for Bevy (lightmap_<page>.ktx2): `rgb9e5`, `bc6h` or `off` [default: rgb9e5].
    #[arg(long, value_enum)]
    pub ktx2: Option<radbake::config::Ktx2Mode>,
    /// Light layers: `auto` bakes one lightmap and probe set per layer where the scene names one
    /// (`extras.radbake.layer` on a light's node or a material) or --sky-layer is given; `off` bakes
    /// one of every light [default: auto].
    #[arg(long, value_enum)]
    pub layers: Option<radbake::config::LayerMode>,
    /// The sky's light layer (a plain identifier) [default: static].
    #[arg(long, value_name = "NAME")]
    pub sky_layer: Option<String>,
    /// Live sun: every directional light whose node sets no mode is baked in mode `live` (its
    /// bounced light in layer `live`, re-solved at run time from `live.bin` for any direction;
    /// docs/live.md).
    #[arg(long)]
    pub live: bool,
    /// A live bake's sun directions: an n × n grid over the upper hemisphere, 2 to 64 [default: 12].
    #[arg(long, value_name = "N")]
    pub live_grid: Option<u32>,
    /// A live bake's rays per probe for the live probes' view of the patches, 0 to 4096 (0: the
    /// live light's bounce in the probes stays as baked) [default: 64].
    #[arg(long, value_name = "N")]
    pub live_probe_rays: Option<u32>,
    /// A live sun's path, `LATITUDE,DAY[,SAMPLES]` (degrees north, day 1–366, default 256 samples),
    /// for live lights whose node gives no `extras.radbake.sun_path`: tables along it, not over the
    /// hemisphere.
    #[arg(long, value_name = "LAT,DAY[,N]", value_parser = parse_sun_path, allow_hyphen_values = true)]
    pub sun_path: Option<radbake::config::SunPathSetting>,
    /// Light probes for dynamic objects: on or off [default: on].
    #[arg(long, value_parser = parse_on_off, value_name = "on|off")]
    pub probes: Option<bool>,
    /// Probe spacing in metres (`probe_volume` nodes may set their own) [default: 1].
    #[arg(long, value_name = "METRES")]
    pub probe_spacing: Option<f32>,
    /// Most probes in all; the spacing grows to fit [default: 16384; preview 2048, production 65536].
    #[arg(long)]
    pub probe_budget: Option<u32>,
    /// Rays per probe [default: 256; preview 128, production 1024].
    #[arg(long)]
    pub probe_rays: Option<u32>,
    /// Also bake the signed distance field (sdf.ktx2) with this many voxels along the longest side [default: 0, none].
    #[arg(long, value_name = "VOXELS")]
    pub sdf: Option<u32>,
    /// The distance field's texel format: r32f or r16f (half floats) [default: r32f].
    #[arg(long, value_enum)]
    pub sdf_format: Option<radbake::config::SdfFormat>,
    /// What the distance field covers: the scene, or the union of its probe volumes' boxes [default: scene].
    #[arg(long, value_enum)]
    pub sdf_bounds: Option<radbake::config::SdfBounds>,
    /// Adaptive gather: a texel stops at 32, 64, … rays once its estimated relative
    /// standard error is at most this; 0 casts every ray [default: 0.005].
    #[arg(long)]
    pub gather_threshold: Option<f32>,
    /// Final gather: also sample rays towards the solved bright patches (next-event
    /// estimation, MIS with the cosine rays): true or false [default: false].
    #[arg(long)]
    pub gather_nee: Option<bool>,
    /// Final gather: rays that land closer than this many texels read the emitters' and
    /// point/spot lights' direct light at the hit point, not the hit texel's mean; 0: off [default: 1].
    #[arg(long, value_name = "TEXELS")]
    pub gather_near_field: Option<f32>,
    /// Emissive surfaces: sampled per texel (`direct`), through the radiosity solve (`radiosity`),
    /// or `auto`: direct when a material covers ≤ 2 % of the surface [default: auto].
    #[arg(long, value_enum)]
    pub emitters: Option<EmitterSampling>,
    /// Where the form factors' and final gather's rays are cast: cpu, or gpu (wgpu compute; CPU fallback with a warning) [default: cpu].
    #[arg(long, value_enum)]
    pub device: Option<radbake::config::Device>,
    /// Light transport: radiosity, or the pathtrace / photon references [default: radiosity].
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Paths per texel with --method pathtrace [default: 1024].
    #[arg(long)]
    pub path_samples: Option<u32>,
    /// Photons emitted with --method photon [default: 1048576].
    #[arg(long)]
    pub photons: Option<u64>,
    /// Nearest photons per estimate with --method photon [default: 128].
    #[arg(long)]
    pub photon_neighbours: Option<u32>,
    /// Also write lightmap_<page>_debug.png (patches, texel validity) for the preview's debug views.
    #[arg(long)]
    pub debug_maps: bool,
    /// A light's bake mode, by its light's or node's name (repeatable; overrides the node's
    /// extras.radbake.mode and the config): baked (direct + bounced light in the lightmap),
    /// indirect (bounced only; the engine draws its direct light), shadowmask (as indirect,
    /// plus its occlusion in a channel of the shadowmask pages), realtime (not baked).
    #[arg(long = "light-mode", value_name = "NAME=MODE", value_parser = parse_light_mode)]
    pub light_mode: Vec<(String, radbake::scene::LightMode)>,
    /// Starting settings, below the config file and flags [default: medium].
    #[arg(long, value_enum)]
    pub preset: Option<Preset>,
    /// Refuse scenes whose estimated bake memory exceeds this many megabytes (checked before reading geometry).
    #[arg(long, value_name = "MB")]
    pub max_memory: Option<u64>,
    /// Give up after this many seconds (exit code 3, temporaries removed).
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
    /// Bake even if the outputs are up to date.
    #[arg(long)]
    pub force: bool,
    /// Progress: `bars` (on a terminal) or `json` (one object per line on stderr).
    #[arg(long, value_enum, default_value = "bars")]
    pub progress: ProgressMode,
    /// With --solver progressive: every this many seconds, write the solve
    /// as it stands (direct light, the light shot so far and the ambient
    /// term for the rest; no final gather) to `<out>/<stem>.snapshot.glb`,
    /// for `radbake preview --watch <out>`; removed when the bake is done.
    #[arg(long, value_name = "SECONDS")]
    pub snapshot_every: Option<f64>,
    /// Print nothing but errors.
    #[arg(long, short, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Also print per-stage times and counters.
    #[arg(long, short)]
    pub verbose: bool,
    /// After the bake, print a table of per-stage times, rays, rays/s and peak memory (stderr).
    #[arg(long)]
    pub stats: bool,
}

/// `on`/`off` (or `true`/`false`).
/// `NAME=MODE` of `--light-mode`.
fn parse_light_mode(s: &str) -> Result<(String, radbake::scene::LightMode), String> {
    use radbake::scene::LightMode;
    let names = LightMode::ALL.map(LightMode::name).join(", ");
    let (name, mode) = s
        .rsplit_once('=')
        .ok_or_else(|| format!("`{s}` is not NAME=MODE (MODE one of {names})"))?;
    if name.is_empty() {
        return Err(format!("`{s}`: the light's name is empty"));
    }
    let mode = LightMode::parse(mode)
        .ok_or_else(|| format!("`{mode}` is not a light mode (one of {names})"))?;
    Ok((name.to_owned(), mode))
}

fn parse_sun_path(s: &str) -> Result<radbake::config::SunPathSetting, String> {
    let v: Vec<f32> = (s.split(','))
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    let (latitude, day, samples) = match v[..] {
        [l, d] => (l, d, radbake::scene::sun_path::DEFAULT_SAMPLES as f32),
        [l, d, n] => (l, d, n),
        _ => return Err("expected LATITUDE,DAY or LATITUDE,DAY,SAMPLES".into()),
    };
    if samples.fract() != 0.0 || samples < 2.0 {
        return Err("SAMPLES must be a whole number ≥ 2".into());
    }
    Ok(radbake::config::SunPathSetting {
        latitude,
        day,
        samples: samples as u32,
    })
}

fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" | "true" => Ok(true),
        "off" | "false" => Ok(false),
        _ => Err(format!("expected on or off, got {s:?}")),
    }
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressMode {
    Bars,
    Json,
}

impl BakeArgs {
    /// Defaults < preset < config file < flags.
    pub(super) fn config(&self) -> anyhow::Result<BakeConfig> {
        let base = BakeConfig::preset(self.preset.unwrap_or(Preset::Medium));
        let mut c = match &self.config {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("cannot read config {}", path.display()))?;
                let mut c = BakeConfig::from_toml_over(&base, &text)?;
                // A config file's sky map is relative to the file.
                if let (Some(map), Some(dir)) = (&mut c.sky_map, path.parent()) {
                    if map.is_relative() {
                        *map = dir.join(&*map);
                    }
                }
                c
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
            sky_rotation,
            sky_intensity,
            sky_samples,
            emitters,
            final_gather,
            gather_threshold,
            gather_nee,
            gather_near_field,
            ktx2,
            layers,
            probes,
            probe_spacing,
            probe_budget,
            probe_rays,
            sdf,
            sdf_format,
            sdf_bounds,
            stitch_seams,
            burial_planes,
            backface_tolerance,
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
        if let Some(map) = &self.sky_map {
            c.sky_map = Some(map.clone());
        }
        if let Some(name) = &self.sky_layer {
            c.sky_layer = Some(name.clone());
        }
        if self.live {
            c.light_modes.directional = Some(radbake::config::LightMode::Live);
        }
        if let Some(n) = self.live_grid {
            c.live_grid = n;
        }
        if let Some(n) = self.live_probe_rays {
            c.live_probe_rays = n;
        }
        if let Some(p) = self.sun_path {
            c.sun_path = Some(p);
        }
        for (name, mode) in &self.light_mode {
            c.light_modes.lights.insert(name.clone(), *mode);
        }
        c.validate()?;
        Ok(c)
    }
}

/// Bakes `args.scene` into `args.out`, unless the outputs are up to date.
pub fn run(args: &BakeArgs) -> Outcome {
    let config = args
        .config()
        .map_err(|e| (classify(&e), format!("{e:#}")))?;
    remove_temporaries_on_exit(args);
    let start = Instant::now();
    let load_options = radbake::scene::LoadOptions {
        max_memory: args.max_memory.map(|mb| mb.saturating_mul(1 << 20)),
        ..Default::default()
    };
    let mut scene = radbake::scene::load(&args.scene, &load_options).map_err(lib_err)?;
    config.light_modes.apply(&mut scene).map_err(|e| {
        let (code, message) = lib_err(e);
        (code, format!("{}: {message}", args.scene.display()))
    })?;
    let live = radbake::config::LightMode::Live;
    if args.live && !scene.lights.iter().any(|l| l.mode == live) {
        return Err((
            2,
            format!(
                "{}: --live: the scene has no directional light in mode `live` (none, or each one's node sets its own mode)",
                args.scene.display()
            ),
        ));
    }
    let import = StageTime {
        stage: "import".into(),
        seconds: start.elapsed().as_secs_f64(),
    };
    let stem = args
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let hash = radbake::pipeline::incremental::content_hash(&scene, &config);
    if !args.force && up_to_date(args, &stem, &hash) {
        return Ok(());
    }
    let progress: Box<dyn radbake::Progress> = match args.progress {
        ProgressMode::Json => Box::new(JsonProgress {
            state: Mutex::new((String::new(), 0, 0, Instant::now(), Instant::now())),
            figures: Mutex::new(Default::default()),
        }),
        ProgressMode::Bars => Box::new(Bars {
            bar: Mutex::new(None),
            hidden: args.quiet,
        }),
    };
    let snapshots = match args.snapshot_every {
        Some(every) => Some(snapshot_writer(
            args,
            &config,
            &scene,
            &stem,
            every,
            progress.as_ref(),
        )?),
        None => None,
    };
    let sink: &dyn radbake::Progress = match &snapshots {
        Some(w) => w,
        None => progress.as_ref(),
    };
    // Errors from the bake's stages name what is wrong but not the file.
    let bake = radbake::bake(&scene, &config, sink).map_err(|e| {
        let (code, message) = lib_err(e);
        (code, format!("{}: {message}", args.scene.display()))
    })?;
    let mut report = bake.report(&args.scene.display().to_string());
    report.stages.insert(0, import);
    if let Some(w) = &snapshots {
        let (_, error) = &*w.outcome.lock().expect("snapshot lock");
        report.warnings.extend(error.clone());
    }
    let written = write_outputs(&args.out, &stem, &bake, &mut report)?;
    if let Some(w) = &snapshots {
        // The final .baked.glb supersedes the snapshots.
        let _ = std::fs::remove_file(&w.path);
    }
    radbake::pipeline::incremental::record(&args.out, &hash).map_err(lib_err)?;
    print_summary(args, &report, start, written.len());
    Ok(())
}

/// The `--snapshot-every` sink around `inner`; refused unless the solver
/// is progressive (the others have no partial solution to show).
fn snapshot_writer<'a>(
    args: &BakeArgs,
    config: &BakeConfig,
    scene: &'a radbake::scene::Scene,
    stem: &str,
    every: f64,
    inner: &'a dyn radbake::Progress,
) -> Result<SnapshotWriter<'a>, (u8, String)> {
    if config.solver != Solver::Progressive {
        return Err((
            1,
            "--snapshot-every needs --solver progressive (the other solvers have no partial solution to show)".into(),
        ));
    }
    if !(every.is_finite() && every >= 0.0) {
        return Err((
            1,
            format!("--snapshot-every: {every} is not a number of seconds ≥ 0"),
        ));
    }
    std::fs::create_dir_all(&args.out).map_err(|e| (3, format!("{}: {e}", args.out.display())))?;
    Ok(SnapshotWriter {
        inner,
        every,
        scene,
        path: args.out.join(format!("{stem}.snapshot.glb")),
        outcome: Mutex::new((0, None)),
    })
}

/// Ctrl-C and --timeout: nothing but temporaries can be half-written
/// (outputs are renamed into place), so remove ours and leave at once.
fn remove_temporaries_on_exit(args: &BakeArgs) {
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
}

/// True (and said, unless quiet) when `args.out` holds a bake of this very
/// scene and settings (`hash`) with every main output present.
fn up_to_date(args: &BakeArgs, stem: &str, hash: &str) -> bool {
    let glb = format!("{stem}.baked.glb");
    let expected = [
        "report.json",
        "manifest.json",
        "lightmap_0.exr",
        glb.as_str(),
    ];
    let fresh = radbake::pipeline::incremental::up_to_date(&args.out, hash, &expected);
    if fresh && !args.quiet {
        eprintln!(
            "{}: up to date (use --force to bake again)",
            args.out.display()
        );
    }
    fresh
}

/// Writes every output (each atomically) and, last, `report.json` with the
/// write stage's time; returns the files written.
pub(super) fn write_outputs(
    out: &std::path::Path,
    stem: &str,
    bake: &radbake::Bake,
    report: &mut radbake::pipeline::report::Report,
) -> Result<Vec<PathBuf>, (u8, String)> {
    use radbake::output;
    let t = Instant::now();
    // The float pages and the engines' files are written side by side
    // (different files; each encoder runs on one core).
    let (maps, engines) = rayon::join(
        || -> radbake::Result<Vec<PathBuf>> {
            let mut written = output::write_lightmaps(out, &bake.maps.lightmaps)?;
            written.extend(output::write_extra_maps(out, bake)?);
            if bake.config.debug_maps {
                written.extend(output::write_debug_maps(out, bake)?);
            }
            Ok(written)
        },
        || output::write_engine_outputs(out, stem, bake),
    );
    let mut written = maps.map_err(lib_err)?;
    written.extend(engines.map_err(lib_err)?);
    report.stages.push(StageTime {
        stage: "write".into(),
        seconds: t.elapsed().as_secs_f64(),
    });
    written.push(output::write_report(out, report).map_err(lib_err)?);
    Ok(written)
}

/// Stage times and counters (`--verbose`), the stats table (`--stats`),
/// warnings and the one-line summary (unless `--quiet`).
fn print_summary(
    args: &BakeArgs,
    report: &radbake::pipeline::report::Report,
    start: Instant,
    files: usize,
) {
    if args.verbose {
        for s in &report.stages {
            eprintln!("{:>13}: {:8.3} s", s.stage, s.seconds);
        }
        if let Ok(counts) = serde_json::to_string_pretty(&report.counts) {
            eprintln!("{counts}");
        }
    }
    if args.stats {
        eprint!(
            "{}",
            report.stats_table(radbake::pipeline::report::peak_rss_bytes())
        );
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
            files,
            args.out.display()
        );
    }
}
