//! Measures the denoiser: RMSE of the Cornell box's lightmap texels against a
//! high-sample reference (final gather 4096 rays, 1024 direct samples, no denoising), with and
//! without denoising, at a low final-gather count.
//!
//!     cargo run --release --example denoise_rmse [-- RAYS]

use radbake::{BakeConfig, Silent};

fn main() -> anyhow::Result<()> {
    let rays: u32 = std::env::args().nth(1).map_or(Ok(32), |s| s.parse())?;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box.gltf");
    let scene = radbake::scene::load(&path, &Default::default())?;
    let base = BakeConfig {
        texels_per_meter: 58.0,
        ..BakeConfig::default()
    };
    let reference = radbake::bake(
        &scene,
        &BakeConfig {
            final_gather: 4096,
            direct_samples: 1024,
            denoise: false,
            ..base.clone()
        },
        &Silent,
    )?;
    let rmse = |cfg: &BakeConfig| -> anyhow::Result<f64> {
        let b = radbake::bake(&scene, cfg, &Silent)?;
        let (mut se, mut n) = (0.0f64, 0usize);
        for (a, r) in b
            .maps
            .lightmaps
            .texel_values
            .iter()
            .zip(&reference.maps.lightmaps.texel_values)
        {
            se += ((*a - *r).length_squared() / 3.0) as f64;
            n += 1;
        }
        Ok((se / n as f64).sqrt())
    };
    let mean = reference
        .maps
        .lightmaps
        .texel_values
        .iter()
        .map(|v| v.element_sum() as f64 / 3.0)
        .sum::<f64>()
        / reference.maps.lightmaps.texel_values.len() as f64;
    let noisy = rmse(&BakeConfig {
        final_gather: rays,
        denoise: false,
        ..base.clone()
    })?;
    let denoised = rmse(&BakeConfig {
        final_gather: rays,
        denoise: true,
        ..base.clone()
    })?;
    println!(
        "Cornell box, final gather {rays} rays vs 4096-ray reference (mean texel value {mean:.4}):"
    );
    println!(
        "  RMSE without denoising {noisy:.5} ({:.2} % of the mean)",
        100.0 * noisy / mean
    );
    println!(
        "  RMSE with denoising    {denoised:.5} ({:.2} % of the mean)",
        100.0 * denoised / mean
    );
    Ok(())
}
