//! Opens a window on a radbake bake with a fly camera:
//!
//! ```sh
//! cargo run --release -p bevy_radbake --example view -- <bake dir> [--ev100 9.7]
//!     [--day SECONDS] [--screenshot shot.png [--frames 120]]
//! ```
//!
//! With `--day`, a live bake (`radbake bake --live`, docs/live.md) plays a
//! day in that many seconds, looping: the live sun's node is turned along
//! its sun path (or, for a bake over the hemisphere's grid, from east to
//! west through 60° up), and the plugin re-solves its bounce light in the
//! background as it turns; the window's title shows each solve's time.
//!
//! With `--screenshot`, the window is saved as a PNG after `--frames`
//! frames from the bake being applied, and the example exits (CI runs it so
//! under Xvfb).
//!
//! The bake folder is the asset root. The view starts at the glTF's first
//! camera (or looks at the scene from outside); WASD + mouse (hold the left
//! button) fly, Shift runs. The scene's lights keep their real-time
//! specular and shadows, but their diffuse light on lightmapped meshes is
//! switched off by the plugin, since the bake holds it.

use bevy::camera::Exposure;
use bevy::camera_controller::free_camera::{FreeCamera, FreeCameraPlugin};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::view::screenshot::{save_to_disk, Screenshot, ScreenshotCaptured};
use bevy_radbake::{
    RadbakeApplied, RadbakeBake, RadbakeLiveApplied, RadbakeManifest, RadbakePlugin,
};

#[derive(Resource)]
struct Ev100(f32);

/// `--day SECONDS`: a day's length.
#[derive(Resource)]
struct Day(f32);

/// `--screenshot PATH` after `--frames N` frames.
#[derive(Resource, Clone)]
struct Shot(std::path::PathBuf, u32);

fn main() {
    let mut args = std::env::args().skip(1);
    let mut dir = None;
    let mut ev100 = Exposure::EV100_BLENDER;
    let (mut shot, mut frames, mut day) = (None, 120u32, None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--screenshot" => {
                shot = Some(
                    args.next()
                        .unwrap_or_else(|| usage("--screenshot needs a path")),
                )
            }
            "--frames" => {
                frames = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or_else(|| usage("--frames needs a count"))
            }
            "--day" => {
                day = Some(
                    args.next()
                        .and_then(|v| v.parse::<f32>().ok())
                        .filter(|d| *d > 0.0)
                        .unwrap_or_else(|| usage("--day needs a length in seconds")),
                )
            }
            "--ev100" => {
                ev100 = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or_else(|| usage("--ev100 needs a number"))
            }
            _ if dir.is_none() => dir = Some(a),
            _ => usage(&format!("unexpected argument {a:?}")),
        }
    }
    let dir = dir.unwrap_or_else(|| usage("no bake folder given"));
    let root = std::fs::canonicalize(&dir).unwrap_or_else(|e| usage(&format!("{dir}: {e}")));
    if !root.join("manifest.json").exists() {
        usage(&format!(
            "{dir}: no manifest.json (not a radbake bake folder)"
        ));
    }
    let mut app = App::new();
    app.add_plugins(DefaultPlugins.set(AssetPlugin {
        file_path: root.to_string_lossy().into_owned(),
        ..default()
    }))
    .add_plugins((RadbakePlugin::default(), FreeCameraPlugin))
    .insert_resource(Ev100(ev100))
    .insert_resource(ClearColor(Color::BLACK))
    .add_systems(
        Startup,
        |mut commands: Commands, assets: Res<AssetServer>| {
            commands.spawn(RadbakeBake::load(&assets, ""));
        },
    )
    .add_systems(Update, fly_camera);
    if let Some(seconds) = day {
        app.insert_resource(Day(seconds))
            .add_systems(Update, play_day);
    }
    if let Some(path) = shot {
        app.insert_resource(Shot(path.into(), frames))
            .add_systems(Update, screenshot);
    }
    app.run();
}

/// `--frames` frames after the bake is applied: saves the window, then
/// exits.
fn screenshot(
    mut commands: Commands,
    shot: Res<Shot>,
    applied: Query<(), With<RadbakeApplied>>,
    mut count: Local<u32>,
) {
    if applied.is_empty() {
        return;
    }
    *count += 1;
    if *count == shot.1 {
        let path = shot.0.clone();
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path))
            .observe(
                |_: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
                    exit.write(AppExit::Success);
                },
            );
    }
}

