//! The Cornell box's outputs at the defaults, pinned byte for byte: a
//! restructuring of the code (or a change of a dependency) that moves one
//! bit of the lightmap, the baked `.glb` or the manifest fails here.
//!
//! The hashes live in `tests/fixtures/cornell_outputs.blake3`. A change
//! that means to move the outputs re-pins them with
//! `RADBAKE_REPIN=1 cargo test --release --test pinned`, and says why in
//! its commit.

mod common;

use common::{scene_path, temp_dir};
use std::path::Path;
use std::process::Command;

const PINS: &str = "tests/fixtures/cornell_outputs.blake3";
const FILES: [&str; 3] = ["lightmap_0.exr", "cornell_box.baked.glb", "manifest.json"];

#[test]
fn cornell_outputs_are_pinned() {
    let out = temp_dir("pinned_cornell");
    let run = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(["bake", "-q", "--force", "--out"])
        .arg(&out)
        .arg(scene_path("cornell_box.gltf"))
        .output()
        .expect("radbake runs");
    assert!(
        run.status.success(),
        "bake failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let got: String = FILES
        .iter()
        .map(|f| {
            let bytes = std::fs::read(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
            format!("{}  {f}\n", blake3::hash(&bytes).to_hex())
        })
        .collect();
    let pins = Path::new(env!("CARGO_MANIFEST_DIR")).join(PINS);
    if std::env::var_os("RADBAKE_REPIN").is_some() {
        std::fs::write(&pins, &got).expect("pins written");
    }
    let want = std::fs::read_to_string(&pins).unwrap_or_else(|e| panic!("{PINS}: {e}"));
    assert_eq!(
        want, got,
        "the Cornell outputs moved (want, got); if that is meant, re-pin with RADBAKE_REPIN=1"
    );
}
