//! The live layer's light probes: they follow the sun as the pages do.
//!
//! A probe's radiance SH is Lₗₘ = ∫ L(ω) Yₗₘ(ω) dω. The bake records,
//! for each probe, the patch that each ray of a spherical Fibonacci set of
//! n directions meets ([`crate::format::ProbeHits`]). A surface seen by a
//! probe sends it its outgoing radiance, which at patch resolution is the
//! patch's L = ρ ⊙ (D + F L), the quantity the solve keeps. So the change
//! of a probe's SH since the baked sun is
//!
//! ΔLₗₘ = (4π / n) Σᵢ (L_now − L_baked)(patch hit by ray i) · Yₗₘ(ωᵢ),
//!
//! and the live layer's probes at run time are the baked ones + ΔL
//! ([`crate::Live::probe_delta`]): exact at the baked sun, with the
//! patch-resolution estimate applied only to what changed. Invalid probes
//! (inside solids) take their neighbours' ΔL as the bake fills their light
//! ([`fill_plan`]), and the fill is linear, so baked + ΔL is filled too.
//!
//! SH are real L2, in three.js's `SphericalHarmonics3` order and
//! normalisation, as `probes.bin`; irradiance from radiance SH by
//! Ramamoorthi & Hanrahan (2001) eq. 7–8.

/// Nine RGB radiance SH coefficients (Y₀₀, Y₁₋₁, Y₁₀, Y₁₁, Y₂₋₂, Y₂₋₁,
/// Y₂₀, Y₂₁, Y₂₂).
pub type Sh9 = [[f32; 3]; 9];

/// Direction `i` of a spherical Fibonacci set of `n` (Keinert et al. 2015,
/// "Spherical Fibonacci Mapping"): equal-area bands in z, golden-angle
/// steps in φ.
pub fn fibonacci(i: u32, n: u32) -> [f32; 3] {
    let golden = 0.618_034_f64; // φ − 1
    let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * (i as f64 * golden).fract();
    [(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]
}

/// The nine real SH basis functions at unit direction `d`.
#[inline]
pub fn basis(d: [f32; 3]) -> [f32; 9] {
    let [x, y, z] = d;
    [
        0.282_095,
        0.488_603 * y,
        0.488_603 * z,
        0.488_603 * x,
        1.092_548 * x * y,
        1.092_548 * y * z,
        0.315_392 * (3.0 * z * z - 1.0),
        1.092_548 * x * z,
        0.546_274 * (x * x - y * y),
    ]
}

/// Âₗ / π per coefficient (the clamped cosine's bands π, 2π/3, π/4, over
/// π), so that [`irradiance_over_pi`] gives E / π, the lightmap's quantity.
const COSINE_OVER_PI: [f32; 9] = [
    1.0,
    2.0 / 3.0,
    2.0 / 3.0,
    2.0 / 3.0,
    0.25,
    0.25,
    0.25,
    0.25,
    0.25,
];

/// Irradiance / π on a surface of normal `n` lit by radiance `sh`, not
/// clamped (a change of light may be negative).
pub fn irradiance_over_pi(sh: &Sh9, n: [f32; 3]) -> [f32; 3] {
    let y = basis(n);
    let mut e = [0.0; 3];
    for k in 0..9 {
        for c in 0..3 {
            e[c] += sh[k][c] * (COSINE_OVER_PI[k] * y[k]);
        }
    }
    e
}

/// The six axis normals of Valve's ambient cube (Mitchell 2006): +X, −X,
/// +Y, −Y, +Z, −Z, the face order of Bevy's irradiance volumes.
pub const AXES: [[f32; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

/// The ambient cube of `sh`: irradiance / π per axis normal ([`AXES`]),
/// not clamped (callers clamp a whole probe's light, not a change).
pub fn ambient_cube(sh: &Sh9) -> [[f32; 3]; 6] {
    AXES.map(|n| irradiance_over_pi(sh, n))
}

/// Bevy 0.19's irradiance-volume image for a grid of resolution `r`
/// (as its shader reads it, and radbake writes `probes_<k>.ktx2`): size
/// (Rx, 2·Ry, 3·Rz).
pub fn volume_size(r: [u32; 3]) -> [u32; 3] {
    [r[0], 2 * r[1], 3 * r[2]]
}

/// Where in [`volume_size`]'s image the ambient cube's `face` (2 · axis +
/// negative, [`AXES`]) of the probe at grid cell `c` goes: texel
/// (x, y + Ry·negative, z + Rz·axis), row-major.
pub fn volume_texel(r: [u32; 3], c: [u32; 3], face: usize) -> usize {
    let [sx, sy, _] = volume_size(r);
    let (axis, neg) = ((face / 2) as u32, (face % 2) as u32);
    let (x, y, z) = (c[0], c[1] + r[1] * neg, c[2] + r[2] * axis);
    (x + sx * (y + sy * z)) as usize
}

/// How the invalid probes of `grids` take their neighbours' light, in
/// the order to apply it: (probe, the filled probes whose mean it takes).
/// Ring by ring, each unfilled probe with filled neighbours among its 26
/// takes their mean, the neighbours being those filled before its ring
/// (so the result does not depend on the visiting order), as Unity and
/// Godot fill probes inside walls. Indices are global (`first + local`).
/// Probes that no ring reaches (a grid with no valid probe) are left out.
pub fn fill_plan(grids: &[crate::format::ProbeGrid], valid: &[bool]) -> Vec<(u32, Vec<u32>)> {
    let mut plan = Vec::new();
    for g in grids {
        let [rx, ry, rz] = g.resolution.map(|r| r as i64);
        let first = g.first as usize;
        let n = (rx * ry * rz) as usize;
        let Some(valid) = valid.get(first..first + n) else {
            continue;
        };
        let mut filled = valid.to_vec();
        let index = |x: i64, y: i64, z: i64| (x + rx * (y + ry * z)) as usize;
        loop {
            let mut ring: Vec<(u32, Vec<u32>)> = Vec::new();
            for i in (0..n).filter(|&i| !filled[i]) {
                let (x, y, z) = (i as i64 % rx, (i as i64 / rx) % ry, i as i64 / (rx * ry));
                let mut from = Vec::new();
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let (qx, qy, qz) = (x + dx, y + dy, z + dz);
                            let inside = (0..rx).contains(&qx)
                                && (0..ry).contains(&qy)
                                && (0..rz).contains(&qz);
                            if (dx, dy, dz) != (0, 0, 0) && inside && filled[index(qx, qy, qz)] {
                                from.push((first + index(qx, qy, qz)) as u32);
                            }
                        }
                    }
                }
                if !from.is_empty() {
                    ring.push(((first + i) as u32, from));
                }
            }
            if ring.is_empty() {
                break;
            }
            for (i, _) in &ring {
                filled[*i as usize - first] = true;
            }
            plan.extend(ring);
        }
    }
    plan
}

