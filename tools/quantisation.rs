//! The 8-bit lightmap encoding's precision per instance: for every texel
//! channel at or above 2 % of its instance's largest value, the
//! quantisation step relative to the value, worst per instance, under one
//! scale per page (before) and one scale per instance (now; see
//! `radbake::output::png8`).
//!
//!     cargo run --release --example quantisation -- SCENE [KEY=VALUE ...]
//!
//! KEY=VALUE pairs are settings as in a `--config` TOML file, e.g.
//! `texels_per_meter=4 'sky=[0.4,0.5,0.7]'`.

mod common;

use radbake::output::png8::relative_step;
use radbake::pipeline::progress::Silent;

fn main() -> anyhow::Result<()> {
    let (scene, config) = common::scene_and_settings(
        "quantisation",
        "probes = false
",
    )?;
    let bake = radbake::bake(&scene, &config, &Silent)?;
    let (texels, values) = (&bake.texels, &bake.maps.lightmaps.texel_values);
    let n = scene.instances.len();
    let mut inst_max = vec![0.0f32; n];
    let mut page_max = vec![0.0f32; bake.atlas.page_count as usize];
    for (t, v) in values.iter().enumerate() {
        let i = texels.instance[t] as usize;
        inst_max[i] = inst_max[i].max(v.max_element());
        let p = texels.page[t] as usize;
        page_max[p] = page_max[p].max(v.max_element());
    }
    // Worst relative step (before, after) per instance, over channels ≥ 2 %
    // of the instance's largest value.
    let mut worst = vec![(0.0f32, 0.0f32); n];
    for (t, v) in values.iter().enumerate() {
        let i = texels.instance[t] as usize;
        let p = texels.page[t] as usize;
        for c in v.to_array() {
            if c < 0.02 * inst_max[i] || c <= 0.0 {
                continue;
            }
            let before = relative_step(c, page_max[p]);
            let after = relative_step(c, inst_max[i]);
            worst[i].0 = worst[i].0.max(before);
            worst[i].1 = worst[i].1.max(after);
        }
    }
    println!("| instance | largest value | worst step, one scale per page | worst step, one scale per instance |");
    println!("|---|---|---|---|");
    let mut order: Vec<usize> = (0..n).filter(|&i| inst_max[i] > 0.0).collect();
    order.sort_by(|&a, &b| worst[b].0.total_cmp(&worst[a].0));
    for &i in &order {
        println!(
            "| {} | {:.4} | {:.1} % | {:.1} % |",
            scene.instances[i].node,
            inst_max[i],
            100.0 * worst[i].0,
            100.0 * worst[i].1
        );
    }
    let all_before = worst.iter().map(|w| w.0).fold(0.0f32, f32::max);
    let all_after = worst.iter().map(|w| w.1).fold(0.0f32, f32::max);
    let over = |f: fn(&(f32, f32)) -> f32| worst.iter().filter(|w| f(w) > 0.05).count();
    println!(
        "\n{} instances; worst step {:.1} % before, {:.1} % after; instances over 5 %: {} before, {} after",
        order.len(),
        100.0 * all_before,
        100.0 * all_after,
        over(|w| w.0),
        over(|w| w.1)
    );
    Ok(())
}
