//! Light layers (`extras.radbake.layer`, `sky_layer`): a bake's layers
//! are its lights' shares of it, so any weighted sum of them is the bake at
//! those intensities, bounces included.
//!
//! - Exact: the Cornell box with its ceiling lamp in layer `ceiling` and a
//!   point light in layer `lamp`; for weights (1, 1), (0.5, 2) and (0, 1)
//!   the weighted sum of the layers against a bake of the scene at those
//!   intensities, with the same seed, every ray cast and no denoising in
//!   both: every texel (and every probe coefficient) within 1e-4 relative.
//! - With the defaults (the adaptive gather and the denoiser decide from
//!   the whole bake): every instance's mean within 0.5 %.
//! - An HDRI sky in its own layer beside a sun, the same way.
//! - The outputs: per-layer files listed in `manifest.json`, none without
//!   layers; bad names and misplaced layers are one-line errors.
//! - `radbake preview --layer`: the layers at weights against the preview
//!   of a one-layer bake at those intensities.

mod common;

use common::{scene_path, temp_dir};
use glam::Vec3;
use radbake::config::LayerMode;
use radbake::scene::Scene;
use radbake::{Bake, BakeConfig, Silent};
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::Command;

/// The Cornell box with its lamp's material in layer `ceiling` and a
/// point light (node `bulb`) in layer `lamp` (`scenes/cornell_layers.gltf`),
/// copied into a fresh folder `name`.
fn layered_cornell(name: &str) -> PathBuf {
    let path = temp_dir(name).join("cornell_layers.gltf");
    std::fs::copy(scene_path("cornell_layers.gltf"), &path).unwrap();
    path
}

fn load(path: &std::path::Path) -> Scene {
    radbake::load(path, &Default::default()).unwrap()
}

/// `scene` with the lamp's emission and the bulb's intensity scaled by
/// `w` = (ceiling, lamp), and no layers.
fn at_weights(scene: &Scene, w: (f32, f32)) -> Scene {
    let mut s = scene.clone();
    for m in &mut s.materials {
        if m.layer.is_some() {
            m.emission *= w.0;
            m.layer = None;
        }
    }
    for l in &mut s.lights {
        l.intensity *= w.1;
        l.layer = None;
    }
    s
}

fn config() -> BakeConfig {
    BakeConfig {
        texels_per_meter: 40.0,
        final_gather: 64,
        probe_budget: 27,
        probe_rays: 256,
        ..BakeConfig::default()
    }
}

/// Σ wₖ × layer k's final texel values (lightmap) and probe SH.
fn combined(bake: &Bake, w: &[f32]) -> (Vec<Vec3>, Vec<Vec3>) {
    assert_eq!(bake.maps.layers.len(), w.len());
    let n = bake.maps.lightmaps.texel_values.len();
    let mut texels = vec![Vec3::ZERO; n];
    for (lm, wk) in bake.maps.layers.iter().zip(w) {
        for (t, v) in texels.iter_mut().zip(&lm.texel_values) {
            *t += *v * *wk;
        }
    }
    let probes = bake.probes.as_ref().unwrap();
    let mut sh = vec![Vec3::ZERO; probes.sh.len() * 9];
    for (layer, wk) in probes.layers.iter().zip(w) {
        for (acc, c) in sh.iter_mut().zip(layer.iter().flatten()) {
            *acc += *c * *wk;
        }
    }
    (texels, sh)
}

/// The largest |a − b| / (|b| + floor) over channels.
fn worst(a: &[Vec3], b: &[Vec3], floor: f32) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / (y[c].abs() + floor)))
        .fold(0.0, f32::max)
}

