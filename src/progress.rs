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
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {}
