//! `radbake preview`: look at a baked `.glb` in a window, or render it
//! offscreen (feature `preview`).

use super::{parse_size, Outcome, ViewArgs};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct PreviewArgs {
    /// The baked scene (`<stem>.baked.glb` from `radbake bake`); with --watch, also a bake's output directory.
    pub scene: PathBuf,
    /// Follow a running bake: show the newest `.baked.glb` or `.snapshot.glb` (`bake --solver progressive --snapshot-every S`) and reload it whenever it changes.
    #[arg(long, conflicts_with = "headless")]
    pub watch: bool,
    /// Render offscreen to --out instead of opening a window.
    #[arg(long, requires = "out")]
    pub headless: bool,
    /// Output PNG of --headless (written atomically).
    #[arg(long, short, requires = "headless")]
    pub out: Option<PathBuf>,
    /// Image (headless) or window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    #[command(flatten)]
    pub at: ViewArgs,
    /// Headless: render N frames and print ms/frame. Window: render N frames, then exit.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Window: after --frames frames, save the last view here (PNG) and exit.
    #[arg(long, requires = "frames", conflicts_with = "headless")]
    pub screenshot: Option<PathBuf>,
    /// First debug view (keys 1–8 switch views in the window).
    #[arg(long, value_enum, default_value = "lit")]
    pub view: radbake::preview::ViewMode,
    /// Bicubic (B-spline) lightmap filtering instead of bilinear.
    #[arg(long)]
    pub bicubic: bool,
    /// Exposure in stops (EV).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Tone map of the HDR values.
    #[arg(long, value_enum, default_value = "aces")]
    pub tone_map: radbake::preview::ToneMap,
    /// A distance field (`radbake sdf --out f.ktx2`, placed by `f.json`) in place of the bake's `sdf.ktx2` (found through `manifest.json` beside the .glb).
    #[arg(long)]
    pub sdf: Option<PathBuf>,
    /// Draw the real-time lights unshadowed even where there is a distance field.
    #[arg(long)]
    pub no_sdf_shadows: bool,
    /// Reach in metres of the distance-field ambient occlusion on probe-lit (dynamic) objects; 0 for none.
    #[arg(long, default_value_t = radbake::preview::options::DFAO_REACH)]
    pub dfao_reach: f32,
    /// A light layer's weight, NAME=W or NAME=R,G,B (repeatable; layers not named keep 1): the lightmaps and probes shown are the layers' weighted sum (docs/layers.md).
    #[arg(long = "layer", value_name = "NAME=W", value_parser = parse_layer_weight)]
    pub layers: Vec<(String, glam::Vec3)>,
    /// A live bake relit for a sun towards `x,y,z` (y up): the pages shown are `radbake relight`'s, the sun drawn there (docs/live.md).
    #[arg(long, value_parser = super::parse_vec3, allow_hyphen_values = true)]
    pub sun_direction: Option<[f32; 3]>,
    /// With --sun-direction or --live: the sun's irradiance `r,g,b` in W/m² [default: as baked].
    #[arg(long, value_parser = super::parse_rgb)]
    pub sun_irradiance: Option<[f32; 3]>,
    /// With --sun-direction or --live: the sky's radiance `r,g,b` (a live bake's uniform sky) [default: as baked].
    #[arg(long, value_parser = super::parse_rgb)]
    pub sky: Option<[f32; 3]>,
    /// Draw the baked light alone: no real-time lights (modes `indirect`, `realtime`, `live`).
    #[arg(long)]
    pub no_realtime_lights: bool,
    /// Window: turn a live bake's sun with the arrow keys (←/→ azimuth, ↑/↓ elevation), its bounce light re-solved live; the update time in the title.
    #[arg(long)]
    pub live: bool,
    /// Height (world y) of the sdf view's slice plane [default: none, under the field's box].
    #[arg(long, allow_negative_numbers = true)]
    pub sdf_slice: Option<f32>,
}

pub fn run(args: &PreviewArgs) -> Outcome {
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
            sdf_shadows: !args.no_sdf_shadows,
            dfao_reach: args.dfao_reach,
            sdf_slice: args.sdf_slice,
            realtime_lights: !args.no_realtime_lights,
        },
        sdf: args.sdf.clone(),
        watch: args.watch,
        layers: args.layers.clone(),
        sun: sun(args)?,
        live: args.live,
    };
    radbake::preview::run(&opts).map_err(|e| {
        let code = match e.downcast_ref::<radbake::Error>() {
            Some(le) if le.is_input_error() => 1,
            _ => 3,
        };
        (code, format!("{e:#}"))
    })
}

/// `--sun-direction` (or with `--live` the baked sun), `--sun-irradiance`
/// and `--sky` as a relight; None without either flag.
fn sun(args: &PreviewArgs) -> Result<Option<radbake::output::relight::Relight>, (u8, String)> {
    let towards = match (args.sun_direction, args.live) {
        (Some(d), _) => glam::Vec3::from_array(d),
        (None, true) => radbake::preview::live::baked_direction(&args.scene)
            .map_err(|e| (1, format!("{e:#}")))?,
        (None, false) => {
            if args.sun_irradiance.is_some() || args.sky.is_some() {
                return Err((
                    2,
                    "--sun-irradiance and --sky relight a live bake: give --sun-direction or --live".into(),
                ));
            }
            return Ok(None);
        }
    };
    Ok(Some(radbake::output::relight::Relight {
        sun_direction: towards,
        sun_irradiance: args.sun_irradiance.map(glam::Vec3::from_array),
        sky: args.sky.map(glam::Vec3::from_array),
        weights: Vec::new(),
    }))
}

/// `--layer`'s value ([`radbake::output::combine::parse_weight`]).
fn parse_layer_weight(pair: &str) -> Result<(String, glam::Vec3), String> {
    radbake::output::combine::parse_weight(pair).map_err(|e| e.to_string())
}
