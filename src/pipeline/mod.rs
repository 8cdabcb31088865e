//! The bake, read top to bottom as the data flow: [`bake`] calls one stage
//! function per step, and each step's product is a plain, named struct
//! that the next step reads.
//!
//! ```text
//! Scene ─► Atlas ─► Geometry ─► Texels ─► RayCaster ─► Burial ─► Patches ─► TexelLight ─► Maps ─► Probes ─► files
//! scene    atlas    geometry    texels    raycast      burial    patches    transport     maps     probes    output
//! ```
//!
//! Light transport ([`transport`]) is one dispatch over
//! [`Method`](crate::config::Method): radiosity (form factors, direct
//! light, the solve, the final gather; [`radiosity`]), or the path-traced
//! and photon-mapped references. Every method returns the same
//! [`TexelLight`]. The lightmap stage ([`maps`]) turns it into pages (and
//! the SH and AO pages); [`summary`] turns a [`Bake`] into the report.

pub mod first_pass;
pub mod incremental;
pub mod layered;
pub mod live;
pub mod log;
pub mod maps;
pub mod progress;
pub mod radiosity;
pub mod report;
pub mod shard;
pub mod snapshot;
pub mod summary;
pub mod texel_light;
pub mod transport;

use crate::config::BakeConfig;
use crate::error::Result;
use crate::layout::atlas::{self, Atlas};
use crate::layout::burial::Burial;
use crate::layout::geometry::Geometry;
use crate::layout::patches::{self, Patches};
use crate::layout::texels::{self, Texels};
use crate::maps::shadowmask::Shadowmask;
use crate::pipeline::progress::Progress;
use crate::pipeline::report::StageTime;
use crate::probes::{self, Probes};
use crate::raycast::RayCaster;
use crate::scene::Scene;
use crate::surface::burial;
use crate::surface::Surfaces;
use log::Log;
pub use maps::Maps;
pub use texel_light::{PatchLight, Rays, TexelLight};

/// Everything a bake produced, stage by stage.
pub struct Bake<'s> {
    /// The input scene.
    pub scene: &'s Scene,
    /// Effective settings.
    pub config: BakeConfig,
    /// Lightmap atlas.
    pub atlas: Atlas,
    /// World triangles.
    pub geometry: Geometry,
    /// Lightmap texels.
    pub texels: Texels,
    /// Patches.
    pub patches: Patches,
    /// Burial planes and each texel's exposed fraction.
    pub burial: Burial,
    /// Light transport's product: the light per texel as it arrived (before
    /// invalid texels are filled), validity, ray counts.
    pub transport: TexelLight,
    /// Lightmap pages (and SH, AO pages), seam counters.
    pub maps: Maps,
    /// Shadowmask pages and channels (`None` without shadowmask lights).
    pub shadowmask: Option<Shadowmask>,
    /// Light probes (`None` with `probes = false`).
    pub probes: Option<Probes>,
    /// The signed distance field (`None` with `sdf = 0`).
    pub sdf: Option<crate::sdf::Sdf>,
    /// The light layers (`None`: one lightmap of every light; see
    /// [`crate::scene::layers`]). Their pages are [`Maps::layers`], their
    /// probes [`Probes::layers`].
    pub layers: Option<crate::scene::layers::Layers>,
    /// What the run time re-solves the live lights' bounce light from
    /// (`live.bin`; `None` without live lights; see [`live`]).
    pub live: Option<radbake_live::LiveData>,
    /// Wall time per stage.
    pub stages: Vec<StageTime>,
    /// Non-fatal problems.
    pub warnings: Vec<String>,
}

/// Bakes `scene` with `config`, reporting to `progress`.
///
/// # Errors
/// [`Error::Config`](crate::Error::Config) for settings out of range,
/// [`Error::Unwrap`](crate::Error::Unwrap) when the atlas can't be built,
/// [`Error::Limit`](crate::Error::Limit) for a singular dense solve.
pub fn bake<'s>(
    scene: &'s Scene,
    config: &BakeConfig,
    progress: &dyn Progress,
) -> Result<Bake<'s>> {
    bake_with(
        scene,
        config,
        progress,
        &crate::pipeline::shard::Sharding::whole(),
    )
}

