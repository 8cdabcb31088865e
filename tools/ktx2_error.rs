//! How far a bake's KTX2 lightmap pages are from its EXR pages:
//!
//! ```sh
//! cargo run --release --example ktx2_error -- <bake dir>
//! ```
//!
//! Decodes every `lightmap_<page>.ktx2` the manifest lists (RGB9E5 by the
//! Vulkan specification's formula, BC6H with `bcdec_rs`, an independent
//! decoder), and prints per page: file sizes (KTX2, EXR, PNG), the RMSE
//! over texels with any light (absolute and as a share of their mean), and
//! the median, 99th-percentile and worst channel error relative to the
//! texel's largest channel, and the worst absolute error.

use std::path::Path;

fn decode(bytes: &[u8]) -> (usize, usize, Vec<[f32; 3]>) {
    let reader = ktx2::Reader::new(bytes).expect("a KTX2 file");
    let h = reader.header();
    let (w, hgt) = (h.pixel_width as usize, h.pixel_height as usize);
    let level = reader.levels().next().expect("one level");
    let data = match h.supercompression_scheme {
        Some(ktx2::SupercompressionScheme::Zstandard) => {
            zstd::bulk::decompress(level.data, 1 << 30).expect("zstd")
        }
        None => level.data.to_vec(),
        Some(s) => panic!("unexpected supercompression {s:?}"),
    };
    let mut out = vec![[0f32; 3]; w * hgt];
    match h.format {
        Some(ktx2::Format::E5B9G9R9_UFLOAT_PACK32) => {
            for (o, c) in out.iter_mut().zip(data.chunks_exact(4)) {
                let p = u32::from_le_bytes(c.try_into().unwrap());
                let scale = 2f32.powi((p >> 27) as i32 - 15 - 9);
                *o = [p & 0x1ff, (p >> 9) & 0x1ff, (p >> 18) & 0x1ff].map(|m| m as f32 * scale);
            }
        }
        Some(ktx2::Format::BC6H_UFLOAT_BLOCK) => {
            let bw = w.div_ceil(4);
            for (b, block) in data.chunks_exact(16).enumerate() {
                let (bx, by) = (b % bw, b / bw);
                let mut px = [0f32; 48];
                bcdec_rs::bc6h_float(block, &mut px, 12, false);
                for y in 0..4 {
                    for x in 0..4 {
                        let (u, v) = (bx * 4 + x, by * 4 + y);
                        if u < w && v < hgt {
                            let q = &px[(y * 4 + x) * 3..][..3];
                            out[v * w + u] = [q[0], q[1], q[2]];
                        }
                    }
                }
            }
        }
        f => panic!("unexpected format {f:?}"),
    }
    (w, hgt, out)
}

fn size(path: &Path) -> f64 {
    std::fs::metadata(path).map_or(0.0, |m| m.len() as f64 / 1e6)
}

fn main() {
    let dir = std::env::args()
        .nth(1)
        .expect("usage: ktx2_error <bake dir>");
    let dir = Path::new(&dir);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).expect("manifest.json"))
            .expect("JSON");
    for page in manifest["pages"].as_array().expect("pages") {
        let Some(name) = page["ktx2"].as_str() else {
            println!("page {}: no KTX2 file", page["page"]);
            continue;
        };
        let exr = page["exr"].as_str().unwrap();
        let png = page["png"].as_str().unwrap();
        let (w, _, want) =
            radbake::trace::render::read_exr_rgb(&dir.join(exr)).unwrap_or_else(|e| panic!("{e}"));
        let (w, want): (usize, Vec<[f32; 3]>) =
            (w as usize, want.iter().map(|v| v.to_array()).collect());
        let (kw, kh, got) = decode(&std::fs::read(dir.join(name)).unwrap());
        assert_eq!((kw, kh), (w, want.len() / w), "page size");
        let (mut sq, mut sum, mut n, mut worst) = (0f64, 0f64, 0usize, 0f64);
        let mut rel: Vec<f64> = Vec::new();
        for (g, e) in got.iter().zip(&want) {
            let peak = e.iter().cloned().fold(0.0f32, f32::max) as f64;
            if peak <= 0.0 {
                continue;
            }
            n += 1;
            for c in 0..3 {
                let d = (g[c] - e[c]) as f64;
                sq += d * d;
                worst = f64::max(worst, d.abs());
                sum += e[c] as f64;
                rel.push(d.abs() / peak);
            }
        }
        rel.sort_by(f64::total_cmp);
        let rmse = (sq / (3 * n).max(1) as f64).sqrt();
        let mean = sum / (3 * n).max(1) as f64;
        let pct = |q: f64| {
            rel.get(((rel.len() as f64 - 1.0) * q) as usize)
                .copied()
                .unwrap_or(0.0)
        };
        println!(
            "page {} ({w}×{kh}, {}): KTX2 {:.2} MB, EXR {:.2} MB, PNG {:.2} MB; {n} lit texels: RMSE {rmse:.4e} ({:.2} % of their mean {mean:.4}), channel error / texel max: median {:.3} %, p99 {:.2} %, worst {:.1} %; worst absolute error {worst:.4} ({:.0} % of the mean)",
            page["page"],
            page["ktx2_format"].as_str().unwrap_or("?"),
            size(&dir.join(name)),
            size(&dir.join(exr)),
            size(&dir.join(png)),
            100.0 * rmse / mean,
            100.0 * pct(0.5),
            100.0 * pct(0.99),
            100.0 * pct(1.0),
            100.0 * worst / mean,
        );
    }
}
