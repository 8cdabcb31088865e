//! Killed and interrupted bakes, and fuzzing of the importer and a tiny bake
//! with mutated glTF and GLB files.

mod common;

use common::*;
use proptest::prelude::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bake_cmd(scene: &Path, out: &Path, seed: u32) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_radbake"));
    c.args([
        "bake",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--force",
        "-q",
        "--seed",
        &seed.to_string(),
    ]);
    c.stdout(Stdio::null()).stderr(Stdio::piped());
    c
}

/// Every output file present decodes completely (no truncated file).
fn assert_complete(out: &Path) {
    for e in std::fs::read_dir(out).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue; // a temporary of a killed writer, never a named output
        }
        let path = e.path();
        let bytes = std::fs::read(&path).unwrap();
        if name.ends_with(".json") {
            serde_json::from_slice::<serde_json::Value>(&bytes)
                .unwrap_or_else(|e| panic!("{name} truncated: {e}"));
        } else if name.ends_with(".png") {
            image::load_from_memory(&bytes).unwrap_or_else(|e| panic!("{name} truncated: {e}"));
        } else if name.ends_with(".exr") {
            exr::prelude::read_first_rgba_layer_from_file(
                &path,
                |r, _| vec![0f32; r.width() * r.height()],
                |_, _, _: (f32, f32, f32, f32)| {},
            )
            .unwrap_or_else(|e| panic!("{name} truncated: {e}"));
        } else if name.ends_with(".glb") {
            radbake::scene::load(&path, &Default::default())
                .unwrap_or_else(|e| panic!("{name} truncated: {e}"));
        } else if name == "bake.hash" {
            assert_eq!(bytes.len(), 65, "bake.hash truncated");
        }
    }
}

/// SIGKILL at many points of a bake (some while it writes): every file left
/// is complete; the next bake removes the temporaries and finishes.
#[test]
fn killed_bakes_never_leave_truncated_files() {
    let dir = temp_dir("kill");
    let out = dir.join("out");
    let scene = scene_path("cornell_box.gltf");
    // A complete previous bake, and how long one takes.
    let t = Instant::now();
    assert!(bake_cmd(&scene, &out, 1).status().unwrap().success());
    let full = t.elapsed();
    for k in 0..12u32 {
        let delay = full.mul_f64(0.55 + 0.05 * k as f64);
        let mut child = bake_cmd(&scene, &out, 2 + k).spawn().unwrap();
        std::thread::sleep(delay);
        let _ = child.kill(); // SIGKILL on Unix
        let _ = child.wait();
        assert_complete(&out);
    }
    assert!(bake_cmd(&scene, &out, 99).status().unwrap().success());
    assert_complete(&out);
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporaries left after a finished bake: {leftovers:?}"
    );
}

