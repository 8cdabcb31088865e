//! Jacobi iteration L⁽ᵏ⁺¹⁾ = E + ρ ⊙ (F L⁽ᵏ⁾ + D), starting from L⁽⁰⁾ = E.
//! After k iterations L holds the light of k bounces; since ρ < 1 and the rows
//! of F sum to ≤ 1 the iteration contracts (Cohen & Wallace 1993, ch. 5).
//! Rows are summed in column order, so results do not depend on threads.

use super::{Solution, System};
use crate::form_factors::{Csr, Row};
use glam::Vec3;
use rayon::prelude::*;

/// y = F x (RGB), one row per task ([`row_dot`]).
pub fn spmv(f: &Csr, x: &[Vec3]) -> Vec<Vec3> {
    (0..f.nrows())
        .into_par_iter()
        .map(|i| row_dot(f.row(i), x))
        .collect()
}

/// Σⱼ Fᵢⱼ xⱼ over one row, in column order (so the result does not
/// depend on threads): within a run of columns `x` is read in order.
/// Tried and not kept: eight partial sums per channel over x's channels
/// apart, which freed the sum from waiting on its last add; on a matrix
/// shaped like the furnace's (`examples/spmv_bench.rs`) it read 1.75 G
/// entries/s against 1.63 G, 2.6 against 2.2 with runs of 2,000: the
/// product waits on F's loads, not the adds, at ~8 GB/s.
#[inline]
pub fn row_dot(row: Row, x: &[Vec3]) -> Vec3 {
    let mut acc = Vec3::ZERO;
    for (c, v) in row.segments() {
        let xs = &x[c as usize..c as usize + v.len()];
        for (&xj, &fij) in xs.iter().zip(v) {
            acc += xj * fij;
        }
    }
    acc
}

/// Relative change Σ|a − b| / Σ|a| (0 when a is all zero).
pub fn relative_change(a: &[Vec3], b: &[Vec3]) -> f32 {
    let (mut change, mut total) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        change += (*x - *y).abs().element_sum() as f64;
        total += x.abs().element_sum() as f64;
    }
    if total > 0.0 {
        (change / total) as f32
    } else {
        0.0
    }
}

/// H = D + F L for the final radiance.
pub fn gather(f: &Csr, sys: &System, radiance: &[Vec3]) -> Vec<Vec3> {
    spmv(f, radiance)
        .iter()
        .zip(sys.direct)
        .map(|(h, d)| *h + *d)
        .collect()
}

/// Solves by Jacobi iteration until Σ|ΔL|/Σ|L| < `tolerance` or
/// `max_iterations`. `advance` is called once per iteration.
pub fn solve(
    f: &Csr,
    sys: &System,
    tolerance: f32,
    max_iterations: u32,
    advance: &dyn Fn(u64),
) -> Solution {
    let mut radiance = sys.initial_radiance();
    let mut iterations = 0;
    let mut residual = 0.0f32;
    while iterations < max_iterations {
        let h = spmv(f, &radiance);
        let next: Vec<Vec3> = (0..radiance.len())
            .map(|i| sys.emission[i] + sys.albedo[i] * (h[i] + sys.direct[i]))
            .collect();
        residual = relative_change(&next, &radiance);
        radiance = next;
        iterations += 1;
        advance(1);
        if residual < tolerance {
            break;
        }
    }
    let irradiance = gather(f, sys, &radiance);
    Solution {
        radiance,
        irradiance,
        iterations,
        residual,
        shots: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two-patch enclosure with F = [[0,1],[1,0]]: L = E + ρ L_other.
    #[test]
    fn two_patch_closed_form() {
        let f = Csr::from_parts(2, vec![0, 1, 2], vec![1, 0], vec![1.0f32, 1.0]);
        let e = [Vec3::ONE, Vec3::ZERO];
        let rho = [Vec3::splat(0.5), Vec3::splat(0.5)];
        let sys = System {
            emission: &e,
            albedo: &rho,
            direct: &[Vec3::ZERO; 2],
            area: &[1.0; 2],
        };
        let s = solve(&f, &sys, 1e-7, 1000, &|_| {});
        // L0 = 1 + 0.5 L1, L1 = 0.5 L0 → L0 = 4/3, L1 = 2/3.
        assert!((s.radiance[0].x - 4.0 / 3.0).abs() < 1e-5);
        assert!((s.radiance[1].x - 2.0 / 3.0).abs() < 1e-5);
        assert!((s.irradiance[0].x - 2.0 / 3.0).abs() < 1e-5);
        assert!(s.iterations > 3 && s.residual < 1e-7);
    }
}
