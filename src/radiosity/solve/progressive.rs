//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988): keep the
//! unshot radiance ΔLᵢ of every patch; repeatedly take the patches with the
//! most unshot power ΔLᵢ Aᵢ, get their shooting coefficients on demand
//! ([`ShootingRows`]: a ray-cast or hemicube row from the shooter, or a
//! stored matrix's column) and distribute: ΔHⱼ = Sᵢⱼ ΔLᵢ, Hⱼ += ΔHⱼ,
//! ΔLⱼ += ρⱼ ΔHⱼ. Up to [`BATCH`] shooters go per step, their rows cast in
//! parallel and applied in a fixed order, so the result does not depend on
//! the thread count. Nothing n × n is kept: memory is O(n) plus a row cache
//! sized by the memory available ([`cache_budget`]; a patch is typically
//! shot many times). Stops when the
//! unshot power falls below `tolerance` × the initial power.
//! [`gather_sweeps`] then gathers at every patch from its own row.

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
    /// The shooting rows still cached at the end, for [`gather_sweeps`].
    pub rows: ShotRows,
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

/// A progressive solve as it stands, shown to `solve`'s observer every 64
/// shots and at the end.
pub struct Partial<'a> {
    /// The unshot power left, a fraction of the initial.
    pub unshot_fraction: f64,
    /// Hⱼ so far (direct plus the light shot so far), irradiance / π.
    pub irradiance: &'a [Vec3],
    /// ΔLⱼ, the radiance not yet shot.
    pub unshot: &'a [Vec3],
    /// Shots fired.
    pub shots: u64,
    /// True at the last call.
    pub done: bool,
}

/// The ambient term of Cohen, Chen, Wallace & Greenberg (1988, §3.2):
/// the light not yet shot, spread as if it arrived evenly everywhere and
/// kept interreflecting: ambient = R Σᵢ ΔLᵢ Aᵢ / Σᵢ Aᵢ with the
/// interreflection factor R = 1 / (1 − ρ̄), ρ̄ = Σᵢ ρᵢ Aᵢ / Σᵢ Aᵢ, per
/// channel. Added to every patch's H (irradiance / π) it gives a usable
/// picture long before convergence, exact for a closed uniform enclosure,
/// and it falls to zero as the unshot light does.
pub fn ambient(sys: &System, unshot: &[Vec3]) -> Vec3 {
    let (mut area, mut rho, mut power) = (0.0f64, [0.0f64; 3], [0.0f64; 3]);
    for (i, u) in unshot.iter().enumerate() {
        let a = sys.area[i] as f64;
        area += a;
        for c in 0..3 {
            rho[c] += sys.albedo[i][c] as f64 * a;
            power[c] += u[c] as f64 * a;
        }
    }
    if area <= 0.0 {
        return Vec3::ZERO;
    }
    let term = |c: usize| {
        let r = (rho[c] / area).min(0.999);
        (power[c] / area / (1.0 - r)) as f32
    };
    Vec3::new(term(0), term(1), term(2))
}

/// Up to this many patches the shooter is found by a linear scan.
const SCAN_MAX_PATCHES: usize = 1 << 15;

/// The row cache's least budget in (column, value) entries: 32 M entries =
/// 256 MB ([`cache_budget`]).
const CACHE_MIN_ENTRIES: usize = 32 << 20;

/// Bytes of one cached (column, value) entry.
const ENTRY_BYTES: usize = std::mem::size_of::<(u32, f32)>();

/// The row cache's budget in entries: a quarter of the memory the system
/// reports available when the solve starts (`MemAvailable` in
/// `/proc/meminfo`; [`CACHE_MIN_ENTRIES`] where there is none), at least
/// [`CACHE_MIN_ENTRIES`]. A fixed 256 MB held 11 % of the furnace's rows at
/// its default density (20,184 patches, 290 M entries), and its patches,
/// each shot about 8 times, cast their hemicubes again and again: 189 s,
/// where the rows made once took 36 s (2.4 GB). What is cached changes
/// the time, never the result ([`ShotRows`]).
fn cache_budget() -> usize {
    available_memory().map_or(CACHE_MIN_ENTRIES, |bytes| {
        (bytes / 4 / ENTRY_BYTES as u64).clamp(CACHE_MIN_ENTRIES as u64, usize::MAX as u64) as usize
    })
}

