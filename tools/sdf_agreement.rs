//! Sphere tracing against ray casting on any scene (issue #24): bakes the
//! signed distance field at `resolution` voxels along the longest side,
//! casts `rays` random rays from its open air (as `tests/sdf.rs` does on
//! the Cornell box: [`radbake::sdf::agreement::random_rays`]) both ways,
//! and prints the share that agree (both miss, or hit within one voxel),
//! the rest by class ([`radbake::sdf::agreement::Class`]) with the
//! materials where they part, the grid, the bake's time and memory. A
//! measurement, not a test: Sponza is not in the repository.
//!
//!     mkdir -p /tmp/spz && cp -rL /work/shared/scenes/real/sponza/* /tmp/spz/
//!     cargo run --release --no-default-features --example sdf_agreement -- \
//!         /tmp/spz/Sponza.gltf resolution=256 rays=100000

use radbake::sdf::agreement::{compare, random_rays, Class};
use radbake::sdf::{self, Settings};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or_else(|| {
        anyhow::anyhow!("usage: sdf_agreement <scene> [resolution=256] [rays=100000] [seed=7]")
    })?;
    let (mut resolution, mut n, mut seed) = (256u32, 100_000usize, 7u64);
    for a in args {
        match a.split_once('=') {
            Some(("resolution", v)) => resolution = v.parse()?,
            Some(("rays", v)) => n = v.parse()?,
            Some(("seed", v)) => seed = v.parse()?,
            _ => anyhow::bail!("unknown argument {a}"),
        }
    }
    let scene = radbake::scene::load(path.as_ref(), &Default::default())?;
    let g = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &g);
    let bounds = g.bounds().ok_or_else(|| anyhow::anyhow!("no triangles"))?;
    let voxel = sdf::voxel_for_resolution(bounds, resolution);
    // The peak from here on is the bake's (Linux: writing 5 to
    // clear_refs resets VmHWM to the current RSS).
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let before = memory("VmRSS:");
    let start = Instant::now();
    let field = sdf::bake(&scene, &g, &rays, Settings { voxel, band: None });
    let seconds = start.elapsed().as_secs_f64();
    let [x, y, z] = field.grid.dims;
    println!(
        "{path}: {} triangles; {x} × {y} × {z} = {} voxels of {voxel:.4} m baked in {seconds:.2} s ({} threads, {} sign rays); memory {} before the bake (scene, BVH), peak {} during it",
        g.len(),
        field.grid.len(),
        rayon::current_num_threads(),
        field.rays,
        before,
        memory("VmHWM:")
    );
    let start = Instant::now();
    let list = random_rays(&field, bounds, seed, n);
    let outcomes: Vec<_> = list
        .par_iter()
        .map(|&(o, d)| compare(&scene, &g, &rays, &field, o, d))
        .collect();
    let agree = outcomes.iter().filter(|o| o.class.is_none()).count();
    let misses = outcomes.iter().filter(|o| o.cast.is_none()).count();
    println!(
        "{agree} of {n} rays agree ({:.3} %; {misses} BVH misses); {:.2} s",
        100.0 * agree as f64 / n as f64,
        start.elapsed().as_secs_f64()
    );
    // Per class: rays, and rays by the material of the surface where the
    // march and the BVH parted (the nearest one to where the march
    // stopped short, or the BVH's hit).
    let mut classes: BTreeMap<Class, (usize, BTreeMap<String, usize>)> = BTreeMap::new();
    let v = field.grid.voxel;
    for (o, &(org, d)) in outcomes.iter().zip(&list) {
        let Some(c) = o.class else { continue };
        let tri = if o.early {
            let p = org + d * o.marched.unwrap_or(0.0);
            rays.closest_point(p, 4.0 * v * v).map(|h| h.0)
        } else {
            rays.closest_hit(org, d, f32::INFINITY).map(|h| h.tri)
        };
        let name = tri.map_or("-".into(), |t| {
            scene.materials[g.material[t as usize] as usize]
                .name
                .clone()
        });
        let e = classes.entry(c).or_default();
        e.0 += 1;
        *e.1.entry(name).or_default() += 1;
    }
    for c in Class::ALL {
        if let Some((count, by)) = classes.get(&c) {
            let mut by: Vec<_> = by.iter().collect();
            by.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
            let top: Vec<String> = by.iter().take(4).map(|(m, k)| format!("{m} {k}")).collect();
            println!(
                "  {count:6} ({:.3} %)  {}; materials: {}",
                100.0 * *count as f64 / n as f64,
                c.describe(),
                top.join(", ")
            );
        }
    }
    Ok(())
}

/// A line of `/proc/self/status` (`VmRSS:` now, `VmHWM:` the peak), or
/// "unknown".
fn memory(key: &str) -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .map(|l| l[key.len()..].trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into())
}
