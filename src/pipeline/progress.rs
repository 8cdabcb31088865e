//! Progress reporting: the library calls a [`Progress`] sink; the binary
//! implements it with `indicatif` bars (hidden when stderr is no terminal).

/// Receives stage starts, advances and ends. Called from worker threads.
pub trait Progress: Sync {
    /// A stage begins; `total` is its unit count (0: unknown).
    fn begin(&self, _stage: &str, _total: u64) {}
    /// `n` more units of the current stage are done.
    fn advance(&self, _n: u64) {}
    /// The current stage ended.
    fn end(&self) {}
    /// A named figure of the current stage, its latest value (the
    /// progressive solve's `unshot`: the unshot power left, a fraction of
    /// the initial).
    fn figure(&self, _name: &str, _value: f64) {}
    /// How often (seconds) this sink wants lightmaps of a solve in
    /// progress ([`Progress::snapshot`]); `None` (the default): never.
    fn snapshot_every(&self) -> Option<f64> {
        None
    }
    /// Lightmaps of the progressive solve as it stands, with the ambient
    /// term for the light not yet shot (Cohen et al. 1988), no final
    /// gather: called about every [`Progress::snapshot_every`] seconds
    /// and once when the solve ends.
    fn snapshot(&self, _snapshot: &Snapshot) {}
}

/// A progressive solve's lightmaps while it runs ([`Progress::snapshot`]).
pub struct Snapshot<'a> {
    /// The atlas the pages are laid out by.
    pub atlas: &'a crate::layout::atlas::Atlas,
    /// The pages: direct light, the indirect light shot so far, and the
    /// ambient term (irradiance / π, as a bake's lightmaps).
    pub lightmaps: &'a crate::maps::lightmap::Lightmaps,
    /// The unshot power left, a fraction of the initial.
    pub unshot: f64,
    /// Shots fired so far.
    pub shots: u64,
    /// The ambient term added to every texel (irradiance / π, RGB).
    pub ambient: glam::Vec3,
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {}