/// The memory the system reports available, in bytes (Linux's
/// `MemAvailable`; None elsewhere or where it cannot be read).
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// Shooters per step: up to this many patches shoot together, their rows
/// computed concurrently (one row per thread) and then applied one after
/// another in the order they were picked.
pub const BATCH: usize = 16;

/// A patch joins a step only if its unshot power is at least this fraction
/// of the step's first (largest) shooter's: a step never shoots a patch
/// that a serial solve would have left for much later.
const BATCH_FLOOR: f64 = 0.5;

/// Unshot power ΔLᵢ Aᵢ (summed over the channels) of unshot radiance
/// `unshot` on a patch of `area`.
fn power_of(unshot: Vec3, area: f32) -> f64 {
    (unshot.element_sum() * area).max(0.0) as f64
}

/// What a receiver of albedo ρⱼ gets from a shot of unshot radiance
/// `shoot` through its coefficient Sᵢⱼ = `s`: (ΔHⱼ, ρⱼ ΔHⱼ).
#[inline(always)]
fn received(albedo: Vec3, s: f32, shoot: Vec3) -> (Vec3, Vec3) {
    let dh = shoot * s;
    (dh, albedo * dh)
}

/// One shot of a step: the shooter's row (sorted by column), the unshot
/// radiance it shoots, and, where the row is the shooter i's own row Fᵢ·
/// ([`ShotRows`]), Some(i): its entries are scaled by reciprocity as they
/// are applied; None where they are the Sᵢⱼ.
type Shot<'r> = (&'r [(u32, f32)], Vec3, Option<usize>);

/// Receivers per block of [`Shooting::shoot_all`]: fixed, so that the
/// result does not depend on the thread count.
const SHOT_BLOCK: usize = 2048;

/// The index of `row`'s first entry (sorted by distinct column, columns
/// below `n`) whose column is at least `col`: [`slice::partition_point`]'s
/// answer, searched outward from where `col` would lie were the row's
/// columns spread evenly. At a step's start its rows are out of the cache,
/// so a binary search's ~14 probes were ~14 misses, for each of a shot's
/// blocks (a fifth of the furnace's shooting time); a dense row's boundary
/// lies a few entries from the guess.
fn lower_bound(row: &[(u32, f32)], col: usize, n: usize) -> usize {
    let len = row.len();
    let below = |k: usize| (row[k].0 as usize) < col;
    let guess = (col as u64 * len as u64 / n.max(1) as u64).min(len as u64) as usize;
    // Gallop to a range [lo, hi) that holds the answer, then bisect it.
    let (lo, hi) = if guess < len && below(guess) {
        let (mut lo, mut step) = (guess + 1, 1);
        loop {
            let probe = guess + step;
            if probe >= len {
                break (lo, len);
            }
            if !below(probe) {
                break (lo, probe);
            }
            lo = probe + 1;
            step *= 2;
        }
    } else {
        let (mut hi, mut step) = (guess, 1);
        loop {
            if step > hi {
                break (0, hi);
            }
            let probe = hi - step;
            if below(probe) {
                break (probe + 1, hi);
            }
            hi = probe;
            step *= 2;
        }
    };
    lo + row[lo..hi].partition_point(|e| (e.0 as usize) < col)
}

/// One block of receivers of [`Shooting::shoot_blocks`]: its slices of
/// the shooting state and of the system, from patch `lo` on.
struct Block<'b> {
    h: &'b mut [Vec3],
    l: &'b mut [Vec3],
    u: &'b mut [Vec3],
    p: &'b mut [f64],
    area: &'b [f32],
    albedo: &'b [Vec3],
    lo: usize,
}

