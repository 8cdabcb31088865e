//! Gauss–Seidel iteration: like Jacobi, but each Lᵢ is updated in place and
//! used at once by the rows after it (Cohen & Wallace 1993, §5.3.2), which
//! roughly halves the iterations. Sequential in row order, so deterministic.

use super::jacobi::{gather, relative_change};
use super::{Solution, System};
use crate::radiosity::form_factors::Csr;

/// Solves by Gauss–Seidel until Σ|ΔL|/Σ|L| < `tolerance` or `max_iterations`.
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
        let before = radiance.clone();
        for i in 0..radiance.len() {
            let mut h = sys.direct[i];
            for (c, v) in f.row(i).segments() {
                for (j, &fij) in (c as usize..).zip(v) {
                    h += radiance[j] * fij;
                }
            }
            radiance[i] = sys.emission[i] + sys.albedo[i] * h;
        }
        residual = relative_change(&radiance, &before);
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