#[test]
fn cornell_layers_sum_exactly_to_the_bake_at_any_weights() {
    let path = layered_cornell("layers-exact");
    let scene = load(&path);
    // Every decision that depends on light is taken from the whole bake;
    // those a one-layer bake takes from its own light are switched off in
    // both: the adaptive gather, the denoiser and (by a tolerance the
    // solve cannot reach) the solver's stopping rule.
    let exact = BakeConfig {
        gather_threshold: 0.0,
        denoise: false,
        tolerance: 1e-9,
        max_iterations: 200,
        ..config()
    };
    let layered = radbake::bake(&scene, &exact, &Silent).unwrap();
    let layers = layered.layers.as_ref().expect("the scene names layers");
    assert_eq!(layers.names, ["ceiling", "lamp"]);
    // At weight 1 the layers are the bake's combined lightmap.
    let (sum, _) = combined(&layered, &[1.0, 1.0]);
    let whole = &layered.maps.lightmaps.texel_values;
    let e = worst(&sum, whole, 1e-3);
    eprintln!("layers at weight 1 against the combined lightmap: {e:.2e}");
    assert!(e <= 1e-5, "{e}");
    for w in [(1.0, 1.0), (0.5, 2.0), (0.0, 1.0)] {
        let reference = at_weights(&scene, w);
        let one = radbake::bake(&reference, &exact, &Silent).unwrap();
        assert!(one.layers.is_none());
        let (texels, sh) = combined(&layered, &[w.0, w.1]);
        let want = &one.maps.lightmaps.texel_values;
        // 1e-4 relative, or 1e-6 absolute where the texel is black.
        let bad = (texels.iter().zip(want))
            .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-4 * b.max_element() + 1e-6)
            .count();
        let e = worst(&texels, want, 1e-2);
        let want_sh: Vec<Vec3> = one
            .probes
            .as_ref()
            .unwrap()
            .sh
            .iter()
            .flatten()
            .copied()
            .collect();
        let e_sh = worst(&sh, &want_sh, 1e-2);
        eprintln!(
            "weights {w:?}: {bad} of {} texels off by more than 1e-4; worst {e:.2e}; probes {e_sh:.2e}",
            texels.len()
        );
        assert_eq!(bad, 0);
        assert!(e_sh <= 1e-4, "{e_sh}");
    }
}

/// Area-weighted mean of `values` per instance.
fn instance_means(bake: &Bake, values: &[Vec3]) -> Vec<(String, Vec3)> {
    let n = bake.scene.instances.len();
    let mut acc = vec![(Vec3::ZERO, 0.0f32); n];
    for (t, v) in values.iter().enumerate() {
        if !bake.transport.valid[t] {
            continue;
        }
        let a = bake.texels.area[t];
        let i = bake.texels.instance[t] as usize;
        acc[i].0 += *v * a;
        acc[i].1 += a;
    }
    (bake.scene.instances.iter().zip(acc))
        .map(|(inst, (s, a))| (inst.node.clone(), s / a.max(1e-12)))
        .collect()
}

#[test]
fn with_the_defaults_every_instance_mean_follows_the_weights() {
    let path = layered_cornell("layers-defaults");
    let scene = load(&path);
    let layered = radbake::bake(&scene, &config(), &Silent).unwrap();
    for w in [(0.5, 2.0), (0.0, 1.0), (1.0, 0.0)] {
        let reference = at_weights(&scene, w);
        let one = radbake::bake(&reference, &config(), &Silent).unwrap();
        let (texels, _) = combined(&layered, &[w.0, w.1]);
        let got = instance_means(&layered, &texels);
        let want = instance_means(&one, &one.maps.lightmaps.texel_values);
        for ((node, g), (_, r)) in got.iter().zip(&want) {
            let (g, r) = (g.element_sum(), r.element_sum());
            let e = (g - r) / r;
            eprintln!(
                "weights {w:?}: {node}: layers {g:.5}, bake {r:.5} ({:+.3} %)",
                100.0 * e
            );
            assert!(e.abs() <= 0.005, "{node}: {e}");
        }
    }
}