impl Block<'_> {
    /// A shot's `entries` in this block, each scaled by `scale(j, v)`
    /// ([`received`]); `change` plus the change of the
    /// unshot power, added entry by entry. (A loop, not a closure: a
    /// closure kept `change` in memory, a store and a load per entry.)
    #[inline(always)]
    fn take(
        &mut self,
        entries: &[(u32, f32)],
        shoot: Vec3,
        mut change: f64,
        scale: impl Fn(usize, f32) -> f32,
    ) -> f64 {
        for &(j, v) in entries {
            let j = j as usize;
            let k = j - self.lo;
            let (dh, dl) = received(self.albedo[k], scale(j, v), shoot);
            self.h[k] += dh;
            self.l[k] += dl;
            self.u[k] += dl;
            let pw = power_of(self.u[k], self.area[k]);
            change += pw - self.p[k];
            self.p[k] = pw;
        }
        change
    }
}

/// The shooting state: radiance, irradiance and unshot radiance per patch,
/// their unshot powers ΔLᵢ·1 Aᵢ, and the structure that finds the largest.
struct Shooting<'a> {
    sys: &'a System<'a>,
    radiance: Vec<Vec3>,
    irradiance: Vec<Vec3>,
    unshot: Vec<Vec3>,
    powers: Vec<f64>,
    tree: Option<Tournament>,
    remaining: f64,
}

