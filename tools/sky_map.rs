//! Writes a procedural equirectangular sky map (linear float EXR) for
//! `radbake bake --sky-map`: a clear-sky gradient (horizon to zenith), a
//! dim ground below the horizon and a bright glow of 3° around a sun
//! direction, in radbake's convention (row 0 the zenith, the image centre
//! −X; see `radbake::light::sky`). Its mean radiance over the upper hemisphere is
//! near the `--sky 0.4,0.5,0.7` of the Sponza figures.
//!
//! `cargo run --release --example sky_map -- OUT.exr [WIDTH]`

use glam::Vec3;
use std::f32::consts::PI;

fn main() {
    let mut args = std::env::args().skip(1);
    let out = args.next().expect("usage: sky_map OUT.exr [WIDTH]");
    let width: u32 = args.next().map_or(1024, |w| w.parse().expect("WIDTH"));
    let height = width / 2;
    // The glow's direction: 50° above the horizon, towards +X +Z.
    let sun = Vec3::new(0.45, 0.766, 0.45).normalize();
    let mut px = Vec::with_capacity((width * height) as usize);
    for row in 0..height {
        let theta = (row as f32 + 0.5) / height as f32 * PI;
        for col in 0..width {
            // The inverse of u = 0.5 + atan2(−z, −x) / 2π, v = θ / π.
            let phi = ((col as f32 + 0.5) / width as f32 - 0.5) * 2.0 * PI;
            let d = Vec3::new(
                -theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            );
            px.push(radiance(d, sun));
        }
    }
    radbake::output::write_exr_rgb(out.as_ref(), width, height, &px).expect("write the EXR");
    println!("{out}: {width} × {height}");
}

/// Sky radiance towards `d`: the gradient, the ground, the glow.
fn radiance(d: Vec3, sun: Vec3) -> Vec3 {
    let horizon = Vec3::new(0.75, 0.8, 0.85);
    let zenith = Vec3::new(0.25, 0.4, 0.75);
    let mut l = if d.y >= 0.0 {
        horizon.lerp(zenith, d.y.sqrt())
    } else {
        Vec3::new(0.12, 0.11, 0.1)
    };
    let angle = d.dot(sun).clamp(-1.0, 1.0).acos().to_degrees();
    if angle < 3.0 {
        l += Vec3::new(60.0, 55.0, 45.0) * (1.0 - angle / 3.0);
    }
    l
}
