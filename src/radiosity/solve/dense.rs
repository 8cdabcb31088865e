//! Direct solve for small systems: (I − diag(ρ) F) L = E + ρ D by dense LU
//! (nalgebra, f64), one factorisation per distinct albedo channel. O(n³):
//! the reference the iterative solvers are tested against.

use super::jacobi::gather;
use super::{Solution, System};
use crate::radiosity::form_factors::Csr;
use glam::Vec3;
use nalgebra::DMatrix;

/// Solves exactly, or returns `None` when the matrix is singular.
pub fn solve(f: &Csr, sys: &System) -> Option<Solution> {
    let n = sys.len();
    let rhs = sys.initial_radiance();
    let mut radiance = vec![Vec3::ZERO; n];
    let mut done = [false; 3];
    for c in 0..3 {
        if done[c] {
            continue;
        }
        // Channels with the same albedo share one factorisation.
        let group: Vec<usize> = (c..3)
            .filter(|&d| sys.albedo.iter().all(|a| a[c] == a[d]))
            .collect();
        let b = DMatrix::from_fn(n, group.len(), |i, k| rhs[i][group[k]] as f64);
        let x = factor(f, sys, c).lu().solve(&b)?;
        for (k, &d) in group.iter().enumerate() {
            done[d] = true;
            for i in 0..n {
                radiance[i][d] = x[(i, k)] as f32;
            }
        }
    }
    let irradiance = gather(f, sys, &radiance);
    Some(Solution {
        radiance,
        irradiance,
        iterations: 1,
        residual: 0.0,
        shots: 0,
    })
}

/// I − diag(ρ_c) F as a dense f64 matrix.
fn factor(f: &Csr, sys: &System, c: usize) -> DMatrix<f64> {
    let n = sys.len();
    let mut m = DMatrix::<f64>::identity(n, n);
    for (i, row) in f.rows().enumerate() {
        let rho = sys.albedo[i][c] as f64;
        for (j, v) in row.iter() {
            m[(i, j as usize)] -= rho * v as f64;
        }
    }
    m
}
