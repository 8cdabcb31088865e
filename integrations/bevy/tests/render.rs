//! A real Bevy render of a radbake bake: the Cornell box baked by radbake,
//! loaded through `RadbakePlugin`, rendered by Bevy 0.19's own renderer
//! (headless, to an image target, from the glTF camera) and compared with
//! `radbake preview --headless` of the same camera. Also checks that every
//! lightmapped mesh got its `Lightmap` and that instances of one mesh got
//! their own rectangles.
//!
//! Needs a graphics adapter (lavapipe in CI); without one it says so and
//! passes only if `RADBAKE_REQUIRE_GPU` is unset.

use bevy::app::ScheduleRunnerPlugin;
use bevy::camera::RenderTarget;
use bevy::core_pipeline::tonemapping::{DebandDither, Tonemapping};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy::render::RenderPlugin;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_radbake::{
    RadbakeApplied, RadbakeBake, RadbakeFailed, RadbakeLayers, RadbakeLayersApplied,
    RadbakeLiveApplied, RadbakePlugin,
};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Width and height of both renders: a multiple of 32, so Bevy's readback
/// rows (256-byte aligned, 8 bytes a pixel) have no padding.
const SIZE: u32 = 256;

/// One Bevy app at a time in this process.
static SERIAL: Mutex<()> = Mutex::new(());

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("bevy-radbake-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Bakes `gltf` into `out` (radbake's library, the CLI's defaults but the
/// texel density).
fn bake(gltf: &Path, out: &Path, texels_per_meter: f32, ktx2: radbake::config::Ktx2Mode) {
    let scene = radbake::scene::load(gltf, &Default::default()).unwrap();
    let config = radbake::BakeConfig {
        texels_per_meter,
        ktx2,
        ..Default::default()
    };
    let bake = radbake::bake(&scene, &config, &radbake::Silent).unwrap();
    radbake::output::write_engine_outputs(out, "scene", &bake).unwrap();
}

/// What a Bevy run saw.
struct BevyRun {
    /// Linear RGBA, row-major, `SIZE`², or None when nothing was rendered.
    pixels: Option<Vec<[f32; 4]>>,
    applied: RadbakeApplied,
    /// Per mesh entity: its node's name and its lightmap's rectangle.
    lightmaps: Vec<(String, Option<Rect>)>,
    /// Per point light: its name and `affects_lightmapped_mesh_diffuse`.
    point_lights: Vec<(String, bool)>,
}

#[derive(Resource, Clone)]
struct Target(Handle<Image>);

#[derive(Resource, Clone, Default)]
struct Captured(Arc<Mutex<Option<Vec<u8>>>>);

/// Asks for one readback of the render target into `captured`.
fn read_back(world: &mut World, captured: &Captured) {
    let target = world.resource::<Target>().0.clone();
    let sink = captured.0.clone();
    world.spawn(Readback::texture(target)).observe(
        move |event: On<ReadbackComplete>, mut commands: Commands| {
            let mut slot = sink.lock().unwrap();
            if slot.is_none() {
                *slot = Some(event.data.clone());
                commands.entity(event.entity).despawn();
            }
        },
    );
}

/// Bevy's default plugins, headless (no window, no winit), assets from
/// `dir`.
fn headless_plugins(dir: &Path) -> bevy::app::PluginGroupBuilder {
    DefaultPlugins
        .set(AssetPlugin {
            file_path: dir.to_string_lossy().into_owned(),
            ..default()
        })
        .set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            close_when_requested: false,
            ..default()
        })
        .disable::<WinitPlugin>()
}

/// Loads the bake in `dir` with `RadbakePlugin`; with `render`, renders it
/// from its first glTF camera, linear (HDR target, no tone mapping, no
/// dither, Bevy's default exposure), and reads the image back.
fn run_bevy(dir: &Path, render: bool) -> BevyRun {
    let mut app = App::new();
    app.add_plugins(headless_plugins(dir).set(RenderPlugin {
        // Every pipeline ready when first used: no frame drawn
        // with a piece missing.
        synchronous_pipeline_compilation: true,
        ..default()
    }))
    .add_plugins(ScheduleRunnerPlugin::default())
    .add_plugins(RadbakePlugin::default())
    .init_resource::<Captured>()
    // The preview's background is black.
    .insert_resource(ClearColor(Color::BLACK))
    .add_systems(
        Startup,
        |mut commands: Commands, assets: Res<AssetServer>, mut images: ResMut<Assets<Image>>| {
            let mut image = Image::new_target_texture(SIZE, SIZE, TextureFormat::Rgba16Float, None);
            image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
            commands.insert_resource(Target(images.add(image)));
            commands.spawn(RadbakeBake::load(&assets, ""));
        },
    );
    if render {
        app.add_systems(Update, aim_camera);
    }
    app.finish();
    app.cleanup();
    let captured = app.world().resource::<Captured>().clone();
    let mut ready_at = None;
    for frame in 0..3000 {
        app.update();
        let world = app.world_mut();
        let applied = world
            .query::<&RadbakeApplied>()
            .iter(world)
            .next()
            .is_some();
        let manifest = world
            .query::<&RadbakeBake>()
            .iter(world)
            .next()
            .unwrap()
            .manifest
            .clone();
        let loaded = world
            .resource::<AssetServer>()
            .is_loaded_with_dependencies(&manifest);
        if applied && loaded && ready_at.is_none() {
            ready_at = Some(frame);
            if !render {
                break;
            }
        }
        // Frames for the uploads (the lightmap pages, the volume), then
        // one readback.
        if ready_at.is_some_and(|r| frame == r + 60) {
            read_back(world, &captured);
        }
        if captured.0.lock().unwrap().is_some() {
            break;
        }
    }
    assert!(
        ready_at.is_some(),
        "the bake was not applied within 3000 frames"
    );
    let (applied, lightmaps, point_lights) = what_was_applied(app.world_mut());
    let pixels = captured
        .0
        .lock()
        .unwrap()
        .take()
        .map(|bytes| rgba16f(&bytes));
    BevyRun {
        point_lights,
        pixels,
        applied,
        lightmaps,
    }
}

