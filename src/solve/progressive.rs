//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988): keep the
//! unshot radiance ΔLᵢ of every patch; repeatedly take the patch with the
//! most unshot power ΔLᵢ Aᵢ, get its shooting coefficients on demand
//! ([`ShootingRows`]: a ray-cast or hemicube row from the shooter, or a
//! stored matrix's column) and distribute: ΔHⱼ = Sᵢⱼ ΔLᵢ, Hⱼ += ΔHⱼ,
//! ΔLⱼ += ρⱼ ΔHⱼ. Nothing n × n is kept: memory is O(n) plus a row cache of
//! fixed size (a patch is typically shot many times). Stops when the unshot
//! power falls below `tolerance` × the initial power. (The bake then
//! gathers at every patch from its own row; see `radbake::bake`.)

use super::{ShootingRows, Solution, System};
use glam::Vec3;
use std::collections::HashMap;

/// Result of a progressive solve.
pub struct Progressive {
    /// The solution (`shots` fired, `residual` = unshot fraction).
    pub solution: Solution,
    /// Σⱼ Fᵢⱼ of every patch that shot (NaN for patches that never did).
    pub row_sums: Vec<f32>,
}

/// Row-cache budget in (column, value) entries: 32 M entries = 256 MB.
const CACHE_ENTRIES: usize = 32 << 20;

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
    let power = |l: Vec3, i: usize| (l.element_sum() * sys.area[i]).max(0.0) as f64;
    let mut powers: Vec<f64> = (0..n).map(|i| power(unshot[i], i)).collect();
    let initial: f64 = powers.iter().sum();
    let mut remaining = initial;
    let mut cache: HashMap<u32, (Vec<(u32, f32)>, f32)> = HashMap::new();
    let mut cached = 0usize;
    let mut shots = 0u64;
    while initial > 0.0 && shots < max_shots {
        if shots % 4096 == 0 {
            remaining = powers.iter().sum(); // no drift from incremental updates
        }
        if remaining / initial < tolerance as f64 {
            break;
        }
        // The shooter: most unshot power (a linear scan is cheaper than a
        // heap here, since every shot changes hundreds of entries; the first
        // index wins ties, so the order is deterministic).
        let mut i = 0;
        for (k, &p) in powers.iter().enumerate() {
            if p > powers[i] {
                i = k;
            }
        }
        if powers[i] == 0.0 {
            break;
        }
        let shoot = unshot[i];
        unshot[i] = Vec3::ZERO;
        remaining -= powers[i];
        powers[i] = 0.0;
        if !cache.contains_key(&(i as u32)) {
            let r = rows.shooting_row(i);
            if cached + r.0.len() > CACHE_ENTRIES {
                cache.clear();
                cached = 0;
            }
            cached += r.0.len();
            cache.insert(i as u32, r);
        }
        let (row, sum) = &cache[&(i as u32)];
        row_sums[i] = *sum;
        for &(j, s) in row {
            let j = j as usize;
            let dh = shoot * s;
            irradiance[j] += dh;
            let dl = sys.albedo[j] * dh;
            radiance[j] += dl;
            unshot[j] += dl;
            let p = power(unshot[j], j);
            remaining += p - powers[j];
            powers[j] = p;
        }
        shots += 1;
        advance(1);
    }
    let remaining: f64 = powers.iter().sum();
    Progressive {
        solution: Solution {
            radiance,
            irradiance,
            iterations: 0,
            residual: if initial > 0.0 {
                (remaining / initial) as f32
            } else {
                0.0
            },
            shots,
        },
        row_sums,
    }
}
