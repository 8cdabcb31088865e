//! Writes a scene's world triangles and a seeded set of incoherent rays to a
//! binary file, with radbake's answers (its BVH4/BVH8 over an obvhs build), and measures its
//! closest-hit and occlusion rays/s on them (one thread and all threads).
//! `tests/benches/embree_compare.py` casts the same rays with Embree.
//!
//!     cargo run --release --example dump_rays -- [scene.glb] --out rays.bin
//!     python3 tests/benches/embree_compare.py rays.bin
//!
//! Without a scene, the generated level of `--triangles` (as
//! `tools/gen_level.rs` writes it) is used.
//!
//! File layout (little-endian): `b"RBRAYS01"`; u32 triangles, closest-hit
//! rays, occlusion rays, rayon threads; f64 radbake rays/s: closest-hit on 1
//! and on all threads, occlusion on 1 and on all threads; f32 triangle
//! corners [n][3][3]; closest-hit rays
//! then occlusion rays, f32 [n][7] (origin, unit direction, tmax; tmax is
//! +∞ for closest-hit rays); radbake's hit distance per closest-hit ray, f32
//! (+∞ for a miss); radbake's occlusion per occlusion ray, u8 (1 = occluded).

#[path = "../tests/benches/common/mod.rs"]
mod common;

use clap::Parser;
use radbake::raycast::RayCaster;
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(
    about = "Dump a scene's triangles and incoherent rays; time radbake's ray caster on them"
)]
struct Args {
    /// The scene (.gltf/.glb); the generated level when left out.
    scene: Option<PathBuf>,
    /// Triangles of the generated level (without a scene).
    #[arg(long, default_value_t = 1_000_000)]
    triangles: u64,
    /// Rays of each kind (closest-hit and occlusion).
    #[arg(long, default_value_t = 1 << 18)]
    rays: usize,
    /// Timed runs of each measurement (the best is reported).
    #[arg(long, default_value_t = 3)]
    repeat: u32,
    /// obvhs build preset: fastest, very-fast, fast, medium (radbake's), slow or very-slow.
    #[arg(long, default_value = "medium")]
    bvh: String,
    /// BVH width: auto (8 with AVX2, else 4), 4 or 8.
    #[arg(long, default_value = "auto")]
    width: String,
    /// Output file.
    #[arg(long, short, default_value = "rays.bin")]
    out: PathBuf,
}

/// Best of `repeat` runs of `f`, in rays per second.
fn rate(repeat: u32, rays: usize, mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    rays as f64 / best
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let scene = match &args.scene {
        Some(path) => radbake::scene::load(path, &Default::default())?,
        None => common::level_scene(args.triangles),
    };
    let geometry = common::world_geometry(&scene);
    let t = Instant::now();
    let caster = RayCaster::with_width(
        &scene,
        &geometry,
        bvh_params(&args.bvh)?,
        width(&args.width)?,
    );
    let build = t.elapsed().as_secs_f64();
    let closest = common::surface_rays(&geometry, args.rays, common::SEED);
    let shadow = common::shadow_rays(&geometry, args.rays, common::SEED);
    // The answers, then the timings.
    let hit_t: Vec<f32> = (0..closest.len())
        .into_par_iter()
        .map(|i| {
            caster
                .closest_hit(closest.origin[i], closest.dir[i], closest.tmax[i])
                .map_or(f32::INFINITY, |h| h.t)
        })
        .collect();
    let occluded: Vec<u8> = (0..shadow.len())
        .into_par_iter()
        .map(|i| u8::from(!caster.unoccluded(shadow.origin[i], shadow.dir[i], shadow.tmax[i])))
        .collect();
    let rates = rates(&caster, &closest, &shadow, args.repeat);
    let bytes = file_bytes(&geometry, &closest, &shadow, (&hit_t, &occluded), rates);
    radbake::output::write_bytes_atomic(&args.out, &bytes)?;
    report(
        &args,
        &caster,
        (geometry.len(), build),
        (&hit_t, &occluded),
        rates,
    );
    Ok(())
}

/// obvhs's build preset by name.
fn bvh_params(name: &str) -> anyhow::Result<obvhs::BvhBuildParams> {
    use obvhs::BvhBuildParams as P;
    Ok(match name {
        "fastest" => P::fastest_build(),
        "very-fast" => P::very_fast_build(),
        "fast" => P::fast_build(),
        "medium" => P::medium_build(),
        "slow" => P::slow_build(),
        "very-slow" => P::very_slow_build(),
        other => anyhow::bail!("unknown --bvh preset `{other}`"),
    })
}

