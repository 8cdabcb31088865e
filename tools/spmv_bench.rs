//! Times Jacobi's product y = F x on a synthetic matrix shaped like the
//! furnace box's hemicube F at the defaults (20,184 rows of ~14 k entries
//! in runs of ~20 columns): `cargo run --release --example spmv_bench`.
use glam::Vec3;
use radbake::radiosity::form_factors::Csr;
use radbake::radiosity::solve::jacobi::spmv;

fn main() {
    let n = 20_184usize;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let mut f = Csr::new();
    for _ in 0..n {
        let mut row = Vec::with_capacity(15_000);
        let mut c = (rnd() % 8) as u32;
        while (c as usize) < n {
            // Half the runs one column long, the rest ~40.
            let len = if rnd() % 2 == 0 { 1 } else { 1 + rnd() % 80 } as u32;
            for k in 0..len.min(n as u32 - c) {
                row.push((c + k, 1e-5 + (rnd() % 1000) as f32 * 1e-8));
            }
            c += len + 1 + (rnd() % 8) as u32;
        }
        f.push_row(row);
    }
    let f = f.square(n);
    let x: Vec<Vec3> = (0..n).map(|i| Vec3::splat(1.0 + i as f32 * 1e-4)).collect();
    println!("{} entries in {} runs", f.nnz(), f.nruns());
    for _ in 0..5 {
        let t = std::time::Instant::now();
        let mut y = Vec::new();
        for _ in 0..5 {
            y = spmv(&f, &x);
        }
        let s = t.elapsed().as_secs_f64() / 5.0;
        println!(
            "spmv {:.1} ms, {:.2} G entries/s, {:.1} GB/s of F ({})",
            s * 1e3,
            f.nnz() as f64 / s * 1e-9,
            (f.nnz() * 4 + f.nruns() * 8) as f64 / s * 1e-9,
            y[7].x
        );
    }
}
