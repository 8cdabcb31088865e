//! Measures a bake's texel noise: bakes the scene twice with different seeds
//! and compares every valid texel. For two independent estimates a and b of
//! the same value, σ ≈ |a − b| / √2, so each texel's relative noise is
//! |a − b| / (√2 · (a + b)/2) on the RGB mean. Texels darker than 1 % of the
//! scene's mean texel are left out (their relative noise means nothing).
//!
//!     cargo run --release --example texel_noise -- SCENE [KEY=VALUE ...]
//!
//! KEY=VALUE pairs are settings as in a `--config` TOML file, e.g.
//! `texels_per_meter=4 'sky=[0.4,0.5,0.7]'`.

mod common;

use radbake::{BakeConfig, Silent};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let (scene, config) = common::scene_and_settings("texel_noise", "")?;
    let mut bakes = Vec::new();
    for seed in [config.seed, config.seed.wrapping_add(1)] {
        let t = Instant::now();
        let b = radbake::bake(
            &scene,
            &BakeConfig {
                seed,
                ..config.clone()
            },
            &Silent,
        )?;
        println!("seed {seed}: {:.1} s", t.elapsed().as_secs_f64());
        bakes.push(b);
    }
    let (a, b) = (&bakes[0], &bakes[1]);
    let valid: Vec<usize> = (0..a.maps.lightmaps.texel_values.len())
        .filter(|&i| a.transport.valid[i] && b.transport.valid[i])
        .collect();
    let lum = |v: glam::Vec3| v.element_sum() as f64 / 3.0;
    // Each valid texel's (luminance in bake a, in bake b).
    let pairs: Vec<(f64, f64)> = valid
        .iter()
        .map(|&i| {
            (
                lum(a.maps.lightmaps.texel_values[i]),
                lum(b.maps.lightmaps.texel_values[i]),
            )
        })
        .collect();
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len().max(1) as f64;
    // Relative noise of the texels brighter than `floor` × the mean.
    let relative = |floor: f64| -> Vec<f64> {
        pairs
            .iter()
            .filter_map(|&(x, y)| {
                let m = 0.5 * (x + y);
                (m > floor * mean).then(|| (x - y).abs() / (std::f64::consts::SQRT_2 * m))
            })
            .collect()
    };
    let rms = |v: &[f64]| (v.iter().map(|r| r * r).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let mut rel = relative(0.01);
    // Absolute noise against the mean texel (the denoiser's RMSE measure),
    // and the relative noise of texels brighter than 10 % of the mean.
    let abs_rms = (pairs
        .iter()
        .map(|(x, y)| (x - y).powi(2) / 2.0)
        .sum::<f64>()
        / pairs.len().max(1) as f64)
        .sqrt();
    let bright = relative(0.1);
    println!(
        "noise RMS against the mean texel {:.2} %; texels above 10 % of the mean: {}, relative noise RMS {:.2} %",
        abs_rms / mean * 100.0,
        bright.len(),
        rms(&bright) * 100.0
    );
    rel.sort_by(f64::total_cmp);
    let n = rel.len().max(1);
    let pct = |p: f64| {
        rel.get(((n - 1) as f64 * p) as usize)
            .copied()
            .unwrap_or(0.0)
            * 100.0
    };
    println!(
        "{} valid texels, {} above 1 % of the mean ({mean:.4}): relative noise RMS {:.2} %, median {:.2} %, 90th percentile {:.2} %, {:.1} % of texels under 1 %",
        valid.len(),
        rel.len(),
        rms(&rel) * 100.0,
        pct(0.5),
        pct(0.9),
        rel.iter().filter(|&&r| r < 0.01).count() as f64 * 100.0 / n as f64
    );
    // Where the noise is: the direct part (sampled lights, and the sky and
    // emitters the gather's rays see) and the rest (the gathered indirect
    // light), each against the texel's total, before seams and filling.
    let (ta, tb) = (&a.transport, &b.transport);
    let mut parts: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for &i in &valid {
        let m = 0.5 * (lum(ta.values[i]) + lum(tb.values[i]));
        if m <= 0.01 * mean || ta.direct.is_empty() {
            continue;
        }
        let (da, db) = (lum(ta.direct[i]), lum(tb.direct[i]));
        let (ia, ib) = (lum(ta.values[i]) - da, lum(tb.values[i]) - db);
        parts[0].push((da - db).abs() / (std::f64::consts::SQRT_2 * m));
        parts[1].push((ia - ib).abs() / (std::f64::consts::SQRT_2 * m));
    }
    for (name, v) in ["direct", "indirect"].iter().zip(parts.iter_mut()) {
        v.sort_by(f64::total_cmp);
        let n = v.len().max(1);
        let at = |p: f64| v.get(((n - 1) as f64 * p) as usize).copied().unwrap_or(0.0) * 100.0;
        println!(
            "  {name} part, against the texel's total: median {:.2} %, 90th percentile {:.2} %",
            at(0.5),
            at(0.9)
        );
    }
    Ok(())
}
