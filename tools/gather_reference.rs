//! Measures a bake against a high-sample reference of itself (issue #25's
//! "no bias" checks and the denoiser's error): the reference is the same
//! settings with `final_gather = ref_rays` (default 4096), every ray cast
//! (`gather_threshold = 0`) and no denoising; it is cached in `cache` (a
//! file of its texel values) so that several settings can be compared with
//! one reference. Prints, over the valid texels of both:
//!
//! - RMSE against the reference as a share of the mean texel, for all
//!   texels and for the shadowed ones (below half the mean);
//! - the median and 90th percentile of the relative error |a − r| / r of
//!   texels above 1 % of the mean (the reference's own noise included: at
//!   32 × the rays it is about a sixth of an unfiltered bake's);
//! - every instance's area-weighted mean against the reference's, for
//!   instances of at least `min_area` m² (default 10): the largest
//!   difference and how many differ by more than 0.5 %; with `detail=1`,
//!   the largest instance's texels that differ most;
//! - each such instance's standard error, from the gather's own variance
//!   estimate per texel (`TexelLight::variance`): Var(mean) = Σ a² var / (Σ
//!   a)², the bake's and the reference's added. The denoiser conserves each
//!   chart's power, so it does not change an instance's mean, and with the
//!   same seed the two bakes share every stage before the gather: the
//!   difference of the means is the two gathers' noise (and any bias). The
//!   issue's rule is "within 0.5 % or 3 standard errors"; the RMS of the
//!   instances' z-scores says whether the standard errors are right (about
//!   1 when they are and nothing is biased).
//!
//! Usage:
//!
//!     cargo run --release --example gather_reference -- SCENE \
//!         cache=/tmp/ref.bin [ref_rays=4096] [ref_seed=N] [min_area=10] [KEY=VALUE ...]
//!
//! `ref_only=1` stops once the reference is cached (to make a reference
//! of other settings, e.g. `ref=same method='"pathtrace"'
//! path_samples=16384`, then compare bakes of any settings with it).
//!
//! `ref_seed` bakes the reference with another seed (default: the
//! bake's): with the same seed, every stage before the gather draws the
//! same samples in both. `ref=same` makes the reference the bake's own
//! settings at `ref_seed`: the RMSE is then √2 × one bake's noise.
//!
//! KEY=VALUE pairs are settings as in a `--config` TOML file, applied to
//! both bakes (e.g. `texels_per_meter=4 'sky=[0.4,0.5,0.7]'`).

use glam::Vec3;
use radbake::{BakeConfig, Silent};
use std::time::Instant;

/// The command line: the scene, the reference's settings, what to print.
struct Args {
    path: String,
    cache: std::path::PathBuf,
    ref_rays: u32,
    min_area: f64,
    ref_seed: Option<u64>,
    same: bool,
    detail: bool,
    ref_only: bool,
    config: BakeConfig,
}

fn main() -> anyhow::Result<()> {
    let args = parse()?;
    let scene = radbake::scene::load(std::path::Path::new(&args.path), &Default::default())?;
    let reference = match read(&args.cache) {
        Some(r) => r,
        None => bake_reference(&scene, &args)?,
    };
    if args.ref_only {
        return Ok(());
    }
    let t = Instant::now();
    let b = radbake::bake(&scene, &args.config, &Silent)?;
    println!(
        "bake: {:.1} s, {} gather rays",
        t.elapsed().as_secs_f64(),
        b.transport.rays.gather
    );
    anyhow::ensure!(
        reference.len() == b.texels.len(),
        "the reference has {} texels, the bake {} (other settings?)",
        reference.len(),
        b.texels.len()
    );
    let valid: Vec<usize> = (0..reference.len())
        .filter(|&i| b.transport.valid[i] && reference[i].1)
        .collect();
    texel_errors(&b, &reference, &valid);
    instance_means(&scene, &b, &reference, &valid, &args);
    Ok(())
}

/// Luminance (the mean of the channels, as the gather's variance).
fn lum(v: Vec3) -> f64 {
    v.element_sum() as f64 / 3.0
}