impl<'a> Shooting<'a> {
    fn new(sys: &'a System<'a>) -> Shooting<'a> {
        let radiance = sys.initial_radiance();
        let mut s = Shooting {
            sys,
            irradiance: sys.direct.to_vec(),
            unshot: radiance.clone(),
            radiance,
            powers: Vec::new(),
            tree: None,
            remaining: 0.0,
        };
        s.powers = (0..sys.len()).map(|i| s.power(i)).collect();
        s.remaining = s.powers.iter().sum();
        // Small scenes scan (a contiguous scan of a few thousand powers
        // beats the tree's scattered updates when rows are long: 34.3 ms
        // against 93.3 ms on the Cornell bench); large ones use the tree.
        // Both pick the same shooter, so results do not depend on the choice.
        s.tree = (sys.len() > SCAN_MAX_PATCHES).then(|| Tournament::new(&s.powers));
        s
    }

    fn power(&self, i: usize) -> f64 {
        power_of(self.unshot[i], self.sys.area[i])
    }

    /// The patch with the most unshot power (the first index on ties, so
    /// the order is deterministic).
    fn argmax(&self) -> usize {
        match &self.tree {
            Some(t) => t.argmax(),
            None => (0..self.powers.len()).fold(0, |b, k| {
                if self.powers[k] > self.powers[b] {
                    k
                } else {
                    b
                }
            }),
        }
    }

    fn set_power(&mut self, i: usize) {
        let p = self.power(i);
        self.remaining += p - self.powers[i];
        self.powers[i] = p;
        if let Some(t) = &mut self.tree {
            t.update(&self.powers, i);
        }
    }

    /// The next step's shooters, each with the unshot radiance it shoots
    /// (taken from it now): the largest first, then every next-largest
    /// down to [`BATCH_FLOOR`] of it, at most `limit`. Depends only on the
    /// powers, never on the thread count.
    fn pick(&mut self, limit: usize) -> Vec<(usize, Vec3)> {
        let order = match self.tree {
            Some(_) => None,
            None => Some(self.largest(limit)),
        };
        let mut batch = Vec::with_capacity(limit);
        let mut first = 0.0;
        while batch.len() < limit {
            let i = match &order {
                Some(order) => match order.get(batch.len()) {
                    Some(&i) => i,
                    // Every patch with power left is in the batch.
                    None => break,
                },
                None => self.argmax(),
            };
            let p = self.powers.get(i).copied().unwrap_or(0.0);
            if p == 0.0 || p < first * BATCH_FLOOR {
                break;
            }
            if batch.is_empty() {
                first = p;
            }
            batch.push((i, self.unshot[i]));
            self.unshot[i] = Vec3::ZERO;
            self.set_power(i);
        }
        batch
    }

    /// The (at most) `limit` patches with the most unshot power above 0,
    /// largest first and the first index first among equals: the order
    /// in which repeated [`Shooting::argmax`] scans, each after zeroing
    /// the patch it found, would name them, in one scan instead of
    /// `limit` (16 scans a step were 5 % of the furnace's progressive
    /// solve).
    fn largest(&self, limit: usize) -> Vec<usize> {
        let mut top: Vec<(f64, usize)> = Vec::with_capacity(limit + 1);
        let mut floor = 0.0;
        for (k, &p) in self.powers.iter().enumerate() {
            if p > floor {
                // After every one at least as large: earlier indices win ties.
                let at = top.partition_point(|&(q, _)| q >= p);
                top.insert(at, (p, k));
                top.truncate(limit);
                if top.len() == limit {
                    floor = top[limit - 1].0;
                }
            }
        }
        top.into_iter().map(|(_, k)| k).collect()
    }

    fn show(&self, initial: f64, shots: u64, done: bool, observe: &mut dyn FnMut(&Partial)) {
        observe(&Partial {
            unshot_fraction: self.remaining.max(0.0) / initial,
            irradiance: &self.irradiance,
            unshot: &self.unshot,
            shots,
            done,
        });
    }

    /// Applies a step's shots in order, each distributing its unshot
    /// radiance along its shooter's coefficients: ΔHⱼ = Sᵢⱼ ΔLᵢ, Hⱼ += ΔHⱼ,
    /// Lⱼ += ρⱼ ΔHⱼ, ΔLⱼ += ρⱼ ΔHⱼ ([`Shot`]).
    ///
    /// Receivers are taken in fixed blocks of [`SHOT_BLOCK`]: each block
    /// sees its entries of every shot in the shots' order, so each receiver
    /// gets exactly the serial sequence of updates, and the blocks' changes
    /// of the unshot power are summed per block, then in block order: the
    /// same bits whether the blocks run in parallel (long rows: the
    /// furnace's 155,320 shots of ~14 k entries, distributed one after
    /// another, took 12 of its 34 s) or one after another (short rows over
    /// many patches, where most blocks would be empty).
    fn shoot_all(&mut self, shots: &[Shot]) {
        debug_assert!(shots
            .iter()
            .all(|s| s.0.windows(2).all(|w| w[0].0 < w[1].0)));
        let blocks = self.powers.len().div_ceil(SHOT_BLOCK);
        let entries: usize = shots.iter().map(|s| s.0.len()).sum();
        let changes = if entries >= 8 * blocks * shots.len() {
            self.shoot_blocks(shots)
        } else {
            self.shoot_entries(shots, blocks)
        };
        for c in changes {
            self.remaining += c;
        }
        if let Some(t) = &mut self.tree {
            for &(row, _, _) in shots {
                for &(j, _) in row {
                    t.update(&self.powers, j as usize);
                }
            }
        }
    }

    /// [`Shooting::shoot_all`]'s blocks in parallel: the change of the
    /// unshot power per block.
    fn shoot_blocks(&mut self, shots: &[Shot]) -> Vec<f64> {
        let sys = self.sys;
        let n = sys.len();
        (self.irradiance.par_chunks_mut(SHOT_BLOCK))
            .zip(self.radiance.par_chunks_mut(SHOT_BLOCK))
            .zip(self.unshot.par_chunks_mut(SHOT_BLOCK))
            .zip(self.powers.par_chunks_mut(SHOT_BLOCK))
            .enumerate()
            .map(|(b, (((h, l), u), p))| {
                let lo = b * SHOT_BLOCK;
                let hi = lo + h.len();
                let mut block = Block {
                    h,
                    l,
                    u,
                    p,
                    area: &sys.area[lo..hi],
                    albedo: &sys.albedo[lo..hi],
                    lo,
                };
                let mut change = 0.0f64;
                for &(row, shoot, reciprocal) in shots {
                    let start = lower_bound(row, lo, n);
                    let entries = &row[start..lower_bound(row, hi, n)];
                    change = match reciprocal {
                        Some(i) => block.take(entries, shoot, change, |j, v| {
                            crate::radiosity::solve::reciprocal(v, i, j, sys.area)
                        }),
                        None => block.take(entries, shoot, change, |_, v| v),
                    };
                }
                change
            })
            .collect()
    }

    /// [`Shooting::shoot_all`] entry by entry, the changes of the unshot
    /// power still summed per block (in the order the blocks sum them).
    fn shoot_entries(&mut self, shots: &[Shot], blocks: usize) -> Vec<f64> {
        let sys = self.sys;
        let mut changes = vec![0.0f64; blocks];
        for &(row, shoot, reciprocal) in shots {
            for &(j, v) in row {
                let j = j as usize;
                let s = reciprocal.map_or(v, |i| {
                    crate::radiosity::solve::reciprocal(v, i, j, sys.area)
                });
                let (dh, dl) = received(sys.albedo[j], s, shoot);
                self.irradiance[j] += dh;
                self.radiance[j] += dl;
                self.unshot[j] += dl;
                let pw = power_of(self.unshot[j], sys.area[j]);
                changes[j / SHOT_BLOCK] += pw - self.powers[j];
                self.powers[j] = pw;
            }
        }
        changes
    }
}

