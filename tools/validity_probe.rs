//! Why are texels judged invalid? Bakes a scene, then re-casts 64 rays from
//! each texel the bake judged invalid (inside or under geometry: more than
//! 10 % of its gather rays met back faces) and sorts them by what their
//! back-face hits look like:
//!
//! - *near*: every back face within `near` metres (burial: inside a wall,
//!   under a column or block);
//! - *far*: every back face further than that (one-sided open geometry
//!   seen from behind, which is not burial);
//! - *mixed*: both.
//!
//! It prints the counts overall and per instance (largest invalid area
//! first), the distribution of the back-face distances, and how enclosed
//! the invalid texels are: *sealed* where all 64 rays met back faces (a
//! cavity closed by one-sided shells, or the inside of a solid), *mostly*
//! where at least 90 % did, *open* where more than 10 % met front faces or
//! the sky.
//!
//!     cargo run --release --example validity_probe -- Sponza.lit.gltf texels_per_meter=4 near=0.5

use radbake::raycast::RayCaster;
use radbake::surface::{Landing, Surfaces};
use radbake::util::sampling::{cosine_hemisphere, offset_ray_origin, stratified, Stream};
use radbake::{BakeConfig, Silent};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or_else(|| anyhow::anyhow!("usage: validity_probe <scene> [key=value]..."))?;
    let mut near = 0.5f32;
    let mut toml = String::new();
    for a in args {
        match a.strip_prefix("near=") {
            Some(v) => near = v.parse()?,
            None => toml.push_str(&format!("{a}\n")),
        }
    }
    let config = BakeConfig::from_toml_over(&BakeConfig::default(), &toml)?;
    let scene = radbake::scene::load(path.as_ref(), &Default::default())?;
    let bake = radbake::bake(&scene, &config, &Silent)?;
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    // Per instance: (invalid area, near, far, mixed, none) areas.
    let mut per = vec![[0.0f64; 5]; scene.instances.len()];
    let mut dists: Vec<f32> = Vec::new();
    // Invalid area by enclosure (sealed, mostly, open), over all invalid
    // texels and over the far-only ones.
    let mut enclosure = [[0.0f64; 3]; 2];
    let (mut invalid, mut total) = (0u64, 0u64);
    for t in 0..bake.texels.len() {
        total += 1;
        if bake.transport.valid[t] {
            continue;
        }
        invalid += 1;
        let (n_near, n_far) = back_faces(&s, t, near, &mut dists);
        let a = bake.texels.area[t] as f64;
        let back = n_near + n_far;
        let e = if back == N {
            0
        } else if back * 10 >= N * 9 {
            1
        } else {
            2
        };
        enclosure[0][e] += a;
        if n_near == 0 && n_far > 0 {
            enclosure[1][e] += a;
        }
        let row = &mut per[bake.texels.instance[t] as usize];
        row[0] += a;
        let k = match (n_near > 0, n_far > 0) {
            (true, false) => 1,
            (false, true) => 2,
            (true, true) => 3,
            (false, false) => 4,
        };
        row[k] += a;
    }
    let sum: [f64; 5] = std::array::from_fn(|k| per.iter().map(|r| r[k]).sum());
    println!(
        "{invalid} of {total} texels invalid ({:.1} %); invalid area {:.1} m²: near-only {:.1} %, far-only {:.1} %, mixed {:.1} %, no back face in 64 rays {:.1} % (near = within {near} m)",
        100.0 * invalid as f64 / total as f64,
        sum[0],
        100.0 * sum[1] / sum[0],
        100.0 * sum[2] / sum[0],
        100.0 * sum[3] / sum[0],
        100.0 * sum[4] / sum[0]
    );
    for (label, e) in ["all invalid", "far-only"].iter().zip(&enclosure) {
        let sum: f64 = e.iter().sum();
        println!(
            "{label} ({sum:.1} m²): sealed {:.1} %, mostly (≥ 90 % back faces) {:.1} %, open {:.1} %",
            100.0 * e[0] / sum,
            100.0 * e[1] / sum,
            100.0 * e[2] / sum
        );
    }
    print_distances(&mut dists);
    let mut order: Vec<usize> = (0..per.len()).collect();
    order.sort_by(|&a, &b| per[b][0].total_cmp(&per[a][0]));
    println!("instance: invalid m² (near / far / mixed / none %)");
    for &i in order.iter().take(15) {
        let r = per[i];
        if r[0] <= 0.0 {
            break;
        }
        println!(
            "  {:<16} {:>9.1}  ({:.0} / {:.0} / {:.0} / {:.0})",
            scene.instances[i].node,
            r[0],
            100.0 * r[1] / r[0],
            100.0 * r[2] / r[0],
            100.0 * r[3] / r[0],
            100.0 * r[4] / r[0]
        );
    }
    Ok(())
}

/// Rays cast from each invalid texel.
const N: u32 = 64;

/// Texel `t`'s [`N`] cosine rays from points over it: how many meet a back
/// face within `near` metres and how many beyond; each such hit's distance
/// is added to `dists`.
fn back_faces(s: &Surfaces, t: usize, near: f32, dists: &mut Vec<f32>) -> (u32, u32) {
    let sampler = s.texel_sampler(t as u32);
    let mut rng = Stream::new(99, 77, t as u64);
    let (mut n_near, mut n_far) = (0u32, 0u32);
    for k in 0..N {
        let (p, ng) = sampler.sample(stratified(k, N, rng.next_vec2()));
        let dir = sampler.to_world(cosine_hemisphere(rng.next_vec2()));
        let o = offset_ray_origin(p, ng);
        if let (Landing::BackFace, Some(h)) = s.trace(o, dir) {
            dists.push(h.t);
            if h.t <= near {
                n_near += 1;
            } else {
                n_far += 1;
            }
        }
    }
    (n_near, n_far)
}

/// The back-face hits' distance percentiles.
fn print_distances(dists: &mut [f32]) {
    dists.sort_by(f32::total_cmp);
    let q = |f: f64| {
        dists
            .get(((dists.len() as f64 - 1.0) * f) as usize)
            .copied()
            .unwrap_or(0.0)
    };
    println!(
        "back-face hit distance (m): p10 {:.3}, p25 {:.3}, median {:.3}, p75 {:.3}, p90 {:.3} over {} hits",
        q(0.1),
        q(0.25),
        q(0.5),
        q(0.75),
        q(0.9),
        dists.len()
    );
}
