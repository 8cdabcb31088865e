//! Live radiosity at run time (radbake's `docs/live.md`): in a bake with a
//! live sun (`radbake bake --live`), turn that sun's `DirectionalLight`
//! (its `Transform`) or change its colour or illuminance, and the bounce
//! light follows.
//!
//! The bake's manifest lists `live.bin` (read once, at load): the patches'
//! form factors, albedo and per-direction sun visibility. When the sun
//! light's direction or colour × illuminance changes, the bake's
//! recombination task ([`crate::layers`], on Bevy's
//! [`bevy::tasks::AsyncComputeTaskPool`]: the frame never waits for it)
//! re-solves the radiosity system from the previous solution
//! ([`radbake_live::Live::update`]) and rebuilds the live layer's pages;
//! the lightmap pages become Σₖ wₖ × layer k with the live layer's share
//! replaced by the new solution. Bevy draws the sun's direct light itself,
//! as for any `indirect` light.
//!
//! - The sun's irradiance follows the light: the baked irradiance (from
//!   `live.bin`) × the light's linear colour × illuminance over what they
//!   were when the bake was applied, per channel; an untouched light gives
//!   the baked irradiance exactly.
//! - The irradiance volumes follow too, where `live.bin` has the probes'
//!   rays: the live layer's volumes become the baked ones + the ambient
//!   cubes of [`radbake_live::Live::probe_delta`] (the change of the live
//!   layer's probe SH since the baked sun, from the patches the probes
//!   see); without them the volumes keep the live light's bounce as baked.
//! - The sky's colour: weigh its layer (`sky`, a [`crate::RadbakeLayers`]
//!   weight = new sky / baked sky per channel). A weight on the live layer
//!   itself is refused: turn or dim the light instead.

use bevy::prelude::*;
use radbake_live::{Live, LiveData, Solve, Sun};

/// What the last live solve gave, on the bake entity.
#[derive(Component, Clone, Debug, Default)]
pub struct RadbakeLiveApplied {
    /// Towards the sun (unit, y up), as solved.
    pub direction: Vec3,
    /// The sun's irradiance (W/m², linear RGB), as solved.
    pub irradiance: Vec3,
    /// The solve's Jacobi iterations and last relative change.
    pub iterations: u32,
    pub residual: f32,
    /// Milliseconds of the solve and the live pages (on its task).
    pub solve_ms: f32,
    /// How many solves were applied.
    pub generation: u64,
}

/// A bake's live state, part of its recombination job.
pub(crate) struct LiveJob {
    /// The run time; on its task while a solve runs.
    pub solver: Option<Box<Live>>,
    /// The live layer's index among the bake's layers.
    pub layer: usize,
    /// The live light's entity, once found.
    light: Option<Entity>,
    /// Its linear colour × illuminance when first found.
    reference: Vec3,
    /// The baked irradiance (W/m²).
    baked: Vec3,
    /// The sun last solved (or being solved).
    pub solved: Option<Sun>,
    /// The live layer's pages, buffers reused between solves.
    pub pages: Vec<Vec<[f32; 3]>>,
}

impl LiveJob {
    /// The job for `data`, whose live layer is layer `layer`.
    pub fn new(data: &LiveData, layer: usize) -> LiveJob {
        let baked = data
            .header
            .lights
            .first()
            .map_or(Vec3::ZERO, |l| Vec3::from(l.irradiance));
        LiveJob {
            solver: Some(Box::new(Live::new(data.clone()))),
            layer,
            light: None,
            reference: Vec3::ZERO,
            baked,
            solved: None,
            pages: Vec::new(),
        }
    }