/// Applies [`fill_plan`]'s `plan` to `values` (one per probe): each
/// planned probe becomes the mean of its sources.
pub fn apply_fill<T: Copy>(plan: &[(u32, Vec<u32>)], values: &mut [T], mean: impl Fn(&[T]) -> T) {
    let mut from = Vec::new();
    for (i, sources) in plan {
        from.clear();
        from.extend(sources.iter().map(|&j| values[j as usize]));
        values[*i as usize] = mean(&from);
    }
}

/// The mean of a set of SH.
pub fn mean_sh(set: &[Sh9]) -> Sh9 {
    let mut m = [[0.0f32; 3]; 9];
    for sh in set {
        for k in 0..9 {
            for c in 0..3 {
                m[k][c] += sh[k][c];
            }
        }
    }
    let w = 1.0 / set.len().max(1) as f32;
    m.map(|c| c.map(|v| v * w))
}

/// Per ray of an n-ray Fibonacci set: its basis × 4π / n (the ray's
/// quadrature weight in steradians).
pub(crate) fn weighted_basis(n: u32) -> Vec<[f32; 9]> {
    let w = 4.0 * std::f32::consts::PI / n as f32;
    (0..n)
        .map(|i| basis(fibonacci(i, n)).map(|y| y * w))
        .collect()
}

/// ΔL per probe (unfilled): Σᵢ ΔL(hit i) · Yᵢ · 4π/n over its rays, for
/// `dl` the change of each patch's outgoing radiance; invalid probes 0.
pub(crate) fn delta(hits: &crate::format::ProbeHits, y: &[[f32; 9]], dl: &[[f32; 3]]) -> Vec<Sh9> {
    use rayon::prelude::*;
    let n = y.len();
    (hits.hits.par_chunks(n.max(1)).zip(hits.valid.par_iter()))
        .map(|(rays, &valid)| {
            let mut sh = [[0.0f32; 3]; 9];
            if !valid {
                return sh;
            }
            for (&p, y) in rays.iter().zip(y) {
                let Some(d) = dl.get(p as usize) else {
                    continue;
                };
                for k in 0..9 {
                    for c in 0..3 {
                        sh[k][c] += d[c] * y[k];
                    }
                }
            }
            sh
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::ProbeGrid;

    /// A uniform field of radiance 1 projects to √(4π) in the DC term and
    /// gives irradiance / π = 1 for every normal.
    #[test]
    fn a_uniform_field_gives_unit_irradiance() {
        let y = weighted_basis(256);
        let mut sh = [[0.0f32; 3]; 9];
        for y in &y {
            for k in 0..9 {
                sh[k][0] += y[k];
            }
        }
        assert!((sh[0][0] - (4.0 * std::f32::consts::PI).sqrt()).abs() < 1e-3);
        for face in ambient_cube(&sh) {
            assert!((face[0] - 1.0).abs() < 1e-2, "{face:?}");
        }
    }

    /// A row of three with the middle one invalid takes the mean of its
    /// two neighbours; a grid without a valid probe stays unplanned.
    #[test]
    fn the_fill_takes_the_neighbours_mean() {
        let grids = [
            ProbeGrid {
                first: 0,
                resolution: [3, 1, 1],
            },
            ProbeGrid {
                first: 3,
                resolution: [2, 1, 1],
            },
        ];
        let valid = [true, false, true, false, false];
        let plan = fill_plan(&grids, &valid);
        assert_eq!(plan, vec![(1, vec![0, 2])]);
        let mut v = [1.0f32, 0.0, 3.0, 7.0, 7.0];
        apply_fill(&plan, &mut v, |s| s.iter().sum::<f32>() / s.len() as f32);
        assert_eq!(v, [1.0, 2.0, 3.0, 7.0, 7.0]);
    }
}