/// The BVH width by name.
fn width(name: &str) -> anyhow::Result<radbake::raycast::BvhWidth> {
    use radbake::raycast::BvhWidth;
    Ok(match name {
        "auto" => BvhWidth::Auto,
        "4" => BvhWidth::Four,
        "8" => BvhWidth::Eight,
        other => anyhow::bail!("unknown --width `{other}` (auto, 4 or 8)"),
    })
}

/// Rays/s: closest-hit on 1 and on all threads, occlusion on 1 and on all
/// threads (best of `repeat`).
fn rates(
    caster: &RayCaster,
    closest: &common::Rays,
    shadow: &common::Rays,
    repeat: u32,
) -> [f64; 4] {
    let n = closest.len();
    let sink = |v: u64| {
        std::hint::black_box(v);
    };
    let closest_one = |i: usize| {
        caster
            .closest_hit(closest.origin[i], closest.dir[i], closest.tmax[i])
            .is_some() as u64
    };
    let occluded_one =
        |i: usize| caster.unoccluded(shadow.origin[i], shadow.dir[i], shadow.tmax[i]) as u64;
    let c1 = rate(repeat, n, || sink((0..n).map(closest_one).sum()));
    let cn = rate(repeat, n, || {
        sink(
            (0..n)
                .into_par_iter()
                .with_min_len(256)
                .map(closest_one)
                .sum(),
        )
    });
    let o1 = rate(repeat, n, || sink((0..n).map(occluded_one).sum()));
    let on = rate(repeat, n, || {
        sink(
            (0..n)
                .into_par_iter()
                .with_min_len(256)
                .map(occluded_one)
                .sum(),
        )
    });

    [c1, cn, o1, on]
}

/// The file's bytes (layout in the module's documentation).
fn file_bytes(
    geometry: &radbake::layout::geometry::Geometry,
    closest: &common::Rays,
    shadow: &common::Rays,
    (hit_t, occluded): (&[f32], &[u8]),
    rates: [f64; 4],
) -> Vec<u8> {
    let threads = rayon::current_num_threads();
    let mut bytes: Vec<u8> = Vec::new();
    bytes.extend_from_slice(b"RBRAYS01");
    for v in [geometry.len(), closest.len(), shadow.len(), threads] {
        bytes.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for r in rates {
        bytes.extend_from_slice(&r.to_le_bytes());
    }
    let f32s = |bytes: &mut Vec<u8>, v: &[f32]| {
        for x in v {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    };
    for p in &geometry.p_ws {
        for c in p {
            f32s(&mut bytes, &c.to_array());
        }
    }
    for r in [closest, shadow] {
        for i in 0..r.len() {
            f32s(&mut bytes, &r.origin[i].to_array());
            f32s(&mut bytes, &r.dir[i].to_array());
            f32s(&mut bytes, &[r.tmax[i]]);
        }
    }
    f32s(&mut bytes, hit_t);
    bytes.extend_from_slice(occluded);
    bytes
}

/// What was written, the BVH's shape and the rates.
fn report(
    args: &Args,
    caster: &RayCaster,
    (triangles, build): (usize, f64),
    (hit_t, occluded): (&[f32], &[u8]),
    [c1, cn, o1, on]: [f64; 4],
) {
    let (n, threads) = (args.rays, rayon::current_num_threads());
    let hits = hit_t.iter().filter(|t| t.is_finite()).count();
    let blocked = occluded.iter().filter(|o| **o == 1).count();
    println!(
        "{}: {} triangles ({} BVH built in {:.3} s), {} closest-hit rays ({} hit), {} occlusion rays ({} occluded)",
        args.out.display(),
        triangles,
        args.bvh,
        build,
        n,
        hits,
        n,
        blocked
    );
    let st = caster.stats();
    println!(
        "BVH{}: {} nodes ({:.2} children each), {} leaves, {} packets ({:.2} triangles each), depth {}, SAH cost {:.1} box tests + {:.1} packet tests",
        caster.width(),
        st.nodes,
        st.used_slots as f64 / st.nodes.max(1) as f64,
        st.leaves,
        st.packets,
        st.triangles as f64 / st.packets.max(1) as f64,
        st.depth,
        st.sah_nodes,
        st.sah_packets
    );
    println!(
        "radbake closest-hit: {:.2} M rays/s on 1 thread, {:.2} M rays/s on {threads} threads",
        c1 / 1e6,
        cn / 1e6
    );
    println!(
        "radbake occlusion:   {:.2} M rays/s on 1 thread, {:.2} M rays/s on {threads} threads",
        o1 / 1e6,
        on / 1e6
    );
}
