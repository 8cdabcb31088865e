//! Times the CPU hemicube (`--form-factors hemicube`) one row at a time on
//! one thread, and prints a checksum of the rows, so that two builds can be
//! compared for speed and for bit-identical rows:
//! `cargo run --release --example hemicube_bench [scene.gltf] [rows]`
//! (default: the furnace box at the default density, 2,000 rows spread
//! over its patches).
use radbake::radiosity::form_factors::hemicube;
use radbake::raycast::RayCaster;
use radbake::{BakeConfig, Silent};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .unwrap_or_else(|| "scenes/furnace_box.gltf".into());
    let rows: usize = args.next().map_or(Ok(2000), |a| a.parse())?;
    let scene = radbake::scene::load(std::path::Path::new(&path), &Default::default())?;
    let config = BakeConfig {
        final_gather: 0,
        rays_per_patch: 16,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &config, &Silent)?;
    let rays = RayCaster::new(&scene, &bake.geometry);
    let s = bake.surfaces(&rays);
    let n = s.patches.len();
    let setup = hemicube::Setup::new(&s, config.hemicube_resolution);
    let picks: Vec<usize> = (0..rows.min(n)).map(|k| k * n / rows.min(n)).collect();
    let mut best = f64::INFINITY;
    let mut sum = 0u64;
    let mut entries = 0usize;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        sum = 0;
        entries = 0;
        for &i in &picks {
            let (row, _) = hemicube::row(&s, &setup, i);
            entries += row.len();
            for (j, v) in row {
                sum = sum
                    .wrapping_mul(31)
                    .wrapping_add(u64::from(j) ^ u64::from(v.to_bits()));
            }
        }
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "{} patches, {} rows of {} entries on average: {:.1} µs per hemicube (best of 3), checksum {sum:016x}",
        n,
        picks.len(),
        entries / picks.len().max(1),
        best / picks.len() as f64 * 1e6
    );
    Ok(())
}
