//! The radiosity solvers on the Cornell box's ray-cast F (medium preset) to
//! its tolerance (1e-4): Jacobi (throughput in iterations) and progressive
//! refinement over the stored matrix's columns (throughput in shots).
//!
//!     cargo bench --bench solve

mod common;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use radbake::radiosity::form_factors::rows::StoredColumns;
use radbake::radiosity::solve::{jacobi, progressive, System};

fn solve(c: &mut Criterion) {
    let scene = common::cornell();
    let bake = common::cornell_bake(&scene);
    let emission = common::solve_emission(&bake);
    let system = System {
        emission: &emission,
        albedo: &bake.patches.albedo,
        direct: &bake.patch_light().expect("radiosity").direct,
        area: &bake.patches.area,
    };
    let ff = bake
        .patch_light()
        .expect("radiosity")
        .form_factors
        .as_ref()
        .expect("Jacobi stores F");
    let (tolerance, max) = (bake.config.tolerance, bake.config.max_iterations);
    let mut group = c.benchmark_group("solve_cornell");

    let iterations = jacobi::solve(&ff.matrix, &system, tolerance, max, &|_| {}).iterations;
    group.throughput(Throughput::Elements(iterations as u64));
    group.bench_function(format!("jacobi_{iterations}_iterations"), |b| {
        b.iter(|| jacobi::solve(black_box(&ff.matrix), &system, tolerance, max, &|_| {}))
    });

    let columns = StoredColumns::new(ff);
    let max_shots = max as u64 * bake.patches.len() as u64;
    let shots = progressive::solve(
        &columns,
        &system,
        tolerance,
        max_shots,
        &|_| {},
        &mut |_| {},
    )
    .solution
    .shots;
    group.throughput(Throughput::Elements(shots));
    group.bench_function(format!("progressive_{shots}_shots"), |b| {
        b.iter(|| {
            progressive::solve(
                black_box(&columns),
                &system,
                tolerance,
                max_shots,
                &|_| {},
                &mut |_| {},
            )
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = solve
}
criterion_main!(benches);
