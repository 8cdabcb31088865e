//! Live radiosity against full bakes: a scene baked once with its sun
//! live, relit by the run time ([`radbake_live::Live`]) for suns off the
//! precomputed grid, each compared with a full bake (final gather and
//! all) with the sun in mode `indirect` at that direction.
//!
//! Per instance of at least `min_area` m² it prints the area-weighted mean
//! of the valid texels of the whole lightmap (every layer: what an engine
//! shows, less the sun's direct light) in the full bake and relit, and
//! splits the difference in two: *gather*, the patch solution at the
//! exact visibility for that sun against the full bake (what the missing
//! final gather costs); *interpolation*, the relit one against the patch
//! solution at the exact visibility (what the sun table's directions and
//! bytes cost). Also the texel RMSE (over valid texels, % of the mean
//! texel) and the update's time. And the probes: the live layer's moved
//! by the run time's change ([`Live::probe_delta`]) against the full
//! bake's, as Σ|ΔE| / ΣE over the valid probes' six axis irradiances,
//! beside the bake's probes as they were.
//!
//! With `meter=N`, each of those instances is also read by the meter
//! ([`radbake::trace::measure`], N samples per node) on the scene with the
//! sun in mode `indirect` there, and the relit and full bake's `mean`
//! (over exposed texels, as `report.json`'s) are compared with it.
//!
//! With `sun_path = {latitude, day}` the tables are made along that day's
//! path (256 samples) and the suns are three midpoints between samples
//! (at 30 %, 50 % and 70 % of the day); without, over the hemisphere's
//! grid, for three suns off its nodes.
//!
//!     cargo run --release --example live_accuracy -- Sponza.lit.gltf texels_per_meter=4 'sky=[0.4,0.5,0.7]' 'sun_path={latitude=42.6,day=172}' meter=100000