fn parse() -> anyhow::Result<Args> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or_else(|| {
        anyhow::anyhow!("usage: gather_reference SCENE cache=FILE [ref_rays=N] [KEY=VALUE ...]")
    })?;
    let (mut cache, mut ref_rays, mut min_area) = (None, 4096u32, 10.0f64);
    let mut ref_seed = None;
    let (mut same, mut detail, mut ref_only) = (false, false, false);
    let mut toml = String::new();
    for a in args {
        match a.split_once('=') {
            Some(("cache", v)) => cache = Some(std::path::PathBuf::from(v)),
            Some(("ref_rays", v)) => ref_rays = v.parse()?,
            Some(("min_area", v)) => min_area = v.parse()?,
            Some(("ref_seed", v)) => ref_seed = Some(v.parse()?),
            Some(("ref", "same")) => same = true,
            Some(("detail", v)) => detail = v == "1",
            Some(("ref_only", v)) => ref_only = v == "1",
            _ => toml += &(a + "\n"),
        }
    }
    Ok(Args {
        path,
        cache: cache.ok_or_else(|| anyhow::anyhow!("cache=FILE is required"))?,
        ref_rays,
        min_area,
        ref_seed,
        same,
        detail,
        ref_only,
        config: BakeConfig::from_toml_over(&BakeConfig::default(), &toml)?,
    })
}

/// Bakes the reference and caches it in `args.cache`.
fn bake_reference(scene: &radbake::scene::Scene, args: &Args) -> anyhow::Result<Vec<Texel>> {
    let (config, ref_rays, same) = (&args.config, args.ref_rays, args.same);
    let t = Instant::now();
    let seed = args.ref_seed.unwrap_or(config.seed);
    let reference = if same {
        BakeConfig {
            seed,
            ..config.clone()
        }
    } else {
        BakeConfig {
            final_gather: ref_rays,
            gather_threshold: 0.0,
            denoise: false,
            seed,
            ..config.clone()
        }
    };
    let b = radbake::bake(scene, &reference, &Silent)?;
    println!(
        "reference ({}): {:.1} s",
        if same {
            format!("the bake's settings, seed {seed}")
        } else {
            format!("{ref_rays} rays")
        },
        t.elapsed().as_secs_f64()
    );
    let r: Vec<Texel> = (b.maps.lightmaps.texel_values.iter())
        .zip(&b.transport.valid)
        .enumerate()
        .map(|(i, (&v, &ok))| (v, ok, variance(&b.transport.variance, i)))
        .collect();
    write(&args.cache, &r)?;
    Ok(r)
}

/// RMSE against the reference (all texels, shadowed ones) and the
/// relative error's percentiles, over the `valid` texels.
fn texel_errors(b: &radbake::Bake, reference: &[Texel], valid: &[usize]) {
    let values = &b.maps.lightmaps.texel_values;
    let mean = valid.iter().map(|&i| lum(reference[i].0)).sum::<f64>() / valid.len() as f64;
    let rmse = |keep: &dyn Fn(f64) -> bool| {
        let (mut se, mut n, mut sum) = (0.0f64, 0usize, 0.0f64);
        for &i in valid {
            let r = lum(reference[i].0);
            if keep(r) {
                se += ((values[i] - reference[i].0).length_squared() / 3.0) as f64;
                sum += r;
                n += 1;
            }
        }
        ((se / n.max(1) as f64).sqrt(), sum / n.max(1) as f64, n)
    };
    let (all, _, n_all) = rmse(&|_| true);
    let (dark, dark_mean, n_dark) = rmse(&|r| r < 0.5 * mean);
    println!(
        "{n_all} valid texels: RMSE {:.3} % of the mean texel ({mean:.4}); shadowed (below half the mean, {n_dark}): RMSE {:.3} % of their mean ({dark_mean:.4})",
        100.0 * all / mean,
        100.0 * dark / dark_mean
    );
    let mut rel: Vec<f64> = (valid.iter())
        .filter_map(|&i| {
            let r = lum(reference[i].0);
            (r > 0.01 * mean).then(|| (lum(values[i]) - r).abs() / r)
        })
        .collect();
    rel.sort_by(f64::total_cmp);
    let pct = |p: f64| rel[((rel.len() - 1) as f64 * p) as usize] * 100.0;
    println!(
        "relative error against the reference (texels above 1 % of the mean): median {:.2} %, 90th percentile {:.2} %",
        pct(0.5),
        pct(0.9)
    );
}

