//! Times the run time's update on a live bake: the sun stepped along its
//! path (or across the grid) one sample at a time, each update warm-started
//! from the last, as an engine moves it frame by frame. Prints the median
//! and worst time per update and its parts (direct light + solve, texels,
//! pages, and the probes' change where the file has the probes' rays),
//! and the iterations.
//!
//!     cargo run --release -p radbake-live --example bench -- <bake dir>/live.bin [steps]

use radbake_live::{Live, LiveData, Sun};
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: bench <live.bin> [steps]");
    let steps: usize = args.next().map_or(60, |s| s.parse().expect("steps"));
    let t = Instant::now();
    let data = LiveData::read(path.as_ref()).unwrap_or_else(|e| panic!("{e}"));
    let read = t.elapsed().as_secs_f64();
    let h = data.header.clone();
    let light = &h.lights[0];
    // The sun's directions: along its path, or a sweep over the grid's middle row.
    let dirs: Vec<[f32; 3]> = match &light.path {
        Some(p) => p.clone(),
        None => (0..h.grid)
            .map(|i| radbake_live::directions::node_direction(h.grid, i, h.grid / 2))
            .collect(),
    };
    // Halfway between samples: never a table direction.
    let mid = |k: usize| {
        let (a, b) = (dirs[k % (dirs.len() - 1)], dirs[k % (dirs.len() - 1) + 1]);
        [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
    };
    let mut live = Live::new(data);
    let sun = |k| Sun {
        direction: mid(k),
        irradiance: light.irradiance,
    };
    live.update(&[sun(dirs.len() / 4)]).unwrap();
    let probes = live.probe_delta().map(|d| d.len());
    // The first write allocates the pages and the texel buffers (once per
    // engine): timed apart from the updates.
    let mut pages = Vec::new();
    let t = Instant::now();
    live.write_pages(&mut pages);
    let first = t.elapsed().as_secs_f64();
    let mut times: Vec<[f64; 5]> = Vec::new();
    let mut iterations = Vec::new();
    for s in 0..steps {
        let k = dirs.len() / 4 + s + 1;
        let t0 = Instant::now();
        let solve = live.update(&[sun(k)]).unwrap();
        let t1 = Instant::now();
        let texels = live.texels();
        let t2 = Instant::now();
        live.write_pages(&mut pages);
        let t3 = Instant::now();
        let delta = live.probe_delta();
        let t4 = Instant::now();
        std::hint::black_box((texels, &pages, delta));
        let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
        // An engine needs the texels' page once: solve + pages (pages reads the texels).
        times.push([
            ms(t0, t1),
            ms(t1, t2),
            ms(t2, t3),
            ms(t0, t1) + ms(t2, t3),
            ms(t3, t4),
        ]);
        iterations.push(solve.iterations);
    }
    let median = |c: usize| {
        let mut v: Vec<f64> = times.iter().map(|t| t[c]).collect();
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[v.len() - 1])
    };
    iterations.sort();
    println!(
        "{} patches, {} entries of F, {} texels, {} directions; read {:.0} ms; first pages (allocating) {:.1} ms",
        h.patches,
        h.entries,
        h.texels,
        dirs.len(),
        read * 1e3,
        first * 1e3
    );
    println!(
        "{steps} updates, sun stepped one sample each (median / worst): solve {:.1} / {:.1} ms ({}–{} iterations, median {}), texels {:.1} / {:.1} ms, pages (texels incl., buffers reused) {:.1} / {:.1} ms; update (solve + pages) {:.1} / {:.1} ms",
        median(0).0, median(0).1, iterations[0], iterations[iterations.len() - 1], iterations[iterations.len() / 2],
        median(1).0, median(1).1, median(2).0, median(2).1, median(3).0, median(3).1
    );
    if let (Some(n), Some(q)) = (probes, &h.probes) {
        println!(
            "probes: {n} × {} rays; their change {:.1} / {:.1} ms per update",
            q.rays,
            median(4).0,
            median(4).1
        );
    }
}
