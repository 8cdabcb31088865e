//! Where a bake's texel noise comes from (issue #25): bakes the scene with
//! two seeds as `texel_noise` does, then prints the relative noise by
//! texel brightness and by the size of the texel's filter region (its
//! chart cut by burial planes), and, for every 20th texel of the noisiest
//! tenth, what 512 cosine rays from it meet (sky, sunlit surfaces,
//! shadowed surfaces, back faces) with their shares of the rays, of the
//! light and of its second moment, and the per-ray relative standard
//! deviation. A surface counts as sunlit where its direct light is more
//! than 30 % of its texel's value; a ray reads ρ × the hit texel's final
//! value, or the sky's radiance (a uniform `sky`).
//!
//!     cargo run --release --example noise_sources -- SCENE [KEY=VALUE ...]
//!
//! KEY=VALUE pairs are settings as in a `--config` TOML file.

mod common;

use glam::{Vec2, Vec3};
use radbake::surface::Landing;
use radbake::{BakeConfig, Silent};
use std::collections::HashMap;

/// One texel that `texel_noise` would count: its relative noise, its
/// value against the mean texel, its filter region's size, its index.
struct Noisy {
    noise: f64,
    value: f64,
    region: usize,
    texel: usize,
}

fn main() -> anyhow::Result<()> {
    let (scene, config) = common::scene_and_settings("noise_sources", "")?;
    let mut bakes = Vec::new();
    for seed in [config.seed, config.seed.wrapping_add(1)] {
        let c = BakeConfig {
            seed,
            ..config.clone()
        };
        bakes.push(radbake::bake(&scene, &c, &Silent)?);
    }
    let (a, b) = (&bakes[0], &bakes[1]);
    let tx = &a.texels;
    let lum = |v: Vec3| v.element_sum() as f64 / 3.0;
    let n = tx.len();
    let valid: Vec<bool> = (0..n)
        .map(|i| a.transport.valid[i] && b.transport.valid[i])
        .collect();
    let value = |i: usize| {
        (
            lum(a.maps.lightmaps.texel_values[i]),
            lum(b.maps.lightmaps.texel_values[i]),
        )
    };
    let count = valid.iter().filter(|&&v| v).count().max(1);
    let mean = (0..n)
        .filter(|&i| valid[i])
        .map(|i| value(i).0)
        .sum::<f64>()
        / count as f64;
    let region: Vec<u32> = (0..n).map(|t| a.burial.region(tx, t)).collect();
    let mut sizes: HashMap<(u32, u32, u32), usize> = HashMap::new();
    let key = |t: usize| (tx.instance[t], tx.chart[t], region[t]);
    for t in (0..n).filter(|&t| valid[t]) {
        *sizes.entry(key(t)).or_default() += 1;
    }
    let mut texels: Vec<Noisy> = (0..n)
        .filter(|&t| valid[t])
        .filter_map(|t| {
            let (x, y) = value(t);
            let m = 0.5 * (x + y);
            (m > 0.01 * mean).then(|| Noisy {
                noise: (x - y).abs() / (std::f64::consts::SQRT_2 * m),
                value: m / mean,
                region: sizes[&key(t)],
                texel: t,
            })
        })
        .collect();
    texels.sort_by(|x, y| x.noise.total_cmp(&y.noise));
    let k = texels.len().max(1);
    let p90 = texels[(k - 1) * 9 / 10].noise;
    println!(
        "{k} texels above 1 % of the mean ({mean:.4}): 90th percentile {:.2} %, {:.1} % above 3 %",
        p90 * 100.0,
        share(&texels, |_| true) * 100.0
    );
    let bands = [
        (0.01, 0.05),
        (0.05, 0.2),
        (0.2, 0.5),
        (0.5, 1.0),
        (1.0, 2.0),
    ];
    for (lo, hi) in bands.into_iter().chain([(2.0, f64::INFINITY)]) {
        buckets(&texels, &format!("value/mean {lo}–{hi}"), |t| {
            t.value >= lo && t.value < hi
        });
    }
    let regions = [(0, 10), (10, 25), (25, 50), (50, 100), (100, 1000)];
    for (lo, hi) in regions.into_iter().chain([(1000, usize::MAX)]) {
        let name = if hi == usize::MAX {
            format!("region of {lo} texels or more")
        } else {
            format!("region {lo}–{hi} texels")
        };
        buckets(&texels, &name, |t| t.region >= lo && t.region < hi);
    }
    let tail: Vec<&Noisy> = texels.iter().filter(|t| t.noise >= p90).collect();
    composition(a, &tail, lum(Vec3::from(config.sky)));
    Ok(())
}