/// The plugin's `RadbakeApplied`, the mesh entities' lightmaps and the
/// point lights, as [`BevyRun`] holds them.
type Applied = (
    RadbakeApplied,
    Vec<(String, Option<Rect>)>,
    Vec<(String, bool)>,
);

/// What the plugin left in `world`: its `RadbakeApplied`, each mesh
/// entity's node name and lightmap rectangle, and each point light's name
/// and `affects_lightmapped_mesh_diffuse`.
fn what_was_applied(world: &mut World) -> Applied {
    let applied = world
        .query::<&RadbakeApplied>()
        .iter(world)
        .next()
        .unwrap()
        .clone();
    let mut q = world.query::<(&Mesh3d, Option<&Lightmap>, &ChildOf)>();
    let parents: Vec<(Entity, Option<Rect>)> = q
        .iter(world)
        .map(|(_, l, p)| (p.parent(), l.map(|l| l.uv_rect)))
        .collect();
    let lightmaps = parents
        .into_iter()
        .map(|(p, r)| {
            let name = world
                .get::<Name>(p)
                .map(|n| n.to_string())
                .unwrap_or_default();
            (name, r)
        })
        .collect();
    let mut q = world.query::<(&PointLight, Option<&Name>)>();
    let point_lights = q
        .iter(world)
        .map(|(l, n)| {
            (
                n.map(|n| n.to_string()).unwrap_or_default(),
                l.affects_lightmapped_mesh_diffuse,
            )
        })
        .collect();
    (applied, lightmaps, point_lights)
}

/// A readback of the `Rgba16Float` target as linear RGBA, row-major.
fn rgba16f(bytes: &[u8]) -> Vec<[f32; 4]> {
    assert_eq!(bytes.len(), (SIZE * SIZE * 8) as usize, "readback size");
    bytes
        .chunks_exact(8)
        .map(|p| {
            let c = |k: usize| half::f16::from_le_bytes([p[2 * k], p[2 * k + 1]]).to_f32();
            [c(0), c(1), c(2), c(3)]
        })
        .collect()
}

/// Once the bake is applied: a camera at the first glTF camera's place,
/// with its projection, renders to the target, linear (the glTF camera is
/// switched off).
fn aim_camera(
    mut commands: Commands,
    target: Res<Target>,
    applied: Query<Entity, Added<RadbakeApplied>>,
    children: Query<&Children>,
    mut cameras: Query<(&mut Camera, &GlobalTransform, &Projection)>,
) {
    for root in &applied {
        let gltf_camera = children
            .iter_descendants(root)
            .find(|e| cameras.contains(*e))
            .expect("the baked scene has a glTF camera");
        let (mut camera, at, projection) = cameras.get_mut(gltf_camera).unwrap();
        camera.is_active = false;
        commands.spawn((
            Camera3d::default(),
            at.compute_transform(),
            projection.clone(),
            RenderTarget::Image(target.0.clone().into()),
            bevy::camera::Hdr,
            Tonemapping::None,
            DebandDither::Disabled,
            Msaa::Off,
        ));
    }
}

/// `radbake preview --headless` of the bake's glTF camera, tone map none,
/// EV 0; linear RGB per pixel (the PNG's sRGB decoded). None without a
/// graphics adapter.
fn preview(glb: &Path, png: &Path, camera: &str) -> Option<Vec<[f32; 3]>> {
    preview_at(glb, png, camera, &[])
}

/// [`preview`] of a layered bake at `layers` (`NAME=W` or `NAME=R,G,B`,
/// as `radbake preview --layer` takes them).
fn preview_at(glb: &Path, png: &Path, camera: &str, layers: &[&str]) -> Option<Vec<[f32; 3]>> {
    preview_lit(glb, png, camera, layers, None)
}