/// Rows of patches that may shoot again. A row pays only while its patch
/// can still gather unshot light: a black patch (ρ = 0) shoots once, so
/// its row is never kept ([`ShotRows::pays`]). When the budget is full,
/// the half of the rows whose patches hold the least unshot power (the
/// least likely to shoot soon) is dropped. What is cached changes the
/// time, never the result: where the source's rows are reciprocal
/// ([`ShootingRows::reciprocal_rows`]) the cache holds each patch's own
/// row Fᵢ· exactly as it would be made again, and scales it as it shoots.
/// (It used to hold the scaled Sᵢ· and scale them back for the gathering
/// sweeps, which is exact only up to rounding: the lightmaps then depended
/// on which rows the budget had kept.)
#[derive(Default)]
pub struct ShotRows {
    rows: HashMap<u32, (Vec<(u32, f32)>, f32)>,
    entries: usize,
    /// Most entries held ([`cache_budget`]).
    budget: usize,
    /// The rows are the patches' own rows Fᵢ·, not shooting rows Sᵢ·.
    reciprocal: bool,
}

impl ShotRows {
    fn new(budget: usize) -> ShotRows {
        ShotRows {
            budget,
            ..ShotRows::default()
        }
    }

    fn pays(i: usize, sys: &System) -> bool {
        sys.albedo[i] != Vec3::ZERO
    }

    /// Drops rows until `need` more entries fit, never those of `batch`.
    fn make_room(&mut self, need: usize, st: &Shooting, batch: &[(usize, Vec3)]) {
        if self.entries + need <= self.budget {
            return;
        }
        let mut held: Vec<(f64, u32)> = (self.rows.keys())
            .filter(|&&k| batch.iter().all(|b| b.0 != k as usize))
            .map(|&k| (st.powers[k as usize], k))
            .collect();
        held.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (dropped, &(_, k)) in held.iter().enumerate() {
            if dropped >= held.len().div_ceil(2) && self.entries + need <= self.budget {
                break;
            }
            if let Some(r) = self.rows.remove(&k) {
                self.entries -= r.0.len();
            }
        }
    }

    fn insert(&mut self, i: usize, row: (Vec<(u32, f32)>, f32)) {
        self.entries += row.0.len();
        self.rows.insert(i as u32, row);
    }
}