/// The share of `texels` that `keep` picks whose noise is above 3 %.
fn share(texels: &[Noisy], keep: impl Fn(&Noisy) -> bool) -> f64 {
    let picked: Vec<_> = texels.iter().filter(|t| keep(t)).collect();
    picked.iter().filter(|t| t.noise > 0.03).count() as f64 / picked.len().max(1) as f64
}

/// Prints the texels `keep` picks: their share, noise median and 90th
/// percentile, and how many are above 3 %.
fn buckets(texels: &[Noisy], name: &str, keep: impl Fn(&Noisy) -> bool + Copy) {
    let mut v: Vec<f64> = texels.iter().filter(|t| keep(t)).map(|t| t.noise).collect();
    if v.is_empty() {
        return;
    }
    v.sort_by(f64::total_cmp);
    println!(
        "{name}: {:.1} % of the texels, noise median {:.2} %, 90th percentile {:.2} %, {:.1} % above 3 %",
        v.len() as f64 * 100.0 / texels.len() as f64,
        v[v.len() / 2] * 100.0,
        v[(v.len() - 1) * 9 / 10] * 100.0,
        share(texels, keep) * 100.0
    );
}

/// What 512 cosine rays from every 20th of `tail`'s texels meet.
fn composition(a: &radbake::pipeline::Bake, tail: &[&Noisy], sky: f64) {
    let tx = &a.texels;
    let rays = radbake::raycast::RayCaster::new(a.scene, &a.geometry);
    let s = a.surfaces(&rays);
    let lum = |v: Vec3| v.element_sum() as f64 / 3.0;
    let values = &a.maps.lightmaps.texel_values;
    let mut rng = radbake::util::sampling::Stream::new(7, 0, 0);
    // Per class (sky, sunlit, shadowed, back face): rays, light, second
    // moment, each as a share of its texel's, summed over texels.
    let (mut rays_of, mut light, mut moment) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
    let mut spread = Vec::new();
    for t in tail.iter().step_by(20) {
        let sampler = s.texel_sampler(t.texel as u32);
        let (mut sum, mut sq, mut cast) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
        let mut all = Vec::with_capacity(512);
        for _ in 0..512 {
            let (p, ng) = sampler.sample(rng.next_vec2());
            let u: Vec2 = rng.next_vec2();
            let dir = sampler.to_world(radbake::util::sampling::cosine_hemisphere(u));
            let origin = radbake::util::sampling::offset_ray_origin(p, ng);
            let (class, x) = match rays.closest_hit(origin, dir, f32::INFINITY) {
                None => (0, sky),
                Some(h) => match s.land(h.tri, h.u, h.v, dir) {
                    Landing::Texel(h) => {
                        let h = h as usize;
                        let v = lum(values[h]);
                        let sunlit = lum(a.transport.direct[h]) > 0.3 * v;
                        (if sunlit { 1 } else { 2 }, lum(tx.albedo[h]) * v)
                    }
                    _ => (3, 0.0),
                },
            };
            sum[class] += x;
            sq[class] += x * x;
            cast[class] += 1.0;
            all.push(x);
        }
        let total: f64 = sum.iter().sum();
        let total_sq: f64 = sq.iter().sum();
        for c in 0..4 {
            rays_of[c] += cast[c] / 512.0;
            if total > 0.0 {
                light[c] += sum[c] / total;
                moment[c] += sq[c] / total_sq;
            }
        }
        let m = total / 512.0;
        if m > 0.0 {
            let var = all.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / 511.0;
            spread.push(var.sqrt() / m);
        }
    }
    let norm = |v: [f64; 4]| {
        let s: f64 = v.iter().sum();
        v.map(|x| x / s.max(1e-30) * 100.0)
    };
    let (r, l, q) = (norm(rays_of), norm(light), norm(moment));
    println!(
        "{} texels of the noisiest tenth, 512 rays each (sky / sunlit / shadowed / back faces):",
        spread.len()
    );
    println!(
        "  rays {:.1} / {:.1} / {:.1} / {:.1} %",
        r[0], r[1], r[2], r[3]
    );
    println!("  light {:.1} / {:.1} / {:.1} %", l[0], l[1], l[2]);
    println!("  second moment {:.1} / {:.1} / {:.1} %", q[0], q[1], q[2]);
    spread.sort_by(f64::total_cmp);
    if !spread.is_empty() {
        println!(
            "  per-ray relative standard deviation: median {:.2}, 90th percentile {:.2}",
            spread[spread.len() / 2],
            spread[(spread.len() - 1) * 9 / 10]
        );
    }
}
