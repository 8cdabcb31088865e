//! What a bake's stages report to ([`Log`]): progress, the wall time of
//! each stage, and warnings.

use crate::pipeline::progress::Progress;
use crate::pipeline::report::StageTime;
use std::time::Instant;

/// What the stages report to: progress, the wall time of each stage, and
/// warnings.
pub struct Log<'p> {
    progress: &'p dyn Progress,
    start: Instant,
    /// Wall time per stage, in order.
    pub stages: Vec<StageTime>,
    /// Non-fatal problems, in order.
    pub warnings: Vec<String>,
}

impl<'p> Log<'p> {
    /// A log reporting to `progress`, starting with `warnings`.
    pub fn new(progress: &'p dyn Progress, warnings: Vec<String>) -> Self {
        Log {
            progress,
            start: Instant::now(),
            stages: Vec::new(),
            warnings,
        }
    }

    /// Stage `stage` begins, with `total` units of work (0: unknown).
    pub fn begin(&mut self, stage: &str, total: u64) {
        self.start = Instant::now();
        self.progress.begin(stage, total);
    }

    /// Stage `stage` ends: its wall time is recorded.
    pub fn end(&mut self, stage: &str) {
        self.progress.end();
        self.stages.push(StageTime {
            stage: stage.into(),
            seconds: self.start.elapsed().as_secs_f64(),
        });
    }

    /// Where the current stage reports units done.
    pub fn progress(&self) -> &'p dyn Progress {
        self.progress
    }
}