/// Solves by shooting until the unshot power is below `tolerance` of the
/// initial power or `max_shots` shots have been fired. Each step shoots up
/// to [`BATCH`] patches ([`Shooting::pick`]): their missing rows are
/// computed in parallel, one row per thread (splitting one row's rays over
/// threads was tried and was slower), then the shots are applied in the
/// order picked. The steps depend on the powers alone, so the result is
/// the same on any number of threads. `observe` is shown the solve as it
/// stands ([`Partial`]) every 64 shots and at the end: the convergence of
/// Cohen et al. (1988), fig. 5, as it happens.
pub fn solve(
    rows: &dyn ShootingRows,
    sys: &System,
    tolerance: f32,
    max_shots: u64,
    advance: &dyn Fn(u64),
    observe: &mut dyn FnMut(&Partial),
) -> Progressive {
    let mut cache = ShotRows::new(cache_budget());
    cache.reciprocal = rows.reciprocal_rows(&[]).is_some();
    solve_caching(rows, sys, (tolerance, max_shots), cache, advance, observe)
}

/// [`solve`] with the row cache `cache` (its budget set).
fn solve_caching(
    rows: &dyn ShootingRows,
    sys: &System,
    (tolerance, max_shots): (f32, u64),
    mut cache: ShotRows,
    advance: &dyn Fn(u64),
    observe: &mut dyn FnMut(&Partial),
) -> Progressive {
    let n = sys.len();
    let mut st = Shooting::new(sys);
    let initial = st.remaining;
    let mut row_sums = vec![f32::NAN; n];
    let (mut shots, mut resum) = (0u64, 0u64);
    if initial > 0.0 {
        st.show(initial, 0, false, observe);
    }
    while initial > 0.0 && shots < max_shots {
        if shots >= resum {
            st.remaining = st.powers.iter().sum(); // no drift from incremental updates
            resum = shots + 4096;
        }
        if st.remaining / initial < tolerance as f64 {
            break;
        }
        let batch = st.pick(BATCH.min((max_shots - shots) as usize));
        if batch.is_empty() {
            break;
        }
        let missing: Vec<usize> = (batch.iter())
            .filter(|(i, _)| !cache.rows.contains_key(&(*i as u32)))
            .map(|&(i, _)| i)
            .collect();
        let fresh = match cache.reciprocal {
            true => rows.reciprocal_rows(&missing).unwrap_or_default(),
            false => rows.shooting_rows(&missing),
        };
        let mut fresh: HashMap<usize, _> = missing.into_iter().zip(fresh).collect();
        let need = (fresh.iter())
            .filter(|(&i, _)| ShotRows::pays(i, sys))
            .map(|(_, r)| r.0.len())
            .sum();
        cache.make_room(need, &st, &batch);
        // Rows that do not pay are shot once from here.
        let mut once = HashMap::new();
        for &(i, _) in &batch {
            if let Some(r) = fresh.remove(&i) {
                if ShotRows::pays(i, sys) {
                    cache.insert(i, r);
                } else {
                    once.insert(i, r);
                }
            }
        }
        let step: Vec<Shot> = (batch.iter())
            .map(|&(i, shoot)| {
                let (row, sum) = once.get(&i).unwrap_or_else(|| &cache.rows[&(i as u32)]);
                row_sums[i] = *sum;
                (row.as_slice(), shoot, cache.reciprocal.then_some(i))
            })
            .collect();
        st.shoot_all(&step);
        let before = shots;
        shots += batch.len() as u64;
        advance(batch.len() as u64);
        if shots / 64 != before / 64 {
            st.show(initial, shots, false, observe);
        }
    }
    let remaining: f64 = st.powers.iter().sum();
    if initial > 0.0 {
        st.remaining = remaining;
        st.show(initial, shots, true, observe);
    }
    Progressive {
        solution: Solution {
            radiance: st.radiance,
            irradiance: st.irradiance,
            iterations: 0,
            residual: if initial > 0.0 {
                (remaining / initial) as f32
            } else {
                0.0
            },
            shots,
        },
        row_sums,
        rows: cache,
    }
}