#[test]
fn an_hdri_sky_in_its_own_layer() {
    // A sunlit ground under a sky map (a bright band and a dim rest).
    let to_sun = Vec3::new(0.3, 1.0, 0.2).normalize();
    let extras = json!({"radbake": {"layer": "sun"}});
    let path = common::sunlit_ground("layers-hdri", to_sun, true, Some(extras));
    let map = path.with_file_name("sky.exr");
    let (w, h) = (64u32, 32u32);
    let px: Vec<Vec3> = (0..w * h)
        .map(|i| {
            if (8..12).contains(&(i / w)) {
                Vec3::new(3.0, 2.0, 1.0)
            } else {
                Vec3::splat(0.2)
            }
        })
        .collect();
    radbake::output::write_exr_rgb(&map, w, h, &px).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 2.0,
        sky_map: Some(map),
        sky_layer: Some("sky".into()),
        gather_threshold: 0.0,
        denoise: false,
        ..BakeConfig::default()
    };
    let scene = load(&path);
    let layered = radbake::bake(&scene, &cfg, &Silent).unwrap();
    assert_eq!(layered.layers.as_ref().unwrap().names, ["sky", "sun"]);
    for (sky, sun) in [(1.0, 1.0), (0.5, 1.0), (1.0, 0.0)] {
        let mut reference = scene.clone();
        reference.lights[0].intensity *= sun;
        reference.lights[0].layer = None;
        let one_cfg = BakeConfig {
            sky_intensity: sky,
            sky_layer: None,
            ..cfg.clone()
        };
        let one = radbake::bake(&reference, &one_cfg, &Silent).unwrap();
        let (texels, sh) = combined(&layered, &[sky, sun]);
        let e = worst(&texels, &one.maps.lightmaps.texel_values, 1e-2);
        let want_sh: Vec<Vec3> = one
            .probes
            .as_ref()
            .unwrap()
            .sh
            .iter()
            .flatten()
            .copied()
            .collect();
        let e_sh = worst(&sh, &want_sh, 1e-2);
        eprintln!("sky {sky}, sun {sun}: texels {e:.2e}, probes {e_sh:.2e}");
        assert!(e <= 1e-4 && e_sh <= 1e-4, "{e} {e_sh}");
    }
}

fn radbake() -> Command {
    Command::new(env!("CARGO_BIN_EXE_radbake"))
}

