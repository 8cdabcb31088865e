//! Progress of a bake on stderr: indicatif bars (one per stage), or one
//! JSON object per line for build tools.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::Mutex;
use std::time::Instant;

/// indicatif bars, one per stage.
pub struct Bars {
    pub bar: Mutex<Option<ProgressBar>>,
    pub hidden: bool,
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
/// and the stage's latest figures (`radbake::Progress::figure`, e.g. the
/// progressive solve's `"unshot"`), at most every 100 ms, and at each
/// stage's start and end.
pub struct JsonProgress {
    pub state: Mutex<(String, u64, u64, Instant, Instant)>,
    /// The current stage's figures.
    pub figures: Mutex<serde_json::Map<String, serde_json::Value>>,
}

impl JsonProgress {
    fn emit(&self, stage: &str, done: u64, total: u64, started: Instant) {
        let elapsed = started.elapsed().as_secs_f64();
        let eta = if done > 0 && total >= done {
            serde_json::json!(elapsed * (total - done) as f64 / done as f64)
        } else {
            serde_json::Value::Null
        };
        let mut line = serde_json::json!({"stage": stage, "done": done, "total": total, "elapsed": elapsed, "eta": eta});
        for (k, v) in self.figures.lock().expect("progress lock").iter() {
            line[k] = v.clone();
        }
        eprintln!("{line}");
    }
}

impl radbake::Progress for JsonProgress {
    fn begin(&self, stage: &str, total: u64) {
        let now = Instant::now();
        *self.state.lock().expect("progress lock") = (stage.to_owned(), 0, total, now, now);
        self.figures.lock().expect("progress lock").clear();
        self.emit(stage, 0, total, now);
    }
    fn advance(&self, n: u64) {
        let mut s = self.state.lock().expect("progress lock");
        s.1 += n;
        if s.4.elapsed().as_millis() >= 100 {
            s.4 = Instant::now();
            self.emit(&s.0, s.1, s.2, s.3);
        }
    }
    fn figure(&self, name: &str, value: f64) {
        let mut f = self.figures.lock().expect("progress lock");
        f.insert(name.to_owned(), serde_json::json!(value));
    }
    fn end(&self) {
        let s = self.state.lock().expect("progress lock");
        self.emit(&s.0, s.1.max(s.2), s.2, s.3);
    }
}

/// `bake --snapshot-every`: passes everything on to `inner`, and writes
/// each snapshot of the progressive solve to `path` (atomically) for
/// `preview --watch`. A snapshot that cannot be written is counted; the
/// first error becomes a warning in `report.json`.
pub struct SnapshotWriter<'a> {
    pub inner: &'a dyn radbake::Progress,
    pub every: f64,
    pub scene: &'a radbake::scene::Scene,
    pub path: std::path::PathBuf,
    /// (snapshots written, the first error).
    pub outcome: Mutex<(u64, Option<String>)>,
}

impl radbake::Progress for SnapshotWriter<'_> {
    fn begin(&self, stage: &str, total: u64) {
        self.inner.begin(stage, total);
    }
    fn advance(&self, n: u64) {
        self.inner.advance(n);
    }
    fn end(&self) {
        self.inner.end();
    }
    fn figure(&self, name: &str, value: f64) {
        self.inner.figure(name, value);
    }
    fn snapshot_every(&self) -> Option<f64> {
        Some(self.every)
    }
    fn snapshot(&self, s: &radbake::Snapshot) {
        let r = radbake::output::write_snapshot_glb(&self.path, self.scene, s.atlas, s.lightmaps);
        let mut o = self.outcome.lock().expect("snapshot lock");
        match r {
            Ok(()) => {
                o.0 += 1;
                self.inner.figure("snapshots", o.0 as f64);
            }
            Err(e) => {
                o.1.get_or_insert_with(|| format!("snapshot: {e}"));
            }
        }
    }
}