/// [`preview_at`], with `sun` a live bake relit towards it (`radbake
/// preview --sun-direction`), the real-time lights not drawn.
fn preview_lit(
    glb: &Path,
    png: &Path,
    camera: &str,
    layers: &[&str],
    sun: Option<Vec3>,
) -> Option<Vec<[f32; 3]>> {
    use radbake::preview::{Options, Settings, ToneMap, Viewpoint};
    let layers = layers
        .iter()
        .map(|w| radbake::output::combine::parse_weight(w).unwrap())
        .collect();
    let opts = Options {
        scene: glb.to_path_buf(),
        headless: true,
        out: Some(png.to_path_buf()),
        size: (SIZE, SIZE),
        viewpoint: Viewpoint::Camera(camera.to_string()),
        frames: None,
        screenshot: None,
        settings: Settings {
            tone_map: ToneMap::None,
            exposure_ev: 0.0,
            realtime_lights: sun.is_none(),
            ..Default::default()
        },
        sdf: None,
        watch: false,
        layers,
        sun: sun.map(|d| radbake::output::relight::Relight {
            sun_direction: glam::Vec3::from_array(d.to_array()),
            sun_irradiance: None,
            sky: None,
            weights: Vec::new(),
        }),
        live: false,
    };
    if let Err(e) = radbake::preview::run(&opts) {
        let text = format!("{e:#}");
        assert!(
            text.contains("no graphics adapter"),
            "preview failed: {text}"
        );
        return None;
    }
    let img = image::open(png).unwrap().to_rgb8();
    let lin = |c: u8| {
        let c = c as f32 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    Some(
        img.pixels()
            .map(|p| [lin(p[0]), lin(p[1]), lin(p[2])])
            .collect(),
    )
}

/// Linear RGBA to an sRGB PNG (clamped), for looking at.
fn save_png(pixels: &[[f32; 4]], path: &Path) {
    let enc = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        let s = if v <= 0.0031308 {
            v * 12.92
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    let img = image::RgbImage::from_fn(SIZE, SIZE, |x, y| {
        let p = pixels[(y * SIZE + x) as usize];
        image::Rgb([enc(p[0]), enc(p[1]), enc(p[2])])
    });
    img.save(path).unwrap();
    eprintln!("wrote {}", path.display());
}

fn mean(pixels: impl Iterator<Item = [f32; 3]>) -> [f64; 3] {
    let (mut s, mut n) = ([0f64; 3], 0f64);
    for p in pixels {
        (0..3).for_each(|c| s[c] += p[c] as f64);
        n += 1.0;
    }
    s.map(|v| v / n.max(1.0))
}

fn no_adapter(what: &str) {
    assert!(
        std::env::var_os("RADBAKE_REQUIRE_GPU").is_none(),
        "{what}: no graphics adapter, and RADBAKE_REQUIRE_GPU is set"
    );
    eprintln!("SKIPPED {what}: no graphics adapter on this machine");
}

#[test]
fn bevy_renders_the_cornell_box_as_the_preview_does() {
    cornell_in_bevy(radbake::config::Ktx2Mode::Rgb9e5);
}

/// The same with BC6H pages (`--ktx2 bc6h`): Bevy loads them as they are.
#[test]
fn bevy_renders_bc6h_pages_as_the_preview_does() {
    cornell_in_bevy(radbake::config::Ktx2Mode::Bc6h);
}

fn cornell_in_bevy(ktx2: radbake::config::Ktx2Mode) {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir(&format!("cornell-{ktx2:?}"));
    bake(&repo().join("scenes/cornell_box.gltf"), &dir, 40.0, ktx2);
    let glb = dir.join("scene.baked.glb");
    // The glTF camera's node, as both renderers name it.
    let camera = "camera";
    let Some(want) = preview(&glb, &dir.join("preview.png"), camera) else {
        return no_adapter("Bevy vs preview");
    };
    let run = run_bevy(&dir, true);

    // Every mesh of the scene is lightmapped: each got its Lightmap.
    assert!(
        run.applied.missing.is_empty(),
        "missing {:?}",
        run.applied.missing
    );
    assert_eq!(run.applied.lightmapped, run.lightmaps.len());
    assert!(
        run.lightmaps.len() >= 8,
        "{} mesh entities",
        run.lightmaps.len()
    );
    for (node, rect) in &run.lightmaps {
        assert!(rect.is_some(), "{node} has no Lightmap");
    }
    assert_eq!(run.applied.volumes, 1, "the bake's probe grid");

    let got = run.pixels.expect("Bevy rendered nothing");
    save_png(&got, &dir.join("bevy.png"));
    // The preview's PNG is clamped to [0, 1] (tone map none): so is Bevy's.
    let clamp = |p: &[f32; 4]| {
        [
            p[0].clamp(0.0, 1.0),
            p[1].clamp(0.0, 1.0),
            p[2].clamp(0.0, 1.0),
        ]
    };
    let (b, p) = (mean(got.iter().map(clamp)), mean(want.iter().copied()));
    // And the unsaturated pixels alone (the lamp is over 1 in both).
    let lit = |k: usize| want[k].iter().all(|&c| c < 0.99) && got[k][..3].iter().all(|&c| c < 0.99);
    let keep: Vec<usize> = (0..want.len()).filter(|&k| lit(k)).collect();
    let (b2, p2) = (
        mean(keep.iter().map(|&k| clamp(&got[k]))),
        mean(keep.iter().map(|&k| want[k])),
    );
    let ratio = |a: [f64; 3], b: [f64; 3]| (a[0] + a[1] + a[2]) / (b[0] + b[1] + b[2]);
    eprintln!(
        "{ktx2:?} pages: mean linear radiance: Bevy {b:.4?}, preview {p:.4?}, ratio {:.4}; unsaturated ({} px): Bevy {b2:.4?}, preview {p2:.4?}, ratio {:.4}",
        ratio(b, p),
        keep.len(),
        ratio(b2, p2)
    );
    for c in 0..3 {
        assert!(
            (b[c] / p[c] - 1.0).abs() <= 0.03,
            "channel {c}: Bevy mean {:.4} vs preview {:.4} (over 3 %)",
            b[c],
            p[c]
        );
    }
    assert!(
        (ratio(b2, p2) - 1.0).abs() <= 0.03,
        "unsaturated pixels differ by over 3 %"
    );
    assert!(keep.len() > want.len() / 2, "most pixels are not saturated");
}

#[test]
fn instances_of_one_mesh_get_their_own_rectangles() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("instances");
    // Cornell with its short block instanced twice more, at half size on
    // the floor by the front wall.
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(repo().join("scenes/cornell_box.gltf")).unwrap())
            .unwrap();
    let nodes = doc["nodes"].as_array().unwrap().clone();
    let (k, block) = nodes
        .iter()
        .enumerate()
        .find(|(_, n)| {
            n["name"]
                .as_str()
                .is_some_and(|s| s.to_lowercase().contains("short"))
        })
        .expect("a short block node");
    let mesh = block["mesh"].clone();
    let mut added = Vec::new();
    for (i, dx) in [(1, 0.0), (2, 0.33)] {
        let mut n = serde_json::json!({"name": format!("short_copy_{i}"), "mesh": mesh});
        n["translation"] = serde_json::json!([dx, 0.0, 0.0]);
        n["scale"] = serde_json::json!([0.5, 0.5, 0.5]);
        added.push(n);
    }
    let first = nodes.len();
    doc["nodes"].as_array_mut().unwrap().extend(added);
    doc["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .extend([first, first + 1].map(|i| serde_json::json!(i)));
    // (Its buffer is a data URI: the copy can live anywhere.)
    let gltf = dir.join("instances.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
    bake(&gltf, &dir, 20.0, radbake::config::Ktx2Mode::Rgb9e5);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    let rect_of = |node: &str| -> Rect {
        let i = manifest["instances"]
            .as_array()
            .unwrap()
            .iter()
            .find(|i| i["node"] == node)
            .unwrap_or_else(|| panic!("{node} not in the manifest"));
        let r: Vec<f32> = i["uv_rect"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap() as f32)
            .collect();
        Rect::new(r[0], r[1], r[2], r[3])
    };
    let run = run_bevy(&dir, false);
    assert!(
        run.applied.missing.is_empty(),
        "missing {:?}",
        run.applied.missing
    );
    let short = nodes[k]["name"].as_str().unwrap();
    let mut seen = Vec::new();
    for node in [short, "short_copy_1", "short_copy_2"] {
        let rects: Vec<Rect> = run
            .lightmaps
            .iter()
            .filter(|(n, _)| n == node)
            .map(|(_, r)| r.unwrap_or_else(|| panic!("{node} has no Lightmap")))
            .collect();
        assert!(!rects.is_empty(), "no mesh entity under {node}");
        let want = rect_of(node);
        for r in &rects {
            // uv_rect as Bevy packs it (unorm16) is not what we compare: the
            // component's own f32 rectangle is the manifest's.
            assert!(
                (r.min - want.min).abs().max_element() < 1e-6,
                "{node}: {r:?} vs {want:?}"
            );
            assert!(
                (r.max - want.max).abs().max_element() < 1e-6,
                "{node}: {r:?} vs {want:?}"
            );
        }
        seen.push(want);
    }
    for i in 0..seen.len() {
        for j in i + 1..seen.len() {
            assert_ne!(seen[i], seen[j], "instances {i} and {j} share a rectangle");
        }
    }
}

/// A bake folder whose manifest is not one, or names a file that is not
/// there: `RadbakeFailed` with the reason, not a hang.
#[test]
fn a_broken_bake_is_a_clear_error() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for (name, manifest, want) in [
        ("garbage", "{ this is not JSON", "not a radbake manifest"),
        (
            // Neither file is there: whichever is found missing first.
            "missing-files",
            r#"{"baked_gltf": "scene.baked.glb", "pages": [{"ktx2": "lightmap_0.ktx2"}], "instances": [], "probes": null}"#,
            "Path not found",
        ),
    ] {
        let dir = temp_dir(name);
        std::fs::write(dir.join("manifest.json"), manifest).unwrap();
        let mut app = App::new();
        app.add_plugins(headless_plugins(&dir))
            .add_plugins(RadbakePlugin::default())
            .add_systems(
                Startup,
                |mut commands: Commands, assets: Res<AssetServer>| {
                    commands.spawn(RadbakeBake::load(&assets, ""));
                },
            );
        app.finish();
        app.cleanup();
        // Loading is asynchronous: frames until the outcome, 60 s at most.
        let (mut failed, start) = (None, std::time::Instant::now());
        while start.elapsed().as_secs() < 60 {
            app.update();
            let world = app.world_mut();
            if let Some(f) = world.query::<&RadbakeFailed>().iter(world).next() {
                failed = Some(f.0.clone());
                break;
            }
        }
        let failed = failed.unwrap_or_else(|| panic!("{name}: no RadbakeFailed within 60 s"));
        eprintln!("{name}: {failed}");
        assert!(
            failed.contains(want),
            "{name}: {failed:?} does not mention {want:?}"
        );
    }
}

/// Light modes reach Bevy through the baked `.glb` (the light's node's
/// `extras.radbake.mode`): a baked point light is switched off for
/// lightmapped diffuse (the lightmap holds it), an `indirect` one keeps
/// lighting lightmapped meshes in real time (only its bounces are baked).
#[test]
fn indirect_lights_stay_on_for_lightmapped_meshes() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("modes");
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(repo().join("scenes/cornell_box.gltf")).unwrap())
            .unwrap();
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
        {"name": "bulb_baked", "type": "point", "intensity": 0.02},
        {"name": "bulb_live", "type": "point", "intensity": 0.02}]}});
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(
        serde_json::json!({"name": "baked", "translation": [0.2, 0.4, 0.3],
        "extensions": {"KHR_lights_punctual": {"light": 0}}}),
    );
    nodes.push(
        serde_json::json!({"name": "live", "translation": [0.35, 0.4, 0.3],
        "extras": {"radbake": {"mode": "indirect"}},
        "extensions": {"KHR_lights_punctual": {"light": 1}}}),
    );
    let n = nodes.len();
    doc["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .extend([n - 2, n - 1].map(|i| serde_json::json!(i)));
    let gltf = dir.join("modes.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
    bake(&gltf, &dir, 20.0, radbake::config::Ktx2Mode::Rgb9e5);
    let run = run_bevy(&dir, false);
    assert_eq!((run.applied.lights, run.applied.realtime_lights), (1, 1));
    let mut lights = run.point_lights.clone();
    lights.sort();
    assert_eq!(
        lights,
        vec![
            ("bulb_baked".to_owned(), false),
            ("bulb_live".to_owned(), true)
        ]
    );
}

/// A headless Bevy app that renders the bake in `dir` (with `weights` on
/// the bake entity, if any) from its glTF camera to the [`Target`], linear,
/// on a black background; finished, ready to update.
fn render_app(dir: &Path, weights: Option<RadbakeLayers>) -> App {
    let mut app = App::new();
    app.add_plugins(headless_plugins(dir).set(RenderPlugin {
        synchronous_pipeline_compilation: true,
        ..default()
    }))
    .add_plugins(ScheduleRunnerPlugin::default())
    .add_plugins(RadbakePlugin::default())
    .init_resource::<Captured>()
    .insert_resource(ClearColor(Color::BLACK))
    .add_systems(Update, aim_camera)
    .add_systems(
        Startup,
        move |mut commands: Commands,
              assets: Res<AssetServer>,
              mut images: ResMut<Assets<Image>>| {
            let mut image = Image::new_target_texture(SIZE, SIZE, TextureFormat::Rgba16Float, None);
            image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
            commands.insert_resource(Target(images.add(image)));
            let mut bake = commands.spawn(RadbakeBake::load(&assets, ""));
            if let Some(w) = &weights {
                bake.insert(w.clone());
            }
        },
    );
    app.finish();
    app.cleanup();
    app
}

/// A layered bake's two renders in one Bevy app, and the frame times
/// around the change of weights between them.
struct LayeredRun {
    first: Vec<[f32; 4]>,
    second: Vec<[f32; 4]>,
    /// Milliseconds per `App::update`: the 30 frames before the change,
    /// then every frame from the change to 5 after the new weights were
    /// applied.
    before: Vec<f64>,
    around: Vec<f64>,
    /// The recombination task's milliseconds.
    task_ms: f32,
}

/// Loads the bake in `dir` with `first` weights, renders it; sets
/// `second`, renders again once they are applied.
fn run_bevy_layers(dir: &Path, first: RadbakeLayers, second: RadbakeLayers) -> LayeredRun {
    let mut app = render_app(dir, Some(first.clone()));
    let captured = app.world().resource::<Captured>().clone();
    let generation = |app: &mut App| {
        let world = app.world_mut();
        world
            .query::<&RadbakeLayersApplied>()
            .iter(world)
            .next()
            .map_or((0, 0.0), |a| (a.generation, a.task_ms))
    };
    let mut shots: Vec<Vec<[f32; 4]>> = Vec::new();
    let (mut times, mut ready_at, mut changed_at, mut applied_at) = (Vec::new(), None, None, None);
    let mut task_ms = 0.0;
    for frame in 0..4000 {
        let t = std::time::Instant::now();
        app.update();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        let (g, ms) = generation(&mut app);
        if g == 1 && ready_at.is_none() {
            ready_at = Some(frame);
        }
        if g == 2 && applied_at.is_none() {
            applied_at = Some(frame);
            task_ms = ms;
        }
        let shoot = [ready_at, applied_at]
            .iter()
            .any(|r| r.is_some_and(|r| frame == r + 60));
        if shoot {
            let world = app.world_mut();
            read_back(world, &captured);
        }
        if let Some(bytes) = captured.0.lock().unwrap().take() {
            shots.push(rgba16f(&bytes));
            if shots.len() == 1 {
                // 40 frames more before the change: a quiet baseline.
                changed_at = Some(frame + 40);
            }
        }
        if changed_at == Some(frame) {
            let world = app.world_mut();
            let mut layers = world.query::<&mut RadbakeLayers>();
            *layers.single_mut(world).unwrap() = second.clone();
        }
        if shots.len() == 2 {
            break;
        }
    }
    assert_eq!(shots.len(), 2, "both renders within 4000 frames");
    let (c, a) = (changed_at.unwrap() + 1, applied_at.unwrap());
    LayeredRun {
        second: shots.pop().unwrap(),
        first: shots.pop().unwrap(),
        before: times[c - 30..c].to_vec(),
        around: times[c..=a + 5].to_vec(),
        task_ms,
    }
}

/// (mean of a / mean of b, 95th percentile of the per-pixel |a − b| /
/// max(b, 1 % of b's mean)), on the RGB mean of linear pixels clamped to
/// [0, 1] (the preview's PNG is).
fn agreement(a: &[[f32; 4]], b: &[[f32; 3]]) -> (f64, f64) {
    let lum = |p: &[f32]| p[..3].iter().map(|c| c.clamp(0.0, 1.0) as f64).sum::<f64>() / 3.0;
    let (sa, sb): (f64, f64) = (
        a.iter().map(|p| lum(p)).sum(),
        b.iter().map(|p| lum(p)).sum(),
    );
    let floor = 0.01 * sb / b.len() as f64;
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| (lum(x) - lum(y)).abs() / lum(y).max(floor))
        .collect();
    d.sort_by(f64::total_cmp);
    (sa / sb, d[d.len() * 95 / 100])
}