#[test]
fn layer_files_are_listed_in_the_manifest() {
    let path = layered_cornell("layers-files");
    let out = temp_dir("layers-files-out");
    let status = radbake()
        .args([
            "bake",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ])
        .args([
            "--texels-per-meter",
            "24",
            "--final-gather",
            "32",
            "--probe-budget",
            "8",
        ])
        .status()
        .unwrap();
    assert!(status.success());
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let layers = manifest["layers"].as_array().unwrap();
    let names: Vec<&str> = layers.iter().map(|l| l["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["ceiling", "lamp"]);
    assert_eq!(layers[0]["materials"], json!(["light"]));
    assert_eq!(layers[1]["lights"], json!(["bulb"]));
    for l in layers {
        for p in l["pages"].as_array().unwrap() {
            for key in ["exr", "ktx2"] {
                let f = out.join(p[key].as_str().unwrap());
                assert!(f.is_file(), "{}", f.display());
            }
        }
        assert!(out.join(l["probes"]["binary"].as_str().unwrap()).is_file());
        for v in l["probes"]["bevy_irradiance_volumes"].as_array().unwrap() {
            assert!(out.join(v.as_str().unwrap()).is_file());
        }
    }
    // `--layers off`: one lightmap, no layer files, no `layers` key.
    let off = temp_dir("layers-files-off");
    let status = radbake()
        .args([
            "bake",
            path.to_str().unwrap(),
            "--out",
            off.to_str().unwrap(),
            "-q",
        ])
        .args([
            "--texels-per-meter",
            "24",
            "--final-gather",
            "32",
            "--probe-budget",
            "8",
        ])
        .args(["--layers", "off"])
        .status()
        .unwrap();
    assert!(status.success());
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(off.join("manifest.json")).unwrap()).unwrap();
    assert!(manifest.get("layers").is_none());
    assert!(!off.join("lightmap_0_lamp.exr").exists());
    // The combined files are the same with and without layers.
    for f in ["lightmap_0.exr", "cornell_layers.baked.glb", "probes.bin"] {
        assert_eq!(
            std::fs::read(out.join(f)).unwrap(),
            std::fs::read(off.join(f)).unwrap(),
            "{f}"
        );
    }
    combine_writes_the_weighted_sum(&out);
}

/// An EXR page's RGB pixels.
fn read_exr(path: &std::path::Path) -> Vec<Vec3> {
    exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![Vec3::ZERO; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .unwrap()
    .layer_data
    .channel_data
    .pixels
    .1
}

fn f32s(path: &std::path::Path) -> Vec<f32> {
    (std::fs::read(path).unwrap().chunks_exact(4))
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// `radbake combine` on the bake in `out`: its page and probes are the
/// layers' weighted sum (a layer not named keeps weight 1); at weight 1
/// they are the bake's own, to rounding; an unknown layer, a negative
/// weight or the bake folder as `--out` write nothing.
fn combine_writes_the_weighted_sum(out: &std::path::Path) {
    let comb = temp_dir("layers-combine");
    let o = radbake()
        .args(["combine", out.to_str().unwrap(), "lamp=2,1,0.5"])
        .args(["--out", comb.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ceiling, lamp) = (
        read_exr(&out.join("lightmap_0_ceiling.exr")),
        read_exr(&out.join("lightmap_0_lamp.exr")),
    );
    let page = read_exr(&comb.join("lightmap_0.exr"));
    let w = Vec3::new(2.0, 1.0, 0.5);
    let want: Vec<Vec3> = ceiling
        .iter()
        .zip(&lamp)
        .map(|(c, l)| *c + w * *l)
        .collect();
    assert!(worst(&page, &want, 1e-6) <= 1e-6);
    let (pc, pl, pb) = (
        f32s(&out.join("probes_ceiling.bin")),
        f32s(&out.join("probes_lamp.bin")),
        f32s(&comb.join("probes.bin")),
    );
    assert_eq!(pb.len(), pc.len());
    for (i, ((c, l), b)) in pc.iter().zip(&pl).zip(&pb).enumerate() {
        let want = c + [2.0, 1.0, 0.5][i % 3] * l;
        assert!(
            (b - want).abs() <= 1e-6 * (1.0 + want.abs()),
            "{i}: {b} {want}"
        );
    }
    for f in [
        "lightmap_0.ktx2",
        "lightmap_0.png",
        "probes.json",
        "probes_0.ktx2",
    ] {
        assert!(comb.join(f).is_file(), "{f}");
    }
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(comb.join("manifest.json")).unwrap()).unwrap();
    assert!(manifest.get("layers").is_none());
    assert_eq!(
        manifest["combined"]["weights"]["lamp"],
        json!([2.0, 1.0, 0.5])
    );
    assert_eq!(
        manifest["combined"]["weights"]["ceiling"],
        json!([1.0, 1.0, 1.0])
    );
    // At weight 1: the bake.
    let one = temp_dir("layers-combine-one");
    let status = radbake()
        .args([
            "combine",
            out.to_str().unwrap(),
            "--out",
            one.to_str().unwrap(),
            "-q",
        ])
        .status()
        .unwrap();
    assert!(status.success());
    let (a, b) = (
        read_exr(&one.join("lightmap_0.exr")),
        read_exr(&out.join("lightmap_0.exr")),
    );
    assert!(worst(&a, &b, 1e-6) <= 1e-5, "{}", worst(&a, &b, 1e-6));
    // Errors: one line, nothing written.
    for (args, want) in [
        (vec!["lampp=0"], "no layer `lampp`"),
        (vec!["lamp=-1"], "lamp=-1"),
        (vec!["lamp"], "NAME=W"),
    ] {
        let bad = temp_dir("layers-combine-bad").join("new");
        let o = radbake()
            .args(["combine", out.to_str().unwrap()])
            .args(&args)
            .args(["--out", bad.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{want}: {err}");
        assert!(!bad.exists(), "{want}");
    }
    let o = radbake()
        .args([
            "combine",
            out.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("the bake folder itself"),
        "{err}"
    );
    assert!(out.join("lightmap_0_lamp.exr").is_file());
}

/// The Cornell box JSON with `edit` applied, written to `name`.
fn edited(name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let mut doc: Value =
        serde_json::from_slice(&std::fs::read(layered_cornell(name)).unwrap()).unwrap();
    edit(&mut doc);
    let path = temp_dir(&format!("{name}-edited")).join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

#[test]
fn misplaced_layers_and_bad_names_are_one_line_errors() {
    let cases: Vec<(PathBuf, Vec<&str>, &str)> = vec![
        (
            edited("layers-bad-name", |d| {
                d["nodes"][9]["extras"]["radbake"]["layer"] = json!("two words")
            }),
            vec![],
            "nodes[9].extras.radbake.layer",
        ),
        (
            edited("layers-mesh-node", |d| {
                d["nodes"][0]["extras"] = json!({"radbake": {"layer": "x"}})
            }),
            vec![],
            "the node has no light",
        ),
        (
            edited("layers-dark-material", |d| {
                d["materials"][0]["extras"] = json!({"radbake": {"layer": "x"}})
            }),
            vec![],
            "the material emits nothing",
        ),
        (
            layered_cornell("layers-realtime"),
            vec!["--light-mode", "bulb=realtime"],
            "is realtime",
        ),
        (
            layered_cornell("layers-sky-name"),
            vec!["--sky-layer", "9sky"],
            "sky_layer",
        ),
        (
            layered_cornell("layers-progressive"),
            vec!["--solver", "progressive"],
            "stored form-factor matrix",
        ),
    ];
    for (path, extra, want) in cases {
        let out = temp_dir("layers-bad-out");
        let o = radbake()
            .args([
                "bake",
                path.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "-q",
            ])
            .args(["--texels-per-meter", "8"])
            .args(&extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{want}: succeeded");
        assert!(err.contains(want), "{want}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.join("manifest.json").exists());
    }
    // In the library, too: no layers with layers = "off".
    let scene = load(&layered_cornell("layers-off-lib"));
    let off = BakeConfig {
        layers: LayerMode::Off,
        texels_per_meter: 8.0,
        probes: false,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &off, &Silent).unwrap();
    assert!(bake.layers.is_none() && bake.maps.layers.is_empty());
}

/// Bakes `scene` into a fresh folder `name` with every ray cast and no
/// denoising (so that a bake at other intensities is the layers' sum to
/// rounding), `extra` added; the folder.
fn bake_exactly(scene: &std::path::Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = temp_dir(name);
    let run = radbake()
        .args([
            "bake",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ])
        .args([
            "--texels-per-meter",
            "24",
            "--final-gather",
            "32",
            "--probe-budget",
            "8",
        ])
        .args(["--gather-threshold", "0", "--denoise", "false"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    out
}

/// `radbake preview --headless --tone-map none` of `glb` from the box's
/// camera, `extra` added, as linear RGB; `None` on a machine with no
/// graphics adapter.
fn preview_pixels(glb: &std::path::Path, extra: &[&str]) -> Option<Vec<Vec3>> {
    let png = glb.with_extension(format!("{}.png", extra.join("_").replace(['=', ','], "-")));
    let run = radbake()
        .args([
            "preview",
            glb.to_str().unwrap(),
            "--headless",
            "--tone-map",
            "none",
        ])
        .args([
            "--camera",
            "camera",
            "--size",
            "160x160",
            "--out",
            png.to_str().unwrap(),
        ])
        .args(extra)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    if !run.status.success() && stderr.contains("no graphics adapter") {
        assert!(
            std::env::var_os("RADBAKE_REQUIRE_GPU").is_none(),
            "{stderr}"
        );
        eprintln!("SKIPPED (no graphics adapter): {stderr}");
        return None;
    }
    assert!(run.status.success(), "{stderr}");
    let img = image::open(&png).unwrap().to_rgb8();
    let lin = |c: u8| radbake::scene::texture::srgb_to_linear(c as f32 / 255.0);
    Some(
        img.pixels()
            .map(|p| Vec3::new(lin(p[0]), lin(p[1]), lin(p[2])))
            .collect(),
    )
}

/// (mean of a / mean of b, the 95th percentile of the per-pixel
/// |a − b| / max(b, 1 % of b's mean), on the RGB mean): the browser and
/// Bevy tests' measure.
fn image_agreement(a: &[Vec3], b: &[Vec3]) -> (f32, f32) {
    let lum = |v: &Vec3| v.element_sum() / 3.0;
    let (sa, sb): (f32, f32) = (a.iter().map(lum).sum(), b.iter().map(lum).sum());
    let floor = 0.01 * sb / b.len() as f32;
    let mut d: Vec<f32> = (a.iter().zip(b))
        .map(|(x, y)| (lum(x) - lum(y)).abs() / lum(y).max(floor))
        .collect();
    d.sort_by(f32::total_cmp);
    (sa / sb, d[d.len() * 95 / 100])
}

/// `radbake preview --layer lamp=W` shows the bake at the lamp's weight W:
/// for W = 1 the `.glb`'s own pages (the sum of the layers), for
/// W = 0, 0.5 and 2 the preview of a bake with the bulb at those
/// intensities (its layers at weight 1). An unknown layer is a one-line error.
#[test]
fn the_preview_shows_the_layers_at_their_weights() {
    let path = layered_cornell("layers-preview");
    let out = bake_exactly(&path, "layers-preview-out", &[]);
    let glb = out.join("cornell_layers.baked.glb");
    let Some(stock) = preview_pixels(&glb, &[]) else {
        return;
    };
    let at_one = preview_pixels(&glb, &["--layer", "lamp=1"]).unwrap();
    let (mean, p95) = image_agreement(&at_one, &stock);
    eprintln!("lamp=1 against the .glb's pages: mean {mean:.5}, 95th percentile {p95:.4}");
    // The .glb's pages are 8-bit sRGB, dithered, one scale per instance:
    // their dark texels differ from the layers' half floats by their
    // dither, pixel by pixel.
    assert!((mean - 1.0).abs() < 0.015, "{mean} {p95}");
    let doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    for w in [0.0f32, 0.5, 2.0] {
        let mut one = doc.clone();
        let i = &mut one["extensions"]["KHR_lights_punctual"]["lights"][0]["intensity"];
        *i = json!(i.as_f64().unwrap() * w as f64);
        let scene = path.with_file_name(format!("one_layer_{w}.gltf"));
        std::fs::write(&scene, serde_json::to_vec(&one).unwrap()).unwrap();
        // Its layers at weight 1: its own bake, in the same half floats.
        let bake = bake_exactly(&scene, &format!("layers-preview-{w}"), &[]);
        let reference = preview_pixels(
            &bake.join(format!("one_layer_{w}.baked.glb")),
            &["--layer", "lamp=1"],
        )
        .unwrap();
        let weighted = preview_pixels(&glb, &["--layer", &format!("lamp={w}")]).unwrap();
        let (mean, p95) = image_agreement(&weighted, &reference);
        eprintln!(
            "lamp={w} against a bake at that intensity: mean {mean:.5}, 95th percentile {p95:.4}"
        );
        assert!(
            (mean - 1.0).abs() < 0.015 && p95 < 0.02,
            "lamp={w}: {mean} {p95}"
        );
    }
    let run = radbake()
        .args(["preview", glb.to_str().unwrap(), "--headless", "--out"])
        .arg(out.join("never.png"))
        .args(["--layer", "lantern=1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("no layer `lantern`") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(!out.join("never.png").exists());
}