/// Every instance's area-weighted mean against the reference's, with its
/// standard error (instances of at least `min_area` m²).
fn instance_means(
    scene: &radbake::scene::Scene,
    b: &radbake::Bake,
    reference: &[Texel],
    valid: &[usize],
    args: &Args,
) {
    let (min_area, detail) = (args.min_area, args.detail);
    let values = &b.maps.lightmaps.texel_values;
    // Instance means over the texels valid in both (area-weighted).
    let instances = scene.instances.len();
    // Per instance: Σ a·value, Σ a·reference, Σ a, Σ a²·(var + var_ref).
    let mut sums = vec![[0.0f64; 4]; instances];
    for &i in valid {
        let k = b.texels.instance[i] as usize;
        let a = b.texels.area[i] as f64;
        sums[k][0] += a * lum(values[i]);
        sums[k][1] += a * lum(reference[i].0);
        sums[k][2] += a;
        sums[k][3] += a * a * (variance(&b.transport.variance, i) + reference[i].2) as f64;
    }
    let mut worst: (f64, Option<usize>) = (0.0, None);
    let mut worst_z: (f64, f64, Option<usize>) = (0.0, 0.0, None);
    let (mut counted, mut off, mut beyond, mut z_sq) = (0, 0, 0, 0.0f64);
    for (k, &[x, r, area, var]) in sums.iter().enumerate() {
        if area < min_area || r <= 0.0 {
            continue;
        }
        counted += 1;
        let d = (x - r) / r;
        // Standard error of the difference of the two means.
        let se = var.sqrt() / area;
        let z = if se > 0.0 { (x - r) / area / se } else { 0.0 };
        z_sq += z * z;
        if d.abs() > 0.005 {
            off += 1;
            if z.abs() > 3.0 {
                beyond += 1;
                println!(
                    "  {}: {:+.3} %, {z:+.2} standard errors (standard error {:.3} % of its mean)",
                    scene.instances[k].node,
                    100.0 * d,
                    100.0 * se * area / r
                );
            }
        }
        if d.abs() > worst.0.abs() {
            worst = (d, Some(k));
        }
        if z.abs() > worst_z.0.abs() {
            worst_z = (z, d, Some(k));
        }
    }
    let name = |k: Option<usize>| k.map_or(String::new(), |k| scene.instances[k].node.clone());
    if let (true, Some(k)) = (detail, worst.1) {
        let mut d: Vec<(f64, f64, f64, f32, usize)> = valid
            .iter()
            .filter(|&&i| b.texels.instance[i] as usize == k)
            .map(|&i| {
                (
                    lum(values[i]) - lum(reference[i].0),
                    lum(values[i]),
                    lum(reference[i].0),
                    b.texels.area[i],
                    i,
                )
            })
            .collect();
        d.sort_by(|a, b| {
            (b.0 * b.3 as f64)
                .abs()
                .total_cmp(&(a.0 * a.3 as f64).abs())
        });
        println!(
            "{}: {} texels; largest area-weighted differences:",
            name(Some(k)),
            d.len()
        );
        for x in d.iter().take(8) {
            println!(
                "  texel {} value {:.4} ref {:.4} area {:.4} diff×area {:.5}",
                x.4,
                x.1,
                x.2,
                x.3,
                x.0 * x.3 as f64
            );
        }
        let pos: f64 = d
            .iter()
            .filter(|x| x.0 > 0.0)
            .map(|x| x.0 * x.3 as f64)
            .sum();
        let neg: f64 = d
            .iter()
            .filter(|x| x.0 < 0.0)
            .map(|x| x.0 * x.3 as f64)
            .sum();
        println!("  Σ diff×area: {pos:+.4} and {neg:+.4}");
    }
    println!(
        "{counted} instances of at least {min_area} m²: {off} differ from the reference by more than 0.5 %; largest {:+.3} % ({})",
        100.0 * worst.0,
        name(worst.1)
    );
    println!(
        "standard errors: {beyond} of the {off} differ by more than 3 as well (the issue's rule: within 0.5 % or 3 standard errors); largest {:+.2} ({}, {:+.3} %); RMS of the z-scores {:.2}",
        worst_z.0,
        name(worst_z.2),
        100.0 * worst_z.1,
        (z_sq / counted.max(1) as f64).sqrt()
    );
}

/// A reference texel: its value, validity and the gather's variance of it.
type Texel = (Vec3, bool, f32);

/// Texel `i`'s gather variance (0 without a final gather).
fn variance(v: &[f32], i: usize) -> f32 {
    v.get(i).copied().unwrap_or(0.0)
}

/// The cached reference: per texel, its value, validity and variance.
fn read(path: &std::path::Path) -> Option<Vec<Texel>> {
    let bytes = std::fs::read(path).ok()?;
    let out: Vec<Texel> = bytes
        .chunks_exact(17)
        .map(|c| {
            let f = |k: usize| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap());
            (Vec3::new(f(0), f(1), f(2)), c[12] != 0, {
                f32::from_le_bytes(c[13..17].try_into().unwrap())
            })
        })
        .collect();
    (bytes.len() % 17 == 0).then_some(out)
}

fn write(path: &std::path::Path, r: &[Texel]) -> anyhow::Result<()> {
    let mut bytes = Vec::with_capacity(r.len() * 17);
    for (v, ok, var) in r {
        for c in v.to_array() {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
        bytes.push(u8::from(*ok));
        bytes.extend_from_slice(&var.to_le_bytes());
    }
    std::fs::write(path, bytes)?;
    Ok(())
}