/// `RadbakeLayers` in Bevy's renderer: the Cornell box with its point
/// light in layer `lamp` (`scenes/cornell_layers.gltf`) at weight 0, then,
/// in the same app, 2; each against `radbake preview --layer` of the same
/// weight: mean within 3 %, 95th-percentile pixel difference ≤ 5 %. The
/// frames from the change to the new weights' application are timed
/// against the frames before it.
#[test]
fn layer_weights_recombine_as_the_preview_does() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("layers");
    bake(
        &repo().join("scenes/cornell_layers.gltf"),
        &dir,
        40.0,
        radbake::config::Ktx2Mode::Rgb9e5,
    );
    let glb = dir.join("scene.baked.glb");
    let mut want = Vec::new();
    for w in ["lamp=0", "lamp=2"] {
        let Some(p) = preview_at(&glb, &dir.join(format!("preview_{w}.png")), "camera", &[w])
        else {
            return no_adapter("Bevy layers vs preview");
        };
        want.push(p);
    }
    let run = run_bevy_layers(
        &dir,
        RadbakeLayers::default().with("lamp", Vec3::ZERO),
        RadbakeLayers::default().with("lamp", Vec3::splat(2.0)),
    );
    for (name, got, want) in [
        ("lamp=0", &run.first, &want[0]),
        ("lamp=2", &run.second, &want[1]),
    ] {
        save_png(got, &dir.join(format!("bevy_{name}.png")));
        let (mean, p95) = agreement(got, want);
        eprintln!(
            "{name}: Bevy / preview mean {mean:.4}, 95th-percentile pixel difference {:.2} %",
            100.0 * p95
        );
        assert!((mean - 1.0).abs() <= 0.03, "{name}: mean ratio {mean}");
        assert!(p95 <= 0.05, "{name}: 95th percentile {p95}");
    }
    let median = |v: &[f64]| {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let normal = median(&run.before);
    let worst = run.around.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "frames: median {normal:.2} ms before the change; {} frames from the change to 5 after the new weights, worst {worst:.2} ms ({:.2} ×); recombination task {:.2} ms",
        run.around.len(),
        worst / normal,
        run.task_ms
    );
}