use glam::Vec3;
use radbake::config::LightMode;
use radbake::light::sun_table::patch_direct;
use radbake::raycast::RayCaster;
use radbake::{BakeConfig, Silent};
use radbake_live::{Live, Sun};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or_else(|| {
        anyhow::anyhow!("usage: live_accuracy <scene> [min_area=10] [key=value]...")
    })?;
    let mut min_area = 10.0f64;
    let mut meter_samples = 0u64;
    let mut toml = String::new();
    for a in args {
        if let Some(v) = a.strip_prefix("min_area=") {
            min_area = v.parse()?;
        } else if let Some(v) = a.strip_prefix("meter=") {
            meter_samples = v.parse()?;
        } else {
            toml.push_str(&format!("{a}\n"));
        }
    }
    let mut config = BakeConfig::from_toml_over(&BakeConfig::default(), &toml)?;
    let mut scene = radbake::scene::load(path.as_ref(), &Default::default())?;
    let sun = (scene.lights.iter())
        .position(|l| l.kind == radbake::scene::LightKind::Directional)
        .ok_or_else(|| anyhow::anyhow!("{path}: no directional light"))?;
    let name = scene.lights[sun].name.clone();
    let mut full_config = config.clone();
    config
        .light_modes
        .lights
        .insert(name.clone(), LightMode::Live);
    config.light_modes.apply(&mut scene)?;
    full_config
        .light_modes
        .lights
        .insert(name, LightMode::Indirect);
    let start = Instant::now();
    let bake = radbake::bake(&scene, &config, &Silent)?;
    println!("live bake: {:.2} s", start.elapsed().as_secs_f64());
    let data = bake.live.clone().expect("a live bake writes live data");
    let layers = bake.layers.as_ref().expect("a live bake has layers");
    let live_k = layers.names.iter().position(|n| n == "live").unwrap();
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let baked = scene.lights[sun].clone();
    let irradiance = baked.intensity;
    let suns: Vec<Vec3> = match config.sun_path {
        Some(p) => {
            // Midpoints between the table's samples: the odd samples of a
            // path of 2n − 1.
            let fine = radbake::scene::sun_path::SunPath::Day {
                latitude: p.latitude,
                day: p.day,
                samples: 2 * p.samples - 1,
            };
            let d = fine.directions().map_err(anyhow::Error::msg)?;
            let odd = |f: f64| ((f * (d.len() - 1) as f64) as usize) | 1;
            [0.3, 0.5, 0.7].map(|f| d[odd(f)]).to_vec()
        }
        // Three suns off the grid's nodes: elevation, azimuth (degrees).
        None => [(33.0f32, 17.0f32), (52.0, 128.0), (71.0, 241.0)]
            .map(|(e, a): (f32, f32)| {
                let (e, a) = (e.to_radians(), a.to_radians());
                Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
            })
            .to_vec(),
    };
    let mut live = Live::new(data.clone());
    for towards in suns {
        let elev = towards.y.asin().to_degrees();
        let azim = towards.z.atan2(towards.x).to_degrees();
        // The run time: from the previous solution.
        let t0 = Instant::now();
        let solve = live.update(&[Sun {
            direction: towards.to_array(),
            irradiance: irradiance.to_array(),
        }])?;
        let relit_live = live.texels();
        let update_ms = t0.elapsed().as_secs_f64() * 1e3;
        // The patch solution at the exact visibility.
        let exact_d = patch_direct(&s, &baked, &[towards], config.seed, &|_| {});
        let mut exact = Live::new(data.clone());
        let d: Vec<[f32; 3]> = (exact_d.iter())
            .map(|v| (irradiance * v[0]).to_array())
            .collect();
        exact.set_direct(&d)?;
        exact.solve(data.header.max_iterations);
        let exact_live = exact.texels();
        // The full bake at that sun.
        let mut full_scene = scene.clone();
        full_config.light_modes.apply(&mut full_scene)?;
        full_scene.lights[sun].direction = -towards;
        let t1 = Instant::now();
        let full = radbake::bake(&full_scene, &full_config, &Silent)?;
        let full_s = t1.elapsed().as_secs_f64();
        let with = |live_part: &[[f32; 3]]| -> Vec<Vec3> {
            (0..bake.texels.len())
                .map(|t| {
                    let others: Vec3 = (bake.maps.layers.iter().enumerate())
                        .filter(|(k, _)| *k != live_k)
                        .map(|(_, lm)| lm.texel_values[t])
                        .sum();
                    others + Vec3::from(live_part[t])
                })
                .collect()
        };
        if let (Some(delta), Some(bp), Some(fp)) = (live.probe_delta(), &bake.probes, &full.probes)
        {
            let relit: Vec<radbake::probes::Sh9> = (bp.sh.iter().zip(&delta))
                .map(|(b, d)| std::array::from_fn(|i| b[i] + Vec3::from(d[i])))
                .collect();
            let cubes = |sh: &[radbake::probes::Sh9]| -> Vec<Vec3> {
                (sh.iter().zip(&bp.valid))
                    .filter(|(_, v)| **v)
                    .flat_map(|(s, _)| {
                        radbake::probes::sh::AXES
                            .map(|n| radbake::probes::sh::irradiance_over_pi(s, n))
                    })
                    .collect()
            };
            let want = cubes(&fp.sh);
            let rel = |a: &[Vec3]| {
                let num: f32 = a
                    .iter()
                    .zip(&want)
                    .map(|(x, y)| (*x - *y).abs().element_sum())
                    .sum();
                num / want.iter().map(|y| y.abs().element_sum()).sum::<f32>()
            };
            println!(
                "probes at {elev:.1}°, {azim:.1}°: relit {:.2} % off the full bake, as baked {:.2} % ({} valid)",
                100.0 * rel(&cubes(&relit)),
                100.0 * rel(&cubes(&bp.sh)),
                want.len() / 6
            );
        }
        let relit = with(&relit_live);
        let exact = with(&exact_live);
        if meter_samples > 0 {
            let settings = radbake::trace::measure::MeterSettings {
                samples: meter_samples,
                normal: Default::default(),
                sky: Vec3::from(config.sky),
                seed: 24301,
            };
            against_the_meter(&full, &relit, &full_scene, &settings, min_area)?;
        }
        let reference = &full.maps.lightmaps.texel_values;
        report(
            (elev, azim, update_ms, solve.iterations, full_s),
            &bake,
            &full.transport.valid,
            (reference, &relit, &exact),
            min_area,
        );
    }
    Ok(())
}