/// [`bake`] as one job of a sharded bake ([`crate::pipeline::shard`]): the sliced
/// stages compute, write or read their slices as `shard` says, and a job
/// whose part is written stops there with
/// [`Error::ShardDone`](crate::Error::ShardDone).
///
/// # Errors
/// As [`bake`], and [`Error::Shard`](crate::Error::Shard) for a slice
/// file that is missing or bad.
pub fn bake_with<'s>(
    scene: &'s Scene,
    config: &BakeConfig,
    progress: &dyn Progress,
    shard: &crate::pipeline::shard::Sharding,
) -> Result<Bake<'s>> {
    check_inputs(scene, config)?;
    // The sky map is read (and refused) before any work is done.
    let sky = config.load_sky()?;
    // A uniform sky in a live bake: its own layer, so its colour can change.
    let config = &live::effective_config(scene, config, &sky);
    live::check(scene, config, shard)?;
    let layers = crate::scene::layers::resolve(scene, config, sky.is_black())?;
    if layers.is_some() {
        layered::check(config, shard, false)?;
    }
    let mut log = Log::new(progress, input_warnings(scene));

    log.begin("unwrap", 0);
    let atlas = shard.prepared("atlas", || atlas::unwrap(scene, config))?;
    log.warnings.extend(atlas.warnings.iter().cloned());
    log.end("unwrap");

    log.begin("texels", 0);
    let geometry = Geometry::new(scene, &atlas);
    let texels = shard.prepared("texels", || Ok(texels::rasterize(scene, &atlas, &geometry)))?;
    log.end("texels");

    log.begin("bvh", 0);
    let rays = RayCaster::new(scene, &geometry);
    log.end("bvh");

    let burial = shard.prepared("burial", || {
        Ok(burial_planes(
            scene, &geometry, &texels, &rays, config, &mut log,
        ))
    })?;

    log.begin("patches", 0);
    let texel_area: Vec<f32> = scene
        .instances
        .iter()
        .map(|i| (atlas.texels_per_meter * i.texel_scale).powi(-2))
        .collect();
    let patches = shard.prepared("patches", || {
        Ok(patches::build(
            &texels,
            &burial,
            config.patch_texels,
            &texel_area,
        ))
    })?;
    log.end("patches");
    shard.checkpoint(0, false)?;

    let surfaces = Surfaces {
        scene,
        geometry: &geometry,
        texels: &texels,
        patches: &patches,
        rays: &rays,
        burial: &burial,
    };
    let light = transport::run(
        &surfaces,
        &atlas,
        config,
        (&sky, layers.as_ref()),
        &mut log,
        shard,
    )?;
    // A phase-2 job stops here even where nothing was sliced (no gather).
    shard.checkpoint(2, false)?;

    log.begin("lightmaps", 0);
    let maps = maps::build(&surfaces, atlas.page_count, &light, config);
    log.end("lightmaps");

    let shadowmask = shadowmask(&surfaces, atlas.page_count, &light.valid, config, &mut log);

    let probes = config.probes.then(|| {
        log.begin("probes", 0);
        let progress = log.progress();
        let inputs = probes::Inputs {
            s: &surfaces,
            texel_values: &maps.lightmaps.texel_values,
            mixed: &light.mixed,
            specs: &scene.probe_volumes,
            sky: &sky,
        };
        // Each light layer's probes: the same rays, read for its share of
        // the lights and of the lightmap.
        let layer_inputs: Vec<probes::LayerInputs> = match &layers {
            Some(l) => (maps.layers.iter().zip(&light.layers).enumerate())
                .map(|(k, (lm, lt))| probes::LayerInputs {
                    texel_values: &lm.texel_values,
                    mixed: &lt.mixed,
                    mask: crate::light::lights::Mask::of_layer(l, scene, k),
                })
                .collect(),
            None => Vec::new(),
        };
        let p = probes::bake_layers(&inputs, &layer_inputs, config, &|n| progress.advance(n));
        log.end("probes");
        p
    });
    if let Some(p) = &probes {
        log.warnings.extend(probe_warnings(p));
    }

    let live = match &layers {
        Some(l) => live::build(
            &surfaces,
            (config, &sky, l),
            (&light, probes.as_ref()),
            atlas.page_count,
            &mut log,
        )?,
        None => None,
    };

    let sdf = (config.sdf > 0).then(|| {
        log.begin("sdf", 0);
        let field = sdf_stage(scene, &geometry, &rays, config);
        log.end("sdf");
        field
    });

    Ok(Bake {
        scene,
        config: config.clone(),
        atlas,
        geometry,
        texels,
        patches,
        burial,
        transport: light,
        maps,
        shadowmask,
        probes,
        sdf,
        layers,
        live,
        stages: log.stages,
        warnings: log.warnings,
    })
}

/// The settings and the scene together, refused before any work: the
/// settings' own checks, the light modes against the scene's lights, at
/// most [`crate::maps::shadowmask::MAX_LIGHTS`] shadowmask lights, and probe
/// volumes where the distance field is to cover them.
fn check_inputs(scene: &Scene, config: &BakeConfig) -> Result<()> {
    config.validate()?;
    config.light_modes.check(scene)?;
    let masked = crate::maps::shadowmask::lights(&scene.lights).len();
    if masked > crate::maps::shadowmask::MAX_LIGHTS {
        return Err(crate::Error::Config {
            key: "light_modes".into(),
            message: format!(
                "{masked} shadowmask lights, above the limit of {}; make the others indirect",
                crate::maps::shadowmask::MAX_LIGHTS
            ),
        });
    }
    if config.sdf > 0
        && config.sdf_bounds == crate::config::SdfBounds::ProbeVolumes
        && scene.probe_volumes.is_empty()
    {
        return Err(crate::Error::Config {
            key: "sdf_bounds".into(),
            message: "probe-volumes: the scene has no probe volume (a node with extras.radbake.probe_volume); use \"scene\"".into(),
        });
    }
    Ok(())
}

