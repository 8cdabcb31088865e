//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988): keep the
//! unshot radiance ΔLᵢ of every patch; repeatedly take the patch with the
//! most unshot power ΔLᵢ Aᵢ, get its shooting coefficients on demand
//! ([`ShootingRows`]: a ray-cast or hemicube row from the shooter, or a
//! stored matrix's column) and distribute: ΔHⱼ = Sᵢⱼ ΔLᵢ, Hⱼ += ΔHⱼ,
//! ΔLⱼ += ρⱼ ΔHⱼ. Nothing n × n is kept: memory is O(n). Stops when the
//! unshot power falls below `tolerance` × the initial power. (The bake then
//! gathers once at every patch from its own row; see `radbake::bake`.)

use super::{ShootingRows, Solution, System};
use glam::Vec3;
use rayon::prelude::*;

/// Result of a progressive solve.
pub struct Progressive {
    /// The solution (`shots` fired, `residual` = unshot fraction).
    pub solution: Solution,
    /// Σⱼ Fᵢⱼ of every patch that shot (NaN for patches that never did).
    pub row_sums: Vec<f32>,
}

/// Solves by shooting until the unshot power is below `tolerance` of the
/// initial power or `max_shots` shots have been fired.
pub fn solve(
    rows: &dyn ShootingRows,
    sys: &System,
    tolerance: f32,
    max_shots: u64,
    advance: &dyn Fn(u64),
) -> Progressive {
    let n = sys.len();
    let mut radiance = sys.initial_radiance();
    let mut irradiance: Vec<Vec3> = sys.direct.to_vec();
    let mut unshot = radiance.clone();
    let mut row_sums = vec![f32::NAN; n];
    let power = |l: &[Vec3]| -> Vec<f64> {
        l.par_iter()
            .zip(sys.area)
            .map(|(l, a)| (l.element_sum() * a) as f64)
            .collect()
    };
    let initial: f64 = power(&unshot).iter().sum();
    let mut shots = 0u64;
    let mut residual = if initial > 0.0 { 1.0f32 } else { 0.0 };
    while initial > 0.0 && shots < max_shots {
        // The shooter: most unshot power (first index on ties: deterministic).
        let p = power(&unshot);
        let remaining: f64 = p.iter().sum();
        residual = (remaining / initial) as f32;
        if residual < tolerance {
            break;
        }
        let (i, _) = p
            .iter()
            .enumerate()
            .fold((0usize, f64::NEG_INFINITY), |best, (k, &v)| {
                if v > best.1 {
                    (k, v)
                } else {
                    best
                }
            });
        let shoot = unshot[i];
        unshot[i] = Vec3::ZERO;
        let (row, sum) = rows.shooting_row(i);
        row_sums[i] = sum;
        for (j, s) in row {
            let j = j as usize;
            let dh = shoot * s;
            irradiance[j] += dh;
            let dl = sys.albedo[j] * dh;
            radiance[j] += dl;
            unshot[j] += dl;
        }
        shots += 1;
        advance(1);
    }
    if shots >= max_shots {
        let remaining: f64 = power(&unshot).iter().sum();
        residual = if initial > 0.0 {
            (remaining / initial) as f32
        } else {
            0.0
        };
    }
    Progressive {
        solution: Solution {
            radiance,
            irradiance,
            iterations: 0,
            residual,
            shots,
        },
        row_sums,
    }
}