/// Patches per batch of rows in [`gather_sweeps`].
const SWEEP_CHUNK: usize = 4096;

/// Gathering sweeps that complete a progressive solution: `sweeps` times,
/// every patch gathers from its own row, L ← E + ρ (D + F L). Shooting
/// scales a shooter's row by Aᵢ/Aⱼ (reciprocity), which is noisy for small
/// receivers (and biased for the hemicube's point-sampled rows); each sweep
/// puts the accuracy back on the receiving side (dividing the shooting
/// error by ~1/ρ). Rows are made and dropped, so memory stays O(n).
/// `shot`: rows the solve still holds; where they are the patches' own
/// rows Fⱼ· (a reciprocal source, [`ShootingRows::reciprocal_rows`], as
/// [`crate::radiosity::form_factors::rows::OnDemand`]) they are used as they are,
/// bit for bit the rows `rows` would make again, instead of being cast
/// again. Returns Σₖ Fⱼₖ per patch (every patch's row is computed).
pub fn gather_sweeps(
    rows: &dyn GatheringRows,
    sys: &System,
    solution: &mut Solution,
    sweeps: u32,
    shot: Option<&ShotRows>,
) -> Vec<f32> {
    // Held rows are each patch's own row, as `rows` would make it again.
    let cached = |j: usize| {
        shot.filter(|c| c.reciprocal)
            .and_then(|c| c.rows.get(&(j as u32)))
    };
    let mut gathered: Vec<(Vec3, f32)> = Vec::new();
    let all: Vec<usize> = (0..sys.len()).collect();
    for _ in 0..sweeps {
        gathered = Vec::with_capacity(sys.len());
        // A chunk at a time, so rows not cached come in large batches.
        for chunk in all.chunks(SWEEP_CHUNK) {
            let missing: Vec<usize> = chunk
                .iter()
                .copied()
                .filter(|&j| cached(j).is_none())
                .collect();
            let fresh: HashMap<usize, Vec<(u32, f32)>> = missing
                .iter()
                .copied()
                .zip(rows.gathering_rows(&missing))
                .collect();
            let part: Vec<(Vec3, f32)> = (chunk.par_iter())
                .map(|&j| {
                    let row: &[(u32, f32)] = match cached(j) {
                        Some((f, _)) => f,
                        None => &fresh[&j],
                    };
                    let h = row
                        .iter()
                        .map(|&(k, f)| solution.radiance[k as usize] * f)
                        .sum::<Vec3>();
                    (sys.direct[j] + h, row.iter().map(|e| e.1).sum())
                })
                .collect();
            gathered.extend(part);
        }
        solution.irradiance = gathered.iter().map(|g| g.0).collect();
        solution.radiance = (0..sys.len())
            .map(|j| sys.emission[j] + sys.albedo[j] * solution.irradiance[j])
            .collect();
    }
    gathered.iter().map(|g| g.1).collect()
}

#[cfg(test)]
mod tests {
    use super::{lower_bound, Tournament};
    use crate::util::sampling::Stream;

    /// Rows Fᵢ· of a random enclosure-like system, counting the rows made;
    /// a reciprocal source, as the bake's on-demand rows are.
    struct Counted {
        rows: Vec<Vec<(u32, f32)>>,
        area: Vec<f32>,
        made: std::sync::atomic::AtomicUsize,
    }

    impl Counted {
        fn made(&self, i: usize) -> Vec<(u32, f32)> {
            self.made.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.rows[i].clone()
        }
    }

    impl crate::radiosity::solve::ShootingRows for Counted {
        fn shooting_row(&self, i: usize) -> (Vec<(u32, f32)>, f32) {
            let r = self.made(i);
            let sum = r.iter().map(|e| e.1).sum();
            let s = r.into_iter().map(|(j, f)| {
                (
                    j,
                    crate::radiosity::solve::reciprocal(f, i, j as usize, &self.area),
                )
            });
            (s.collect(), sum)
        }
        fn reciprocal_rows(&self, batch: &[usize]) -> Option<crate::radiosity::solve::SummedRows> {
            let rows = batch.iter().map(|&i| {
                let r = self.made(i);
                let sum = r.iter().map(|e| e.1).sum();
                (r, sum)
            });
            Some(rows.collect())
        }
    }