/// The signed distance field over the scene's bounds or its probe
/// volumes' ([`crate::sdf`]), at `config.sdf` voxels along the longest
/// side.
fn sdf_stage(
    scene: &Scene,
    geometry: &Geometry,
    rays: &RayCaster,
    config: &BakeConfig,
) -> crate::sdf::Sdf {
    let bounds = crate::sdf::bounds(scene, geometry, config.sdf_bounds)
        .unwrap_or((glam::Vec3::ZERO, glam::Vec3::ONE));
    let settings = crate::sdf::Settings {
        voxel: crate::sdf::voxel_for_resolution(bounds, config.sdf),
        band: None,
    };
    crate::sdf::bake_over(scene, geometry, rays, bounds, settings)
}

impl<'s> Bake<'s> {
    /// What the light stages read of this bake, over ray caster `rays`
    /// (built over [`Bake::geometry`]): for running a stage again, in
    /// tests, benchmarks and examples.
    pub fn surfaces<'a>(&'a self, rays: &'a RayCaster) -> Surfaces<'a>
    where
        's: 'a,
    {
        Surfaces {
            scene: self.scene,
            geometry: &self.geometry,
            texels: &self.texels,
            patches: &self.patches,
            rays,
            burial: &self.burial,
        }
    }

    /// Radiosity's patch-level products (`None` for the reference methods).
    pub fn patch_light(&self) -> Option<&PatchLight> {
        self.transport.patch_light.as_ref()
    }
}

/// The burial stage ([`crate::surface::burial`]), or no planes where
/// `config.burial_planes` is off.
fn burial_planes(
    scene: &Scene,
    geometry: &Geometry,
    texels: &Texels,
    rays: &RayCaster,
    config: &BakeConfig,
    log: &mut Log,
) -> Burial {
    if !config.burial_planes {
        return Burial::open();
    }
    log.begin("burial", 0);
    let open = Burial::open();
    // The stage reads no patches (they are built from its regions).
    let patches = Patches::default();
    let s = Surfaces {
        scene,
        geometry,
        texels,
        patches: &patches,
        rays,
        burial: &open,
    };
    let burial = burial::compute(
        &s,
        config.seed,
        crate::surface::validity::VALIDITY_RAYS,
        config.backface_tolerance,
    );
    log.end("burial");
    burial
}

/// The shadowmask stage ([`crate::maps::shadowmask`]) where the scene has
/// shadowmask lights; a light without a channel is warned about.
fn shadowmask(
    s: &Surfaces,
    page_count: u32,
    valid: &[bool],
    config: &BakeConfig,
    log: &mut Log,
) -> Option<Shadowmask> {
    if crate::maps::shadowmask::lights(&s.scene.lights).is_empty() {
        return None;
    }
    log.begin("shadowmask", 0);
    let rings = (
        crate::maps::lightmap::fill_rings(config.patch_texels),
        2 * config.padding,
    );
    let mask = crate::maps::shadowmask::bake(s, valid, page_count, rings, config.seed);
    if let Some(m) = &mask {
        log.warnings.extend(m.warnings(&s.scene.lights));
    }
    log.end("shadowmask");
    mask
}

/// What the probe stage has to say: a budget that coarsened the spacing
/// of the user's `probe_volume` boxes (the automatic box is sized by the
/// budget by design), and invalid probes no valid neighbour could fill.
fn probe_warnings(p: &Probes) -> Vec<String> {
    let mut w = Vec::new();
    if p.placed && p.coarsened > 1.0 {
        w.push(format!(
            "probe_budget: the probe spacing was coarsened {:.2}× to fit {} probes",
            p.coarsened,
            p.len()
        ));
    }
    if p.unfilled > 0 {
        w.push(format!(
            "probes: {} probes inside solids have no valid neighbour and stay black",
            p.unfilled
        ));
    }
    w
}

/// Warnings about the input itself: the importer's, and a scene that
/// nothing lights.
fn input_warnings(scene: &Scene) -> Vec<String> {
    let mut warnings = scene.warnings.clone();
    for inst in scene.instances.iter().filter(|i| !i.cast_shadows) {
        let mesh = &scene.meshes[inst.mesh as usize];
        let emissive = mesh
            .triangle_material
            .iter()
            .any(|&m| scene.materials[m as usize].is_emissive());
        if emissive {
            warnings.push(format!(
                "node `{}`: cast_shadows = false and emissive: no ray can meet it, so its emission is not baked",
                inst.node
            ));
        }
    }
    if !scene.has_emitters() {
        warnings
            .push("the scene has no emissive surface and no light: the lightmaps are black".into());
    }
    warnings
}
