//! Jacobi iteration L⁽ᵏ⁺¹⁾ = E + ρ ⊙ (F L⁽ᵏ⁾ + D), starting from L⁽⁰⁾ = E.
//! After k iterations L holds the light of k bounces; since ρ < 1 and the rows
//! of F sum to ≤ 1 the iteration contracts (Cohen & Wallace 1993, ch. 5).
//! Rows are summed in column order, so results do not depend on threads.

use super::Solution;
use glam::Vec3;
use nalgebra_sparse::CsrMatrix;
use rayon::prelude::*;

/// y = F x (RGB), one row per task.
pub fn spmv(f: &CsrMatrix<f32>, x: &[Vec3]) -> Vec<Vec3> {
    let offsets = f.row_offsets();
    let cols = f.col_indices();
    let vals = f.values();
    (0..f.nrows())
        .into_par_iter()
        .map(|i| {
            let mut acc = Vec3::ZERO;
            for k in offsets[i]..offsets[i + 1] {
                acc += x[cols[k]] * vals[k];
            }
            acc
        })
        .collect()
}

/// Solves by Jacobi iteration until Σ|ΔL|/Σ|L| < `tolerance` or
/// `max_iterations`. `direct` is D (may be all zero). `advance` is called once
/// per iteration.
pub fn solve(
    f: &CsrMatrix<f32>,
    emission: &[Vec3],
    albedo: &[Vec3],
    direct: &[Vec3],
    tolerance: f32,
    max_iterations: u32,
    advance: &dyn Fn(u64),
) -> Solution {
    let mut radiance: Vec<Vec3> = emission
        .iter()
        .zip(albedo)
        .zip(direct)
        .map(|((e, r), d)| *e + *r * *d)
        .collect();
    let mut iterations = 0;
    let mut residual = 0.0f32;
    while iterations < max_iterations {
        let h = spmv(f, &radiance);
        let next: Vec<Vec3> = (0..radiance.len())
            .map(|i| emission[i] + albedo[i] * (h[i] + direct[i]))
            .collect();
        let (mut change, mut total) = (0.0f64, 0.0f64);
        for (a, b) in next.iter().zip(&radiance) {
            change += ((*a - *b).abs().element_sum()) as f64;
            total += (a.abs().element_sum()) as f64;
        }
        residual = if total > 0.0 {
            (change / total) as f32
        } else {
            0.0
        };
        radiance = next;
        iterations += 1;
        advance(1);
        if residual < tolerance {
            break;
        }
    }
    let h = spmv(f, &radiance);
    let irradiance = h.iter().zip(direct).map(|(h, d)| *h + *d).collect();
    Solution {
        radiance,
        irradiance,
        iterations,
        residual,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two-patch enclosure with F = [[0,1],[1,0]]: L = E + ρ L_other.
    #[test]
    fn two_patch_closed_form() {
        let f = CsrMatrix::try_from_csr_data(2, 2, vec![0, 1, 2], vec![1, 0], vec![1.0f32, 1.0])
            .unwrap();
        let e = [Vec3::ONE, Vec3::ZERO];
        let rho = [Vec3::splat(0.5), Vec3::splat(0.5)];
        let s = solve(&f, &e, &rho, &[Vec3::ZERO; 2], 1e-7, 1000, &|_| {});
        // L0 = 1 + 0.5 L1, L1 = 0.5 L0 → L0 = 4/3, L1 = 2/3.
        assert!((s.radiance[0].x - 4.0 / 3.0).abs() < 1e-5);
        assert!((s.radiance[1].x - 2.0 / 3.0).abs() < 1e-5);
        assert!((s.irradiance[0].x - 2.0 / 3.0).abs() < 1e-5);
        assert!(s.iterations > 3 && s.residual < 1e-7);
    }
}
