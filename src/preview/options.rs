//! What `radbake preview` is asked for: the debug view, tone map and
//! exposure ([`Settings`]), the first viewpoint, and the options of a run.

use super::camera::Camera;
use super::model::Model;
use anyhow::{anyhow, Result};
use glam::Vec3;
use std::path::PathBuf;

/// What the fragment shader shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[repr(u32)]
pub enum ViewMode {
    /// Base colour × lightmap + emissive, tone mapped (dynamic nodes: base
    /// colour × the probes' irradiance / π + emissive).
    Lit = 0,
    /// The lightmap alone (irradiance / π; the probes' on dynamic nodes),
    /// tone mapped.
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
    /// The lit scene plus a sphere at each light probe, shaded by the
    /// probe's irradiance / π for the sphere's normal (white albedo);
    /// probes found inside solids are red (needs `probes.json` beside the
    /// `.glb`).
    Probes = 7,
    /// The level's signed distance field alone (needs `bake --sdf N`, or
    /// `--sdf <file.ktx2>`): its sphere-traced surface, and the field on a
    /// horizontal slice plane (PageUp / PageDown move it).
    Sdf = 8,
}

impl ViewMode {
    /// All views, in key order (1–9).
    pub const ALL: [ViewMode; 9] = [
        ViewMode::Lit,
        ViewMode::Lightmap,
        ViewMode::Albedo,
        ViewMode::Checker,
        ViewMode::Charts,
        ViewMode::Patches,
        ViewMode::Invalid,
        ViewMode::Probes,
        ViewMode::Sdf,
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
            ViewMode::Probes => "light probes",
            ViewMode::Sdf => "distance field",
        }
    }
}

/// The tone map applied to HDR values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[repr(u32)]
pub enum ToneMap {
    /// ACES filmic (Stephen Hill's fit).
    Aces = 0,
    /// None: values clamped to [0, 1].
    None = 1,
}

/// The default reach of the distance-field ambient occlusion (metres):
/// contact occlusion, finer than the probes' spacing.
pub const DFAO_REACH: f32 = 1.0;

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
    /// With a distance field: the real-time lights' shadows sphere-traced
    /// through it (else they are drawn unshadowed).
    pub sdf_shadows: bool,
    /// With a distance field: the reach (metres) of the distance-field
    /// ambient occlusion on probe-lit surfaces; 0 for none.
    pub dfao_reach: f32,
    /// The sdf view's slice height (world y); None: a voxel below the
    /// field's box (no slice; PageUp raises it).
    pub sdf_slice: Option<f32>,
    /// Draw the lights an engine draws in real time (modes `indirect`,
    /// `realtime`, `live`); off: the baked light alone (lightmaps, probes,
    /// emission).
    pub realtime_lights: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            view: ViewMode::Lit,
            bicubic: false,
            exposure_ev: 0.0,
            tone_map: ToneMap::Aces,
            sdf_shadows: true,
            dfao_reach: DFAO_REACH,
            sdf_slice: None,
            realtime_lights: true,
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
    /// A distance field to use in place of the bake's (`radbake sdf
    /// --out`'s `.ktx2`, placed by its `.json` sidecar).
    pub sdf: Option<PathBuf>,
    /// Window: follow a running bake ([`super::watch`]): `scene` may be
    /// the bake's directory; the newest `.baked.glb` or `.snapshot.glb`
    /// is shown and reloaded whenever it changes.
    pub watch: bool,
    /// A light-layered bake's layer weights (`--layer NAME=R,G,B`; layers
    /// not named keep 1): the pages and probes shown are the layers'
    /// weighted sum ([`super::model::Model::load_weighted`]).
    pub layers: Vec<(String, glam::Vec3)>,
    /// A live bake relit for this sun (`--sun-direction`, docs/live.md):
    /// the pages shown are `radbake relight`'s.
    pub sun: Option<crate::output::relight::Relight>,
    /// Window: turn the live bake's sun on the arrow keys, re-solved live
    /// ([`super::live::LiveView`]).
    pub live: bool,
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