/// The porch (`scenes/porch.gltf`: a floor, a wall and a roof under a sun)
/// with a camera, baked with its sun live and a sky of its own layer.
fn live_porch(dir: &Path) -> PathBuf {
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(repo().join("scenes/porch.gltf")).unwrap()).unwrap();
    let at = Transform::from_xyz(6.0, 3.0, 8.0).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
    doc["cameras"] = serde_json::json!([{"name": "camera", "type": "perspective",
        "perspective": {"yfov": 0.9, "aspectRatio": 1.0, "znear": 0.05, "zfar": 100.0}}]);
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"name": "camera", "camera": 0,
        "translation": at.translation.to_array(), "rotation": at.rotation.to_array()}));
    let n = nodes.len() - 1;
    doc["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!(n));
    let gltf = dir.join("porch.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = radbake::scene::load(&gltf, &Default::default()).unwrap();
    let mut config = radbake::BakeConfig {
        texels_per_meter: 8.0,
        ktx2: radbake::config::Ktx2Mode::Rgb9e5,
        sky: [0.3, 0.4, 0.55],
        ..Default::default()
    };
    config.light_modes.directional = Some(radbake::config::LightMode::Live);
    let mut scene = scene;
    config.light_modes.apply(&mut scene).unwrap();
    let bake = radbake::bake(&scene, &config, &radbake::Silent).unwrap();
    radbake::output::write_engine_outputs(dir, "scene", &bake).unwrap();
    dir.join("scene.baked.glb")
}

/// A live bake in Bevy: two renders, the sun as baked and then turned by
/// `turn` (its node's rotation), each once its solve is applied, and the
/// live solves' figures.
struct LiveRun {
    shots: Vec<Vec<[f32; 4]>>,
    solves: Vec<RadbakeLiveApplied>,
    /// Milliseconds per `App::update` from the turn to the solve's
    /// application, and the median before it.
    around: Vec<f64>,
    before: f64,
    /// The irradiance volumes' texels at the last shot (decoded RGB9E5).
    volumes: Vec<Vec<Vec3>>,
}

/// The texels of every `IrradianceVolume`'s image in `world`.
fn volume_texels(world: &mut World) -> Vec<Vec<Vec3>> {
    let handles: Vec<Handle<Image>> = world
        .query::<&bevy::light::IrradianceVolume>()
        .iter(world)
        .map(|v| v.voxels.clone())
        .collect();
    let images = world.resource::<Assets<Image>>();
    handles
        .iter()
        .map(|h| {
            let data = images
                .get(h)
                .and_then(|i| i.data.clone())
                .unwrap_or_default();
            (data.chunks_exact(4))
                .map(|c| {
                    bevy_radbake::layers::rgb9e5_to_rgb(u32::from_le_bytes(c.try_into().unwrap()))
                })
                .collect()
        })
        .collect()
}

fn run_bevy_live(dir: &Path, turn: Quat) -> LiveRun {
    let mut app = render_app(dir, None);
    let captured = app.world().resource::<Captured>().clone();
    let solved = |app: &mut App| {
        let world = app.world_mut();
        world
            .query::<&RadbakeLiveApplied>()
            .iter(world)
            .next()
            .cloned()
    };
    let (mut shots, mut solves, mut times) = (Vec::new(), Vec::new(), Vec::new());
    let (mut shoot_at, mut turned_at) = (None, None);
    for frame in 0..4000 {
        let t = std::time::Instant::now();
        app.update();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if let Some(s) = solved(&mut app) {
            if s.generation as usize > solves.len() {
                solves.push(s);
                shoot_at = Some(frame + 60);
                // The sun's direct light is Bevy's own (Burley diffuse and
                // GGX specular): the light on a render layer of its own,
                // so it lights nothing and the bounce light is alone.
                let world = app.world_mut();
                let suns: Vec<Entity> = world
                    .query_filtered::<Entity, With<DirectionalLight>>()
                    .iter(world)
                    .collect();
                for e in suns {
                    world
                        .entity_mut(e)
                        .insert(bevy::camera::visibility::RenderLayers::layer(1));
                }
            }
        }
        if shoot_at == Some(frame) {
            let world = app.world_mut();
            read_back(world, &captured);
        }
        if let Some(bytes) = captured.0.lock().unwrap().take() {
            shots.push(rgba16f(&bytes));
            shoot_at = None;
            if shots.len() == 1 {
                // Turn the sun's node: the light is its child.
                turned_at = Some(frame + 1);
                let world = app.world_mut();
                let mut q = world.query_filtered::<&ChildOf, With<DirectionalLight>>();
                let node = q.iter(world).next().expect("a directional light").parent();
                let mut at = world.get_mut::<Transform>(node).unwrap();
                at.rotation = turn * at.rotation;
            }
        }
        if shots.len() == 2 {
            break;
        }
    }
    if shots.len() < 2 {
        let world = app.world_mut();
        let failed: Vec<String> = world
            .query::<&RadbakeFailed>()
            .iter(world)
            .map(|f| f.0.clone())
            .collect();
        let errors: Vec<String> = world
            .query::<&bevy_radbake::RadbakeLayersError>()
            .iter(world)
            .map(|f| f.0.clone())
            .collect();
        let applied = world.query::<&RadbakeApplied>().iter(world).count();
        let layered = world.query::<&RadbakeLayersApplied>().iter(world).count();
        panic!("{} renders within 4000 frames, {} live solves; applied {applied}, layers applied {layered}, failed {failed:?}, errors {errors:?}", shots.len(), solves.len());
    }
    let c = turned_at.unwrap();
    let mut before = times[c - 30..c].to_vec();
    before.sort_by(f64::total_cmp);
    LiveRun {
        shots,
        solves,
        around: times[c..].to_vec(),
        before: before[before.len() / 2],
        volumes: volume_texels(app.world_mut()),
    }
}

/// Live radiosity in Bevy's renderer (`bevy_radbake::live`): the porch's
/// live sun as baked, then its node turned by 30° about +Y; once each solve
/// is applied, Bevy's image against `radbake preview --sun-direction` of
/// the same sun (the pages `radbake relight` writes): mean within 3 %,
/// 95th-percentile pixel difference ≤ 5 %. The sun's direct light is off
/// in both (Bevy draws it with its own Burley diffuse, the preview with
/// Lambert's): what is compared is the bounce and sky light the plugin
/// shows. The frames around the solve are timed, not asserted.
#[test]
fn live_sun_turns_as_the_preview_does() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("live");
    let glb = live_porch(&dir);
    let data = radbake_live::LiveData::read(&dir.join("live.bin")).unwrap();
    let baked = Vec3::from(data.header.lights[0].direction);
    let turn = Quat::from_rotation_y(30f32.to_radians());
    let turned = turn * baked;
    let mut want = Vec::new();
    for (name, sun) in [("baked", baked), ("turned", turned)] {
        let png = dir.join(format!("preview_{name}.png"));
        let Some(p) = preview_lit(&glb, &png, "camera", &[], Some(sun)) else {
            return no_adapter("Bevy live sun vs preview");
        };
        want.push(p);
    }
    let run = run_bevy_live(&dir, turn);
    assert!(run.solves.len() >= 2, "{:?}", run.solves);
    let last = run.solves.last().unwrap();
    assert!(
        last.direction.angle_between(turned) < 1e-3,
        "solved for {} , the sun turned to {turned}",
        last.direction
    );
    assert!(
        (last.irradiance - Vec3::from(data.header.lights[0].irradiance))
            .abs()
            .max_element()
            < 1e-3,
        "an untouched light keeps the baked irradiance: {}",
        last.irradiance
    );
    for (k, name) in ["baked", "turned"].iter().enumerate() {
        save_png(&run.shots[k], &dir.join(format!("bevy_{name}.png")));
        let (mean, p95) = agreement(&run.shots[k], &want[k]);
        eprintln!(
            "sun {name}: Bevy / preview mean {mean:.4}, 95th-percentile pixel difference {:.2} %",
            100.0 * p95
        );
        assert!((mean - 1.0).abs() <= 0.03, "{name}: mean ratio {mean}");
        assert!(p95 <= 0.05, "{name}: 95th percentile {p95}");
    }
    // The turn changed the picture (the bounce follows the sun).
    let (change, _) = agreement(&run.shots[1], &want[0]);
    eprintln!(
        "turned / baked mean {change:.4}; solve {:.2} ms ({} iterations); frames: median {:.2} ms before the turn, worst {:.2} ms until the solve was applied",
        last.solve_ms,
        last.iterations,
        run.before,
        run.around.iter().copied().fold(0.0, f64::max)
    );
    assert!(
        (change - 1.0).abs() > 0.01,
        "the turn changed nothing: {change}"
    );
    // The irradiance volumes follow the sun: Bevy's against the ambient
    // cubes of relight's probes at the turned sun, and away from the bake's.
    let relit = dir.join("relit");
    let r = radbake::output::relight::Relight {
        sun_direction: glam::Vec3::from_array(turned.to_array()),
        sun_irradiance: None,
        sky: None,
        weights: Vec::new(),
    };
    radbake::output::relight::relight(&dir, &r, &relit).unwrap();
    let cubes = |d: &Path| -> Vec<Vec3> {
        let probes = radbake::probes::Probes::read(&d.join("probes.json")).unwrap();
        let (_, texels) = radbake::output::probes::volume_texels(&probes, 0);
        texels
            .into_iter()
            .map(bevy_radbake::layers::rgb9e5_to_rgb)
            .collect()
    };
    let (want, baked) = (cubes(&relit), cubes(&dir));
    let bevy = &run.volumes[0];
    assert_eq!(bevy.len(), want.len());
    let l1 = |a: &[Vec3], b: &[Vec3]| -> f32 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (*x - *y).abs().element_sum())
            .sum::<f32>()
            / b.iter().map(|y| y.element_sum()).sum::<f32>()
    };
    let (off, moved) = (l1(bevy, &want), l1(&baked, &want));
    eprintln!(
        "irradiance volume: Bevy / relight's Σ|Δ| / Σ {off:.2e}; relight's / the bake's {moved:.2e}"
    );
    assert!(moved > 0.02, "the turn did not move the probes: {moved}");
    assert!(off < 0.01, "Bevy's volume off relight's by {off}");
}