    impl crate::radiosity::solve::GatheringRows for Counted {
        fn gathering_row(&self, i: usize) -> Vec<(u32, f32)> {
            self.made(i)
        }
    }

    /// The row cache's budget changes how often rows are made, never the
    /// solution: a cache of 50 entries (a row and a half) against one that
    /// holds every row, through the shooting and the two gathering sweeps
    /// (which take the held rows), bit for bit. (With the cache holding
    /// scaled shooting rows, scaled back for the sweeps, the two differed
    /// in the last bits.)
    #[test]
    fn the_cache_budget_changes_only_the_time() {
        use glam::Vec3;
        let n = 120;
        let mut rng = Stream::new(11, 0, 0);
        let area: Vec<f32> = (0..n).map(|i| 1.0 + (i % 5) as f32 * 0.37).collect();
        let rows: Vec<Vec<(u32, f32)>> = (0..n)
            .map(|i| {
                let mut row = Vec::new();
                for j in 0..n as u32 {
                    if j as usize != i && rng.below(3) == 0 {
                        row.push((j, 0.9 / 40.0 * (0.5 + rng.below(100) as f32 / 100.0)));
                    }
                }
                row
            })
            .collect();
        let emission: Vec<Vec3> = (0..n)
            .map(|i| if i % 17 == 0 { Vec3::ONE } else { Vec3::ZERO })
            .collect();
        let albedo = vec![Vec3::splat(0.8); n];
        let direct = vec![Vec3::ZERO; n];
        let sys = crate::radiosity::solve::System {
            emission: &emission,
            albedo: &albedo,
            direct: &direct,
            area: &area,
        };
        let solve = |budget| {
            let src = Counted {
                rows: rows.clone(),
                area: area.clone(),
                made: Default::default(),
            };
            let mut cache = super::ShotRows::new(budget);
            cache.reciprocal = true;
            let out =
                super::solve_caching(&src, &sys, (1e-4, 100_000), cache, &|_| {}, &mut |_| {});
            let shot = src.made.swap(0, std::sync::atomic::Ordering::Relaxed);
            let mut solution = out.solution;
            super::gather_sweeps(&src, &sys, &mut solution, 2, Some(&out.rows));
            (solution.radiance, shot, src.made.into_inner())
        };
        let (small, shot_small, swept_small) = solve(50);
        let (large, shot_large, swept_large) = solve(usize::MAX);
        assert_eq!((shot_large, swept_large), (n, 0), "every row made once");
        assert!(shot_small > 2 * n, "rows made {shot_small}");
        assert!(swept_small > n, "rows made for the sweeps {swept_small}");
        assert!(small
            .iter()
            .zip(&large)
            .all(|(a, b)| a.to_array() == b.to_array()));
        assert!(large.iter().any(|r| r.x > 0.0));
    }

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

    /// `lower_bound` is `partition_point` on sparse, dense and empty rows.
    #[test]
    fn lower_bound_is_partition_point() {
        let mut rng = crate::util::sampling::Stream::new(7, 0, 0);
        for &(n, keep) in &[
            (1000usize, 0.7f32),
            (1000, 0.05),
            (50, 1.0),
            (3000, 0.002),
            (10, 0.0),
        ] {
            let row: Vec<(u32, f32)> = (0..n as u32)
                .filter(|_| rng.next_f32() < keep)
                .map(|j| (j, 1.0))
                .collect();
            for col in 0..=n {
                let want = row.partition_point(|e| (e.0 as usize) < col);
                assert_eq!(
                    lower_bound(&row, col, n),
                    want,
                    "n {n}, keep {keep}, col {col}"
                );
            }
        }
    }
}
