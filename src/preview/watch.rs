//! `preview --watch`: follow a bake while it runs. `radbake bake --solver
//! progressive --snapshot-every S` writes `<stem>.snapshot.glb` every S
//! seconds (the solve as it stands, with the ambient term for the light
//! not yet shot) and, at the end, `<stem>.baked.glb`, removing the
//! snapshot. The watcher names the newest of these files whenever it
//! changes, and the window reloads it. Every file is written by renaming
//! a finished temporary into place, so a reload never reads half a file.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Suffixes of the files a bake writes that the preview can show.
const SUFFIXES: [&str; 2] = [".baked.glb", ".snapshot.glb"];

/// What was last seen: the file, its modification time and length.
type Seen = (PathBuf, SystemTime, u64);

/// Watches a bake directory, or one `.baked.glb` and its snapshot.
pub struct Watch {
    target: PathBuf,
    seen: Option<Seen>,
}

impl Watch {
    /// Watches `target`: a bake's output directory, or a `.baked.glb`
    /// (then also the `.snapshot.glb` beside it).
    pub fn new(target: &Path) -> Watch {
        Watch {
            target: target.to_path_buf(),
            seen: None,
        }
    }

    /// What is watched.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// The files that count, present or not.
    fn candidates(&self) -> Vec<PathBuf> {
        if self.target.is_dir() {
            let Ok(dir) = std::fs::read_dir(&self.target) else {
                return Vec::new();
            };
            let mut files: Vec<PathBuf> = dir
                .flatten()
                .map(|e| e.path())
                .filter(|p| {
                    let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
                    name.is_some_and(|n| SUFFIXES.iter().any(|s| n.ends_with(s)))
                })
                .collect();
            files.sort();
            return files;
        }
        let name = self.target.to_string_lossy();
        match name.strip_suffix(SUFFIXES[0]) {
            Some(stem) => vec![
                self.target.clone(),
                PathBuf::from(format!("{stem}{}", SUFFIXES[1])),
            ],
            None => vec![self.target.clone()],
        }
    }

    /// The newest file there now (on equal times the final `.baked.glb`,
    /// then the first by name).
    pub fn newest(&self) -> Option<Seen> {
        let mut best: Option<Seen> = None;
        for path in self.candidates() {
            let Ok(meta) = std::fs::metadata(&path) else {
                continue;
            };
            let Ok(time) = meta.modified() else {
                continue;
            };
            let better = match &best {
                None => true,
                Some((p, t, _)) => time > *t || (time == *t && !is_final(p) && is_final(&path)),
            };
            if better {
                best = Some((path, time, meta.len()));
            }
        }
        best
    }

    /// The newest file, if it differs from the one last returned (another
    /// file, or the same one rewritten).
    pub fn changed(&mut self) -> Option<PathBuf> {
        let now = self.newest()?;
        if self.seen.as_ref() == Some(&now) {
            return None;
        }
        let path = now.0.clone();
        self.seen = Some(now);
        Some(path)
    }
}

fn is_final(p: &Path) -> bool {
    p.to_string_lossy().ends_with(SUFFIXES[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn touch(p: &Path, bytes: &[u8], at: SystemTime) {
        std::fs::write(p, bytes).unwrap();
        std::fs::File::options()
            .write(true)
            .open(p)
            .unwrap()
            .set_modified(at)
            .unwrap();
    }

    /// A directory: nothing until a file appears; the snapshot while it is
    /// the newest, each rewrite once, then the final `.glb`; other files
    /// are ignored.
    #[test]
    fn follows_snapshots_then_the_final_bake() {
        let dir = std::env::temp_dir().join(format!("radbake-watch-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
        let mut w = Watch::new(&dir);
        assert_eq!(w.changed(), None);
        touch(&dir.join("report.json"), b"{}", t0);
        assert_eq!(w.changed(), None);
        let snap = dir.join("box.snapshot.glb");
        touch(&snap, b"one", t0);
        assert_eq!(w.changed().as_deref(), Some(snap.as_path()));
        assert_eq!(w.changed(), None, "unchanged: no reload");
        touch(&snap, b"two", t0 + Duration::from_secs(2));
        assert_eq!(w.changed().as_deref(), Some(snap.as_path()));
        let fin = dir.join("box.baked.glb");
        touch(&fin, b"final", t0 + Duration::from_secs(2));
        assert_eq!(
            w.changed().as_deref(),
            Some(fin.as_path()),
            "ties go to the final file"
        );
        std::fs::remove_file(&snap).unwrap();
        assert_eq!(w.changed(), None);
        // A .glb named directly also watches its snapshot.
        let mut one = Watch::new(&fin);
        assert_eq!(one.changed().as_deref(), Some(fin.as_path()));
        touch(&snap, b"three", t0 + Duration::from_secs(5));
        assert_eq!(one.changed().as_deref(), Some(snap.as_path()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