    /// The sun as the live light now stands: `None` until the light is
    /// found (the first `DirectionalLight` under `root` whose glTF node is
    /// one of the live layer's `lights`).
    pub fn sun_now(
        &mut self,
        root: Entity,
        lights: &[String],
        (children, parents, names): (&Query<&Children>, &Query<&ChildOf>, &Query<&Name>),
        suns: &Query<(&DirectionalLight, &GlobalTransform)>,
    ) -> Option<Sun> {
        if self.light.is_none() {
            let e = children.iter_descendants(root).find(|&e| {
                suns.contains(e)
                    && parents
                        .get(e)
                        .ok()
                        .and_then(|p| names.get(p.parent()).ok())
                        .is_some_and(|n| lights.iter().any(|l| l == n.as_str()))
            })?;
            let (l, _) = suns.get(e).ok()?;
            self.reference = power(l);
            self.light = Some(e);
        }
        let (l, at) = suns.get(self.light?).ok()?;
        let ratio = Vec3::select(
            self.reference.cmpgt(Vec3::ZERO),
            power(l) / self.reference,
            Vec3::ZERO,
        );
        // A DirectionalLight shines along its −Z: the sun is at +Z.
        let towards = at.back().as_vec3();
        Some(Sun {
            direction: towards.to_array(),
            irradiance: (self.baked * ratio).to_array(),
        })
    }
}

/// A light's linear colour × illuminance.
fn power(l: &DirectionalLight) -> Vec3 {
    let c = l.color.to_linear();
    Vec3::new(c.red, c.green, c.blue) * l.illuminance
}

/// Whether two suns differ enough to solve again: by more than 0.01° or
/// 0.01 % of the irradiance.
pub(crate) fn moved(a: &Sun, b: &Sun) -> bool {
    let (da, db) = (Vec3::from(a.direction), Vec3::from(b.direction));
    let (ia, ib) = (Vec3::from(a.irradiance), Vec3::from(b.irradiance));
    da.angle_between(db) > 1.75e-4 || (ia - ib).abs().max_element() > 1e-4 * ib.max_element()
}

/// What a live solve on its task returns.
pub(crate) struct Solved {
    pub solver: Box<Live>,
    pub sun: Sun,
    pub pages: Vec<Vec<[f32; 3]>>,
    /// Per probe grid, the change of the live layer's volume texels (in
    /// the volume image's layout); `None` without the probes' rays.
    pub volumes: Option<Vec<Vec<[f32; 3]>>>,
    pub result: Result<Solve, String>,
    pub ms: f32,
}

/// Solves `solver` for `sun` and writes the live layer's pages into
/// `pages` (on the recombination task).
pub(crate) fn solve(mut solver: Box<Live>, sun: Sun, mut pages: Vec<Vec<[f32; 3]>>) -> Solved {
    let t = std::time::Instant::now();
    let result = solver
        .update(&[sun])
        .map_err(|e| format!("radbake: live sun: {e}"));
    let mut volumes = None;
    if result.is_ok() {
        solver.write_pages(&mut pages);
        volumes = volume_deltas(&solver);
    }
    Solved {
        solver,
        sun,
        pages,
        volumes,
        result,
        ms: t.elapsed().as_secs_f32() * 1e3,
    }
}

/// Per probe grid, the ambient cubes of the live layer's probe change
/// ([`Live::probe_delta`]) in Bevy 0.19's irradiance-volume layout
/// ([`radbake_live::probes::volume_texel`], as radbake writes
/// `probes_<k>.ktx2`).
fn volume_deltas(solver: &Live) -> Option<Vec<Vec<[f32; 3]>>> {
    let delta = solver.probe_delta()?;
    let grids = solver.data().header.probes.as_ref()?.grids.clone();
    let volumes = grids
        .iter()
        .map(|g| {
            let [sx, sy, sz] = radbake_live::probes::volume_size(g.resolution);
            let mut texels = vec![[0.0f32; 3]; (sx * sy * sz) as usize];
            let [rx, ry, rz] = g.resolution.map(|r| r as usize);
            for i in 0..rx * ry * rz {
                let c = [i % rx, (i / rx) % ry, i / (rx * ry)].map(|v| v as u32);
                let cube = radbake_live::probes::ambient_cube(&delta[g.first as usize + i]);
                for (face, value) in cube.into_iter().enumerate() {
                    texels[radbake_live::probes::volume_texel(g.resolution, c, face)] = value;
                }
            }
            texels
        })
        .collect();
    Some(volumes)
}
