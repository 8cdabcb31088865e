//! BDPT against unidirectional path tracing at equal time, on the Cornell
//! box as shipped (lamp facing down) and with its lamp turned to face the
//! ceiling (all light arrives by a bounce off a small bright spot: the case
//! BDPT is for). Prints, per scene and integrator, samples per pixel, time,
//! the image mean and the mean per-pixel variance of the mean, and the
//! efficiency 1 / (variance × time).
//!
//!     cargo run --release --example bdpt_vs_path [-- SIZE SECONDS]

use glam::Vec3;
use radbake::layout::geometry::Geometry;
use radbake::raycast::RayCaster;
use radbake::trace::render::{render, Integrator, View};
use radbake::trace::Tracer;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let size: u32 = args.next().map_or(Ok(64), |s| s.parse())?;
    let seconds: f64 = args.next().map_or(Ok(5.0), |s| s.parse())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenes/cornell_box.gltf"))?;
    let mut doc: serde_json::Value = serde_json::from_str(&text)?;
    // The lamp (in the plane y = 0.5483, centred at z = 0.2795) turned over
    // by R_x(180°) and lowered to y = 0.52, 3 cm under the ceiling: the
    // room is lit by a small hot spot.
    let flipped = serde_json::json!([
        1.0,
        0.0,
        0.0,
        0.0, //
        0.0,
        -1.0,
        0.0,
        0.0, //
        0.0,
        0.0,
        -1.0,
        0.0, //
        0.0,
        0.52 + 0.5483,
        2.0 * 0.2795,
        1.0
    ]);
    let dir = std::env::temp_dir().join(format!("radbake-bdpt-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let shipped = root.join("scenes/cornell_box.gltf");
    for node in doc["nodes"].as_array_mut().expect("nodes") {
        if node["name"] == "light" {
            node["matrix"] = flipped.clone();
        }
    }
    let up = dir.join("cornell_lamp_up.gltf");
    std::fs::write(&up, serde_json::to_vec(&doc)?)?;

    println!("scene             integrator  spp   time s   mean (R)   mean var     efficiency");
    for (name, path) in [("lamp down", shipped.as_path()), ("lamp up", up.as_path())] {
        let scene = radbake::scene::load(path, &Default::default())?;
        let g = Geometry::unmapped(&scene);
        let rays = RayCaster::new(&scene, &g);
        let tracer = Tracer::new(&scene, &g, &rays, Vec3::ZERO);
        let view = View::from_camera(&scene.cameras[0]);
        for integrator in [Integrator::Path, Integrator::Bdpt] {
            // Calibrate the samples per pixel to the time budget.
            let t = Instant::now();
            render(&tracer, &view, (size, size), 4, integrator, 1, &|_| {});
            let per_spp = t.elapsed().as_secs_f64() / 4.0;
            let spp = ((seconds / per_spp) as u32).max(4);
            let t = Instant::now();
            let img = render(&tracer, &view, (size, size), spp, integrator, 2, &|_| {});
            let secs = t.elapsed().as_secs_f64();
            let var =
                img.variance.iter().map(|v| v.x as f64).sum::<f64>() / img.variance.len() as f64;
            println!(
                "{name:<17} {:<10} {spp:>5} {secs:>8.2} {:>10.5} {var:>12.4e} {:>12.4e}",
                format!("{integrator:?}"),
                img.mean().x,
                1.0 / (var * secs)
            );
        }
    }
    Ok(())
}
