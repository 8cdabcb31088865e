//! Lightmaps of a progressive solve while it runs (`bake --snapshot-every`,
//! watched by `preview --watch`). Progressive refinement's point is a
//! usable image early (Cohen, Chen, Wallace & Greenberg 1988): each
//! snapshot is the direct light, the indirect light shot so far and the
//! paper's ambient term for the light not yet shot
//! ([`progressive::ambient`]), spread over the texels by the first pass
//! (no final gather, no seam stitching).

use crate::layout::atlas::Atlas;
use crate::maps::lightmap;
use crate::pipeline::progress::{Progress, Snapshot};
use crate::radiosity::solve::progressive::{self, Partial};
use crate::radiosity::solve::System;
use crate::surface::Surfaces;
use glam::Vec3;
use std::time::Instant;

/// Watches a progressive solve for its [`Progress`] sink: the unshot
/// fraction always (the `unshot` figure), lightmaps when the sink asks.
pub struct Snapshots<'a> {
    progress: &'a dyn Progress,
    /// Seconds between snapshots (`None`: figures only).
    every: Option<f64>,
    last: Instant,
    s: &'a Surfaces<'a>,
    atlas: &'a Atlas,
    /// The lightmap's direct light per texel (the baked lights; empty
    /// when no snapshot is wanted).
    direct: Vec<Vec3>,
    dilate: u32,
}

impl<'a> Snapshots<'a> {
    /// `direct` is called only if `progress` wants snapshots.
    pub fn new(
        progress: &'a dyn Progress,
        s: &'a Surfaces<'a>,
        atlas: &'a Atlas,
        direct: impl FnOnce() -> Vec<Vec3>,
        dilate: u32,
    ) -> Self {
        let every = progress
            .snapshot_every()
            .filter(|e| e.is_finite() && *e >= 0.0);
        Snapshots {
            progress,
            every,
            last: Instant::now(),
            s,
            atlas,
            direct: if every.is_some() {
                direct()
            } else {
                Vec::new()
            },
            dilate,
        }
    }

    /// Reports `p`'s unshot fraction and, when a snapshot is due (and at
    /// the end), its lightmaps.
    pub fn observe(&mut self, sys: &System, p: &Partial) {
        self.progress.figure("unshot", p.unshot_fraction);
        let Some(every) = self.every else {
            return;
        };
        if !p.done && p.shots > 0 && self.last.elapsed().as_secs_f64() < every {
            return;
        }
        let ambient = progressive::ambient(sys, p.unshot);
        let indirect: Vec<Vec3> = (p.irradiance.iter().zip(sys.direct))
            .map(|(h, d)| *h - *d + ambient)
            .collect();
        let (texels, patches) = (self.s.texels, self.s.patches);
        let values = lightmap::first_pass(texels, patches, &self.direct, &indirect);
        let lightmaps = lightmap::build(texels, values, self.atlas.page_count, self.dilate);
        self.progress.snapshot(&Snapshot {
            atlas: self.atlas,
            lightmaps: &lightmaps,
            unshot: p.unshot_fraction,
            shots: p.shots,
            ambient,
        });
        self.last = Instant::now();
    }
}