fn usage(why: &str) -> ! {
    eprintln!("error: {why}\nusage: view <bake dir> [--ev100 EV] [--day SECONDS] [--screenshot PNG [--frames N]]");
    std::process::exit(2)
}

/// Once the bake is applied: a fly camera at the glTF's first camera, with
/// its projection (the glTF cameras are switched off), or looking at the
/// scene from outside.
fn fly_camera(
    mut commands: Commands,
    ev100: Res<Ev100>,
    applied: Query<Entity, Added<RadbakeApplied>>,
    children: Query<&Children>,
    mut cameras: Query<(&mut Camera, &GlobalTransform, &Projection)>,
    meshes: Query<&GlobalTransform, With<Mesh3d>>,
) {
    for root in &applied {
        let found: Vec<Entity> = children
            .iter_descendants(root)
            .filter(|e| cameras.contains(*e))
            .collect();
        let mut view = None;
        for &e in &found {
            let (mut camera, at, projection) = cameras.get_mut(e).unwrap();
            camera.is_active = false;
            view.get_or_insert((at.compute_transform(), projection.clone()));
        }
        let (transform, projection) = view.unwrap_or_else(|| {
            let (sum, n) = children
                .iter_descendants(root)
                .filter_map(|e| meshes.get(e).ok())
                .fold((Vec3::ZERO, 0.0f32), |(s, n), t| {
                    (s + t.translation(), n + 1.0)
                });
            let at = sum / n.max(1.0);
            let from = at + Vec3::new(0.0, 2.0, 8.0);
            (
                Transform::from_translation(from).looking_at(at, Vec3::Y),
                Projection::default(),
            )
        });
        commands.spawn((
            Camera3d::default(),
            transform,
            projection,
            FreeCamera::default(),
            Tonemapping::AcesFitted,
            Exposure { ev100: ev100.0 },
        ));
    }
}

/// `--day`: turns the live sun's node to where the sun is at this time of
/// the day (its `live.bin` path, or an east–west arc for a grid bake), and
/// shows the last solve in the title.
#[allow(clippy::too_many_arguments)] // a Bevy system's parameters
fn play_day(
    day: Res<Day>,
    time: Res<Time>,
    bakes: Query<(&RadbakeBake, Option<&RadbakeLiveApplied>), With<RadbakeApplied>>,
    manifests: Res<Assets<RadbakeManifest>>,
    suns: Query<&ChildOf, With<DirectionalLight>>,
    names: Query<&Name>,
    mut nodes: Query<&mut Transform>,
    mut windows: Query<&mut Window>,
) {
    for (bake, solved) in &bakes {
        let Some(m) = manifests.get(&bake.manifest) else {
            continue;
        };
        let Some(live) = m.live.as_ref() else {
            continue;
        };
        // The live light's glTF node: its layer's `lights`.
        let Some(layer) = m.layers.iter().find(|l| l.name == live.header.layer) else {
            continue;
        };
        let light = &live.header.lights[0];
        let f = (time.elapsed_secs() / day.0).fract();
        let towards = match &light.path {
            Some(path) => {
                let x = f * (path.len() - 1) as f32;
                let (i, t) = (x as usize, x.fract());
                let (a, b) = (
                    Vec3::from(path[i]),
                    Vec3::from(path[(i + 1).min(path.len() - 1)]),
                );
                a.lerp(b, t).normalize()
            }
            None => {
                let (e, a) = (
                    60f32.to_radians() * (std::f32::consts::PI * f).sin(),
                    std::f32::consts::PI * f,
                );
                Vec3::new(a.cos() * e.cos(), e.sin().max(0.02), -a.sin() * e.cos()).normalize()
            }
        };
        for parent in &suns {
            let node = parent.parent();
            if names
                .get(node)
                .is_ok_and(|n| layer.lights.iter().any(|l| l == n.as_str()))
            {
                if let Ok(mut t) = nodes.get_mut(node) {
                    // A DirectionalLight shines along −Z: +Z towards the sun.
                    t.rotation = Quat::from_rotation_arc(Vec3::Z, towards);
                }
            }
        }
        if let (Some(s), Ok(mut w)) = (solved, windows.single_mut()) {
            w.title = format!(
                "radbake day: {:.0} % from sunrise, sun {:.1}° up; solve {:.1} ms ({} iterations)",
                100.0 * f,
                s.direction.y.asin().to_degrees(),
                s.solve_ms,
                s.iterations
            );
        }
    }
}