/// Ctrl-C (SIGINT) stops a bake within a second, exit code 130, and leaves
/// no temporary of its own.
#[cfg(unix)]
#[test]
fn ctrl_c_stops_within_a_second() {
    let dir = temp_dir("sigint");
    let out = dir.join("out");
    let scene = scene_path("furnace_box.gltf"); // a few seconds of work
    let mut child = bake_cmd(&scene, &out, 1).spawn().unwrap();
    std::thread::sleep(Duration::from_millis(400));
    let sent = Instant::now();
    assert!(Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            sent.elapsed() < Duration::from_secs(1),
            "still running 1 s after Ctrl-C"
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    assert_eq!(status.code(), Some(130));
    if out.is_dir() {
        let pid = child.id().to_string();
        for e in std::fs::read_dir(&out).unwrap().flatten() {
            assert!(
                !e.file_name()
                    .to_string_lossy()
                    .contains(&format!(".{pid}.tmp")),
                "temporary left: {:?}",
                e.path()
            );
        }
    }
}

/// A mesh of 10⁷ instanced triangles (10⁴ triangles drawn by 10³ nodes)
/// with a 1 GB memory limit is refused with an estimate before its geometry
/// is read, instead of running out of memory.
#[test]
fn memory_limit_refuses_with_an_estimate() {
    let dir = temp_dir("memlimit");
    let mut b = GltfBuilder::default();
    let n = 10_000u32;
    let p: Vec<[f32; 3]> = (0..n + 2)
        .map(|i| [i as f32 * 0.01, (i % 2) as f32 * 0.01, 0.0])
        .collect();
    let idx: Vec<u32> = (0..n).flat_map(|i| [i, i + 1, i + 2]).collect();
    let m = b.mesh(&p, &idx, None);
    let mut doc = b.json();
    doc["nodes"] = serde_json::Value::Array(
        (0..1000)
            .map(|i| serde_json::json!({"mesh": m, "translation": [0.0, i as f32, 0.0]}))
            .collect(),
    );
    doc["scenes"][0]["nodes"] = serde_json::json!((0..1000).collect::<Vec<_>>());
    let path = dir.join("many.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let t = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args([
            "bake",
            path.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
            "--max-memory",
            "1024",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("estimated")
            && err.contains("10000000 instanced triangles")
            && err.contains("1024 MB"),
        "{err}"
    );
    assert!(
        t.elapsed() < Duration::from_secs(10),
        "refusal took {:?}",
        t.elapsed()
    );
}

/// A valid little scene as .gltf text and as .glb bytes.
fn seeds() -> (Vec<u8>, Vec<u8>) {
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let m = b.mesh(&p, &i, Some(emit));
    b.node("lamp", m);
    let text = serde_json::to_vec(&b.json()).unwrap();
    let mut doc = b.json();
    doc["buffers"] = serde_json::json!([{"byteLength": b.buffer.len()}]);
    let glb = radbake::output::baked::glb(&doc, &b.buffer);
    (text, glb)
}

fn tiny() -> radbake::BakeConfig {
    radbake::BakeConfig {
        texels_per_meter: 4.0,
        rays_per_patch: 16,
        direct_samples: 1,
        final_gather: 4,
        max_texels: 1 << 16,
        ..radbake::BakeConfig::default()
    }
}

fn run_mutant(bytes: &[u8], ext: &str) {
    let dir = std::env::temp_dir().join(format!("radbake-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("case.{ext}"));
    std::fs::write(&path, bytes).unwrap();
    let t = Instant::now();
    let result = std::panic::catch_unwind(|| {
        let options = radbake::scene::LoadOptions {
            max_memory: Some(256 << 20),
            ..Default::default()
        };
        if let Ok(scene) = radbake::scene::load(&path, &options) {
            let _ = radbake::bake(&scene, &tiny(), &radbake::Silent);
        }
    });
    assert!(
        result.is_ok(),
        "panic on a mutated .{ext} (saved at {})",
        path.display()
    );
    assert!(
        t.elapsed() < Duration::from_secs(20),
        "a mutated .{ext} took {:?}",
        t.elapsed()
    );
}

proptest! {
    // `PROPTEST_CASES` sets the run length (CI: the default below).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(48),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Random byte edits and truncations of a valid .glb.
    #[test]
    fn fuzz_glb(edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8), cut in prop::option::of(any::<prop::sample::Index>())) {
        let (_, mut glb) = seeds();
        for (at, v) in edits {
            let i = at.index(glb.len());
            glb[i] = v;
        }
        if let Some(c) = cut {
            glb.truncate(c.index(glb.len()));
        }
        run_mutant(&glb, "glb");
    }

    /// Random edits of the .gltf JSON text: digits, signs and brackets where
    /// numbers and structure are, so the document often still parses.
    #[test]
    fn fuzz_gltf(edits in prop::collection::vec((any::<prop::sample::Index>(), prop::sample::select(b"0123456789-.eE[]{},\"9".to_vec())), 1..6)) {
        let (mut text, _) = seeds();
        for (at, v) in edits {
            let i = at.index(text.len());
            text[i] = v;
        }
        run_mutant(&text, "gltf");
    }
}
