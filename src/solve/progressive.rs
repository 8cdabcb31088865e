//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988): keep the
//! unshot radiance ΔLᵢ of every patch; repeatedly take the patch with the
//! most unshot power ΔLᵢ Aᵢ, get its shooting coefficients on demand
//! ([`ShootingRows`]: a ray-cast or hemicube row from the shooter, or a
//! stored matrix's column) and distribute: ΔHⱼ = Sᵢⱼ ΔLᵢ, Hⱼ += ΔHⱼ,
//! ΔLⱼ += ρⱼ ΔHⱼ. Nothing n × n is kept: memory is O(n) plus a row cache of
//! fixed size (a patch is typically shot many times). Stops when the unshot
//! power falls below `tolerance` × the initial power. [`gather_sweeps`]
//! then gathers at every patch from its own row.

use super::{GatheringRows, ShootingRows, Solution, System};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// Result of a progressive solve.
pub struct Progressive {
    /// The solution (`shots` fired, `residual` = unshot fraction).
    pub solution: Solution,
    /// Σⱼ Fᵢⱼ of every patch that shot (NaN for patches that never did).
    pub row_sums: Vec<f32>,
}

/// A tournament (winner) tree over the patches' unshot powers: the index of
/// the largest in O(1), an update in O(log n). A linear scan per shot made
/// progressive refinement O(n) per shot, O(n²) for a scene whose every patch
/// receives direct light (a million patches: hours); the tree picks the
/// same shooter as the scan, ties to the lower index.
struct Tournament {
    /// Leaves start at `size`; `node[k]` is the winning patch of its subtree.
    node: Vec<u32>,
    size: usize,
}

impl Tournament {
    fn new(powers: &[f64]) -> Tournament {
        let size = powers.len().next_power_of_two().max(1);
        let mut node = vec![u32::MAX; 2 * size];
        for (i, slot) in node[size..size + powers.len()].iter_mut().enumerate() {
            *slot = i as u32;
        }
        let mut t = Tournament { node, size };
        for k in (1..size).rev() {
            t.node[k] = t.winner(powers, t.node[2 * k], t.node[2 * k + 1]);
        }
        t
    }

    /// The larger of two entries (`u32::MAX`: empty); the lower index on ties.
    #[inline]
    fn winner(&self, powers: &[f64], a: u32, b: u32) -> u32 {
        match (a, b) {
            (u32::MAX, _) => b,
            (_, u32::MAX) => a,
            _ if powers[b as usize] > powers[a as usize] => b,
            _ => a,
        }
    }

    fn argmax(&self) -> usize {
        self.node[1.min(self.node.len() - 1)] as usize
    }

    /// Re-plays the matches above leaf `i` after `powers[i]` changed.
    fn update(&mut self, powers: &[f64], i: usize) {
        let mut k = (self.size + i) / 2;
        while k >= 1 {
            let w = self.winner(powers, self.node[2 * k], self.node[2 * k + 1]);
            // The same winner, whose power did not change: nothing above
            // changes either.
            if self.node[k] == w && w as usize != i {
                break;
            }
            self.node[k] = w;
            k /= 2;
        }
    }
}

/// Up to this many patches the shooter is found by a linear scan.
const SCAN_MAX_PATCHES: usize = 1 << 15;

/// Row-cache budget in (column, value) entries: 32 M entries = 256 MB.
const CACHE_ENTRIES: usize = 32 << 20;

/// Solves by shooting until the unshot power is below `tolerance` of the
/// initial power or `max_shots` shots have been fired. `unshot` is told
/// the unshot power left (a fraction of the initial) every 64 shots and at
/// the end: the convergence of Cohen et al. (1988), fig. 5, as it happens.
pub fn solve(
    rows: &dyn ShootingRows,
    sys: &System,
    tolerance: f32,
    max_shots: u64,
    advance: &dyn Fn(u64),
    unshot_left: &dyn Fn(f64),
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
    // Small scenes scan (a contiguous scan of a few thousand powers beats
    // the tree's scattered updates when rows are long: 34.3 ms against
    // 93.3 ms on the Cornell bench); large ones use the tree. Both pick the
    // same shooter, so results do not depend on the choice.
    let mut tree = (n > SCAN_MAX_PATCHES).then(|| Tournament::new(&powers));
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
        // The shooter: most unshot power (the first index wins ties, so the
        // order is deterministic).
        let i = match &tree {
            Some(t) => t.argmax(),
            None => (0..n).fold(0, |b, k| if powers[k] > powers[b] { k } else { b }),
        };
        if powers[i] == 0.0 {
            break;
        }
        let shoot = unshot[i];
        unshot[i] = Vec3::ZERO;
        remaining -= powers[i];
        powers[i] = 0.0;
        if let Some(t) = &mut tree {
            t.update(&powers, i);
        }
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
            if let Some(t) = &mut tree {
                t.update(&powers, j);
            }
        }
        shots += 1;
        advance(1);
        if shots % 64 == 0 {
            unshot_left(remaining.max(0.0) / initial);
        }
    }
    let remaining: f64 = powers.iter().sum();
    if initial > 0.0 {
        unshot_left(remaining / initial);
    }
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

/// Gathering sweeps that complete a progressive solution: `sweeps` times,
/// every patch gathers from its own row, L ← E + ρ (D + F L). Shooting
/// scales a shooter's row by Aᵢ/Aⱼ (reciprocity), which is noisy for small
/// receivers (and biased for the hemicube's point-sampled rows); each sweep
/// puts the accuracy back on the receiving side (dividing the shooting
/// error by ~1/ρ). Rows are made and dropped, so memory stays O(n).
/// Returns Σⱼ Fᵢⱼ per patch (every patch's row is computed).
pub fn gather_sweeps(
    rows: &dyn GatheringRows,
    sys: &System,
    solution: &mut Solution,
    sweeps: u32,
) -> Vec<f32> {
    let mut gathered: Vec<(Vec3, f32)> = Vec::new();
    for _ in 0..sweeps {
        gathered = (0..sys.len())
            .into_par_iter()
            .map(|j| {
                let row = rows.gathering_row(j);
                let h = row
                    .iter()
                    .map(|&(k, f)| solution.radiance[k as usize] * f)
                    .sum::<Vec3>();
                (sys.direct[j] + h, row.iter().map(|e| e.1).sum())
            })
            .collect();
        solution.irradiance = gathered.iter().map(|g| g.0).collect();
        solution.radiance = (0..sys.len())
            .map(|j| sys.emission[j] + sys.albedo[j] * solution.irradiance[j])
            .collect();
    }
    gathered.iter().map(|g| g.1).collect()
}

#[cfg(test)]
mod tests {
    use super::Tournament;
    use crate::sampling::Stream;

    /// The tree always names the patch a linear scan (first index on ties)
    /// would, through random updates, zeros and ties, for sizes that are and
    /// are not powers of two.
    #[test]
    fn tournament_matches_linear_scan() {
        for n in [1usize, 2, 3, 7, 64, 1000] {
            let mut rng = Stream::new(3, 0, n as u64);
            let mut powers: Vec<f64> = (0..n).map(|_| rng.below(8) as f64).collect();
            let mut tree = Tournament::new(&powers);
            for _ in 0..5000 {
                let scan = (0..n).fold(0, |b, k| if powers[k] > powers[b] { k } else { b });
                assert_eq!(tree.argmax(), scan, "n = {n}");
                let i = rng.below(n as u32) as usize;
                powers[i] = if rng.below(4) == 0 {
                    0.0
                } else {
                    rng.below(8) as f64
                };
                tree.update(&powers, i);
            }
        }
    }
}
