//! Incremental bakes for build systems: a content hash (BLAKE3) of
//! everything a bake depends on — radbake's version, the effective settings,
//! the glTF document and every buffer and image it uses — is stored in the
//! output folder as `bake.hash`, written last. A later bake with the same
//! hash and all its outputs present has nothing to do.

use crate::config::BakeConfig;
use crate::error::Result;
use crate::scene::Scene;
use std::path::Path;

/// The file holding the hash in the output folder.
pub const HASH_FILE: &str = "bake.hash";

/// Hex BLAKE3 hash of what a bake of `scene` with `config` depends on.
pub fn content_hash(scene: &Scene, config: &BakeConfig) -> String {
    let mut h = blake3::Hasher::new();
    let mut field = |label: &str, bytes: &[u8]| {
        h.update(label.as_bytes());
        h.update(&(bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    field("version", env!("CARGO_PKG_VERSION").as_bytes());
    field("config", &serde_json::to_vec(config).unwrap_or_default());
    // The sky map's bytes (a missing file hashes as nothing: the bake
    // then fails on it, naming it).
    if let Some(map) = &config.sky_map {
        field("sky_map", &std::fs::read(map).unwrap_or_default());
    }
    if let Some(src) = &scene.source {
        field("json", &serde_json::to_vec(&src.json).unwrap_or_default());
        for b in &src.buffers {
            field("buffer", b);
        }
        for (bytes, mime) in src.images.iter().flatten() {
            field("image", bytes);
            field("mime", mime.as_bytes());
        }
    }
    h.finalize().to_hex().to_string()
}

/// True when `out_dir` holds a finished bake with this `hash` and every file
/// in `outputs` exists.
pub fn up_to_date(out_dir: &Path, hash: &str, outputs: &[&str]) -> bool {
    std::fs::read_to_string(out_dir.join(HASH_FILE)).is_ok_and(|h| h.trim() == hash)
        && outputs.iter().all(|f| out_dir.join(f).is_file())
}

/// Records `hash` as the finished bake's (atomically).
///
/// # Errors
/// [`crate::Error::Io`].
pub fn record(out_dir: &Path, hash: &str) -> Result<()> {
    crate::util::files::write_bytes_atomic(&out_dir.join(HASH_FILE), format!("{hash}\n").as_bytes())
}