/// Per instance of at least `min_area` m²: the relit and the full bake's
/// `mean` (what it receives, over its exposed texels, as `report.json`'s)
/// against the meter's reading of the scene with the sun in mode
/// `indirect` there (independent of atlas, texels, patches and gather).
fn against_the_meter(
    full: &radbake::Bake,
    relit: &[Vec3],
    scene: &radbake::scene::Scene,
    settings: &radbake::trace::measure::MeterSettings,
    min_area: f64,
) -> anyhow::Result<()> {
    let reports = full.instance_reports();
    let nodes: Vec<String> = (reports.iter())
        .filter(|r| r.area >= min_area)
        .map(|r| r.node.clone())
        .collect();
    let t = Instant::now();
    let readings = radbake::trace::measure::Meter::new(scene)
        .measure(&nodes, settings)
        .map_err(anyhow::Error::msg)?;
    // Relit means, as `instance_reports` makes them.
    let n = full.scene.instances.len();
    let mut sums = vec![[0.0f64; 2]; n];
    for (t, v) in relit.iter().enumerate() {
        let exposed = if full.transport.valid[t] {
            full.burial.exposed(t) as f64
        } else {
            0.0
        };
        let a = full.texels.area[t] as f64;
        let s = &mut sums[full.texels.instance[t] as usize];
        s[0] += a;
        s[1] += a * exposed * v.element_sum() as f64 / 3.0;
    }
    println!(
        "against the meter ({} samples per node, {:.0} s): | instance | m² | meter | ± | relit | full bake |",
        settings.samples,
        t.elapsed().as_secs_f64()
    );
    let (mut ok_relit, mut ok_full) = (0, 0);
    for m in &readings {
        let i = (reports.iter()).position(|r| r.node == m.node).unwrap();
        let want = m.mean.iter().sum::<f64>() / 3.0;
        let se = m.std_error.iter().map(|s| s * s).sum::<f64>().sqrt() / 3.0;
        let got = sums[i][1] / sums[i][0];
        let baked = reports[i].mean.iter().sum::<f32>() as f64 / 3.0;
        let within = |x: f64| (x - want).abs() <= (0.03 * want).max(3.0 * se);
        ok_relit += within(got) as u32;
        ok_full += within(baked) as u32;
        println!(
            "| {} | {:.1} | {want:.4} | {se:.4} | {:+.2} % | {:+.2} % |",
            m.node,
            reports[i].area,
            100.0 * (got / want - 1.0),
            100.0 * (baked / want - 1.0)
        );
    }
    println!(
        "within 3 % or 3 standard errors of the meter: relit {ok_relit} of {}, full bake {ok_full}",
        readings.len()
    );
    Ok(())
}

type Figures = (f32, f32, f64, u32, f64);

/// Prints the per-instance table and the summary for one sun.
fn report(
    (elev, azim, update_ms, iterations, full_s): Figures,
    bake: &radbake::Bake,
    valid: &[bool],
    (reference, relit, exact): (&[Vec3], &[Vec3], &[Vec3]),
    min_area: f64,
) {
    let n = bake.scene.instances.len();
    // Per instance: area, Σ a·ref, Σ a·relit, Σ a·exact (luminance-free: RGB sum).
    let mut per = vec![[0.0f64; 4]; n];
    let (mut se, mut sref, mut count) = (0.0f64, 0.0f64, 0u64);
    for t in 0..bake.texels.len() {
        if !valid[t] {
            continue;
        }
        let a = bake.texels.area[t] as f64;
        let row = &mut per[bake.texels.instance[t] as usize];
        let (r, l, x) = (
            reference[t].element_sum() as f64,
            relit[t].element_sum() as f64,
            exact[t].element_sum() as f64,
        );
        row[0] += a;
        row[1] += a * r;
        row[2] += a * l;
        row[3] += a * x;
        se += (l - r) * (l - r);
        sref += r;
        count += 1;
    }
    println!(
        "\nsun at elevation {elev}°, azimuth {azim}°: update {update_ms:.1} ms ({iterations} iterations); full bake {full_s:.1} s"
    );
    println!("| instance | m² | full | relit | error | gather | interpolation |");
    println!("|---|---|---|---|---|---|---|");
    let (mut wsum, mut werr, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    for (i, row) in per.iter().enumerate() {
        if row[0] < min_area || row[1] <= 0.0 {
            continue;
        }
        let (r, l, x) = (row[1] / row[0], row[2] / row[0], row[3] / row[0]);
        let err = l / r - 1.0;
        println!(
            "| {} | {:.1} | {:.4} | {:.4} | {:+.2} % | {:+.2} % | {:+.2} % |",
            bake.scene.instances[i].node,
            row[0],
            r,
            l,
            100.0 * err,
            100.0 * (x / r - 1.0),
            100.0 * (l / x - 1.0)
        );
        wsum += row[0];
        werr += row[0] * err.abs();
        worst = worst.max(err.abs());
    }
    let rmse = (se / count as f64).sqrt() / (sref / count as f64);
    println!(
        "area-weighted mean |error| {:.2} %, worst {:.2} %, texel RMSE {:.2} % of the mean texel",
        100.0 * werr / wsum,
        100.0 * worst,
        100.0 * rmse
    );
}
