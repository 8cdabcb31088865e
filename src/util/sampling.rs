//! Sampling shared by every stage that casts random rays: seeded streams,
//! stratified cosine-weighted hemisphere directions, orthonormal frames and
//! robust ray origins.

use glam::{Vec2, Vec3};
use rand::{Rng as _, SeedableRng};

/// A deterministic random stream: one per (seed, purpose, item), so results
/// do not depend on which thread handles which item.
pub struct Stream(rand_pcg::Pcg32);

/// Every random stream's purpose: the second argument of [`Stream::new`].
/// Two uses that shared a purpose would draw the same numbers for the same
/// item; the test below keeps them apart.
pub mod purpose {
    /// Ray-cast form factors: each patch's rays.
    pub const FORM_FACTORS: u64 = 1;
    /// Direct light: each texel's light samples.
    pub const DIRECT: u64 = 2;
    /// Final gather: each texel's position and direction nets.
    pub const GATHER: u64 = 3;
    /// Path-traced reference texels.
    pub const REFERENCE_TEXELS: u64 = 5;
    /// Camera paths of `radbake render`; pass k of the final pass uses RENDER + 16 k.
    pub const RENDER: u64 = 6;
    /// Photon mapping: emitted photons.
    pub const PHOTON_EMIT: u64 = 7;
    /// Photon mapping: each texel's gather.
    pub const PHOTON_GATHER: u64 = 8;
    /// Texel footprint samples.
    pub const FOOTPRINT: u64 = 10;
    /// Texel validity votes.
    pub const VALIDITY: u64 = 11;
    /// Burial planes: each texel's rays.
    pub const BURIAL: u64 = 12;
    /// Final gather: next-event estimation towards patch lights.
    pub const PATCH_LIGHTS: u64 = 15;
    /// The irradiance meter's samples.
    pub const METER: u64 = 21;
    /// Final gather: local lights read at near hits.
    pub const NEAR_FIELD: u64 = 27;
    /// Probe rays.
    pub const PROBES: u64 = 31;
    /// Points over a texel's extent for local lights.
    pub const LIGHT_EXTENT: u64 = 40;
    /// Shadowmask occlusion rays.
    pub const SHADOWMASK: u64 = 41;
    /// Sphere-traced camera rays.
    pub const SPHERE_TRACE: u64 = 42;
    /// Random rays of the SDF-against-ray-casting check.
    pub const SDF_AGREEMENT: u64 = 99;

    /// Every purpose above, by name.
    pub const ALL: &[(&str, u64)] = &[
        ("FORM_FACTORS", FORM_FACTORS),
        ("DIRECT", DIRECT),
        ("GATHER", GATHER),
        ("REFERENCE_TEXELS", REFERENCE_TEXELS),
        ("RENDER", RENDER),
        ("PHOTON_EMIT", PHOTON_EMIT),
        ("PHOTON_GATHER", PHOTON_GATHER),
        ("FOOTPRINT", FOOTPRINT),
        ("VALIDITY", VALIDITY),
        ("BURIAL", BURIAL),
        ("PATCH_LIGHTS", PATCH_LIGHTS),
        ("METER", METER),
        ("NEAR_FIELD", NEAR_FIELD),
        ("PROBES", PROBES),
        ("LIGHT_EXTENT", LIGHT_EXTENT),
        ("SHADOWMASK", SHADOWMASK),
        ("SPHERE_TRACE", SPHERE_TRACE),
        ("SDF_AGREEMENT", SDF_AGREEMENT),
    ];
}

/// SplitMix64 finaliser, to turn (seed, ids) into well-mixed stream seeds.
pub(crate) fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Stream {
    /// The stream for `item` of `purpose` under `seed`.
    pub fn new(seed: u64, purpose: u64, item: u64) -> Self {
        let s = mix(seed ^ mix(purpose.wrapping_add(0x9e37_79b9_7f4a_7c15) ^ mix(item)));
        Stream(rand_pcg::Pcg32::seed_from_u64(s))
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        self.0.random::<f32>()
    }

    /// Two uniforms in [0, 1).
    pub fn next_vec2(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }

    /// Uniform integer in `0..n` (n > 0).
    pub fn below(&mut self, n: u32) -> u32 {
        self.0.random_range(0..n)
    }

    /// A uniformly random permutation of `0..n` (Fisher–Yates), e.g. to pair
    /// position strata with direction strata: any fixed pairing integrates
    /// over only n of the n² stratum pairs, which is biased where the
    /// integrand depends on both.
    pub fn permutation(&mut self, n: u32) -> Vec<u32> {
        let mut perm: Vec<u32> = (0..n).collect();
        for k in (1..n as usize).rev() {
            perm.swap(k, self.below(k as u32 + 1) as usize);
        }
        perm
    }
}

/// Shirley–Chiu concentric map of the unit square to the unit disk.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted direction about +Z (Malley's method): pdf = cos θ / π.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Orthonormal basis (t, b, n) around unit `n` (Duff et al. 2017).
pub fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Local (+Z up) direction to world around `n`.
pub fn to_world(local: Vec3, n: Vec3) -> Vec3 {
    let (t, b) = frame(n);
    t * local.x + b * local.y + n * local.z
}

/// The `i`-th of `n` stratified points in the unit square: a cols × rows
/// grid (cols = ⌊√n⌋, rows = ⌊n / cols⌋) that tiles the whole square, one
/// jittered point per cell; the few samples left over when n is not
/// cols × rows are uniform over the square (`jitter` itself). Every point is
/// uniform over its stratum and the strata tile the square, so an equally
/// weighted sum is unbiased for any n (a partial last row would not be).
pub fn stratified(i: u32, n: u32, jitter: Vec2) -> Vec2 {
    let cols = ((n as f32).sqrt().floor() as u32).max(1);
    let rows = (n / cols).max(1);
    if i >= cols * rows {
        return jitter;
    }
    let (cx, cy) = (i % cols, i / cols);
    Vec2::new(
        (cx as f32 + jitter.x) / cols as f32,
        (cy as f32 + jitter.y) / rows as f32,
    )
}

/// The first two dimensions of the Sobol sequence, a (0, 2)-sequence in
/// base 2: every aligned block of 2ᵐ consecutive points is a (0, m, 2)-net
/// (one point in each of the 2ᵐ boxes of any shape 2⁻ᵃ × 2⁻ᵇ, a + b = m).
/// Returns the points' 32-bit fixed-point coordinates.
fn sobol02(i: u32) -> (u32, u32) {
    let b = i.to_le_bytes();
    let y = SOBOL1[0][b[0] as usize]
        ^ SOBOL1[1][b[1] as usize]
        ^ SOBOL1[2][b[2] as usize]
        ^ SOBOL1[3][b[3] as usize];
    (i.reverse_bits(), y)
}

/// Dimension 1 of [`sobol02`] by bytes: `SOBOL1[j][b]` is the XOR of the
/// direction numbers of the set bits of byte `b` at byte position `j`. The
/// direction numbers are vₖ = vₖ₋₁ ⊕ (vₖ₋₁ ≫ 1) from v₀ = 2³¹ (Pascal's
/// matrix); the scrambled indices use all 32 bits, so a bit loop would
/// cost 32 steps per point.
static SOBOL1: [[u32; 256]; 4] = sobol1_tables();

const fn sobol1_tables() -> [[u32; 256]; 4] {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut j = 0;
    while j < 4 {
        let mut b = 0;
        while b < 256 {
            let mut x = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    x ^= v[j * 8 + bit];
                }
                bit += 1;
            }
            t[j][b] = x;
            b += 1;
        }
        j += 1;
    }
    t
}

/// Laine and Karras's hash (as improved by Burley 2020, "Practical
/// Hash-based Owen Scrambling", JCGT 9(4)): a bijection in which each bit
/// of the result is its input bit flipped by a hash of the *lower* bits.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// A nested uniform scramble of a sample index (Burley 2020 §4): each bit
/// flipped by a hash of the bits above it, which maps every aligned block
/// of 2ᵐ indices onto an aligned block.
#[inline]
fn shuffle(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// A scrambled (0, 2)-sequence for one texel's (or probe's) samples: point
/// `k` is uniform over the unit square, and every prefix of 2ᵐ points is a
/// (0, m, 2)-net, so an estimate may stop after any power of two of its
/// samples and still be stratified. The coordinates are scrambled by a
/// random digital shift (an XOR, which keeps nets nets). Two nets of one
/// estimate are decorrelated by shuffling one's index with a nested
/// uniform scramble ([`Net::shuffled`]), whose aligned blocks of 2ᵐ
/// indices are aligned blocks, i.e. (0, m, 2)-nets, again.
#[derive(Clone, Copy, Debug)]
pub struct Net {
    shuffle: Option<u32>,
    x: u32,
    y: u32,
}

impl Net {
    /// A net with its digital shift drawn from `rng`.
    pub fn new(rng: &mut Stream) -> Net {
        Net {
            shuffle: None,
            x: rng.0.random(),
            y: rng.0.random(),
        }
    }

    /// A net with its shift and index shuffle drawn from `rng`: to pair
    /// with a [`Net::new`] of the same estimate.
    pub fn shuffled(rng: &mut Stream) -> Net {
        Net {
            shuffle: Some(rng.0.random()),
            ..Net::new(rng)
        }
    }

    /// Point `k`.
    #[inline]
    pub fn point(&self, k: u32) -> Vec2 {
        let i = self.shuffle.map_or(k, |seed| shuffle(k, seed));
        let (x, y) = sobol02(i);
        // 24 bits: exactly representable, and strictly below 1.
        let f = |v: u32| (v >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
        Vec2::new(f(x ^ self.x), f(y ^ self.y))
    }
}

/// The shadow ray between surface points `p` (normal `np`) and `q` (normal
/// `nq`): both ends moved off their surfaces towards each other by
/// [`offset_ray_origin`], so neither end's triangle is hit. Returns
/// (origin, unit direction, distance to test). Offsetting only the origin
/// and shortening the distance by a relative margin is not enough: at 15 cm
/// the origin offset exceeds 10⁻⁴ of the distance and the ray hits the
/// target's own triangle (found by comparing BDPT with the path tracer).
pub fn shadow_ray(p: Vec3, np: Vec3, q: Vec3, nq: Vec3) -> (Vec3, Vec3, f32) {
    let d = q - p;
    let np = if np.dot(d) >= 0.0 { np } else { -np };
    let nq = if nq.dot(d) <= 0.0 { nq } else { -nq };
    let a = offset_ray_origin(p, np);
    let b = offset_ray_origin(q, nq);
    let e = b - a;
    let len = e.length();
    (
        a,
        if len > 0.0 {
            e / len
        } else {
            d.normalize_or_zero()
        },
        len,
    )
}

/// Moves a ray origin `p` off the surface with geometric normal `n` (pointing
/// to the side the ray leaves from) by a few ulps scaled to `p`'s magnitude,
/// so the ray does not hit its own surface (Wächter & Binder, "A Fast and
/// Robust Method for Avoiding Self-Intersection", Ray Tracing Gems, 2019).
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let of_i = (n * INT_SCALE).to_array().map(|v| v as i32);
    let comp = |pc: f32, nc: f32, oi: i32| -> f32 {
        let p_i = f32::from_bits((pc.to_bits() as i32 + if pc < 0.0 { -oi } else { oi }) as u32);
        if pc.abs() < ORIGIN {
            pc + FLOAT_SCALE * nc
        } else {
            p_i
        }
    };
    Vec3::new(
        comp(p.x, n.x, of_i[0]),
        comp(p.y, n.y, of_i[1]),
        comp(p.z, n.z, of_i[2]),
    )
}

/// The `k`-th of `n` Hammersley points (k/n, radical inverse of k in base 2),
/// rotated by `shift` (Cranley–Patterson) modulo 1.
pub fn hammersley(k: u32, n: u32, shift: Vec2) -> Vec2 {
    let radical = k.reverse_bits() as f32 * (1.0 / 4_294_967_296.0);
    let p = Vec2::new((k as f32 + 0.5) / n as f32, radical) + shift;
    p - p.floor()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        let mut s = Stream::new(1, 2, 3);
        for _ in 0..1000 {
            let n = (s.next_vec2() * 2.0 - 1.0).extend(s.next_f32() * 2.0 - 1.0);
            let n = n.normalize_or(Vec3::Z);
            let (t, b) = frame(n);
            assert!((t.length() - 1.0).abs() < 1e-4 && (b.length() - 1.0).abs() < 1e-4);
            assert!(t.dot(n).abs() < 1e-4 && b.dot(n).abs() < 1e-4 && t.dot(b).abs() < 1e-4);
        }
    }

    /// Cosine sampling round trip: the estimator ∫ f cosθ/π / pdf must give
    /// E[cos θ] = 2/3 and E[cos² θ] = 1/2 for pdf = cos θ/π.
    #[test]
    fn cosine_moments() {
        let n = 256 * 256;
        let mut s = Stream::new(7, 0, 0);
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let d = cosine_hemisphere(stratified(i, n, s.next_vec2()));
            assert!((d.length() - 1.0).abs() < 1e-4 && d.z >= 0.0);
            m1 += d.z as f64;
            m2 += (d.z * d.z) as f64;
        }
        assert!(
            (m1 / n as f64 - 2.0 / 3.0).abs() < 1e-3,
            "{}",
            m1 / n as f64
        );
        assert!((m2 / n as f64 - 0.5).abs() < 1e-3, "{}", m2 / n as f64);
    }

    #[test]
    fn stratified_covers_square() {
        let n = 100;
        let mut seen = vec![false; n as usize];
        for i in 0..n {
            let p = stratified(i, n, Vec2::splat(0.5));
            let cell = (p.y * 10.0) as usize * 10 + (p.x * 10.0) as usize;
            seen[cell] = true;
        }
        assert!(seen.iter().all(|&s| s));
    }

    /// With n not a perfect rectangle the points must still average to the
    /// square's centre (a partial last row biased them).
    #[test]
    fn stratified_is_unbiased_for_any_n() {
        for n in [2u32, 7, 128, 2048] {
            let mean: Vec2 = (0..n)
                .map(|i| stratified(i, n, Vec2::splat(0.5)))
                .sum::<Vec2>()
                / n as f32;
            assert!((mean - Vec2::splat(0.5)).length() < 1e-4, "n = {n}: {mean}");
        }
    }

    /// Every prefix of 2ᵐ points of a scrambled net has one point in each
    /// box of every shape 2⁻ᵃ × 2⁻ᵇ with a + b = m.
    #[test]
    fn net_prefixes_are_nets() {
        for seed in 0..4 {
            let mut rng = Stream::new(seed, 3, 9);
            let net = if seed % 2 == 0 {
                Net::new(&mut rng)
            } else {
                Net::shuffled(&mut rng)
            };
            for m in 0..=8u32 {
                let n = 1u32 << m;
                let pts: Vec<Vec2> = (0..n).map(|k| net.point(k)).collect();
                for a in 0..=m {
                    let (cols, rows) = (1u32 << a, 1u32 << (m - a));
                    let mut seen = vec![false; n as usize];
                    for p in &pts {
                        let c = (p.y * rows as f32) as u32 * cols + (p.x * cols as f32) as u32;
                        assert!(!seen[c as usize], "seed {seed}, m {m}, a {a}");
                        seen[c as usize] = true;
                    }
                }
            }
        }
    }

    /// Over many scrambles, point k is uniform: its mean is the centre.
    #[test]
    fn net_points_are_uniform() {
        for k in [0u32, 1, 5, 100] {
            let mean: Vec2 = (0..4096)
                .map(|s| Net::shuffled(&mut Stream::new(s, 3, 1)).point(k))
                .sum::<Vec2>()
                / 4096.0;
            assert!((mean - Vec2::splat(0.5)).length() < 0.02, "k {k}: {mean}");
        }
    }

    /// The byte tables give the direction-number product bit by bit.
    #[test]
    fn sobol_tables_match_the_bit_loop() {
        for i in [0u32, 1, 2, 3, 255, 256, 12345, 0xdead_beef, u32::MAX] {
            let (mut bits, mut v, mut y) = (i, 1u32 << 31, 0u32);
            while bits != 0 {
                if bits & 1 != 0 {
                    y ^= v;
                }
                bits >>= 1;
                v ^= v >> 1;
            }
            assert_eq!(sobol02(i).1, y, "{i}");
        }
    }

    #[test]
    fn streams_are_reproducible() {
        let a: Vec<f32> = (0..4).map(|_| Stream::new(1, 2, 3).next_f32()).collect();
        assert!(a.iter().all(|&x| x == a[0]));
        assert_ne!(
            Stream::new(1, 2, 3).next_f32(),
            Stream::new(1, 2, 4).next_f32()
        );
    }

    #[test]
    fn offset_moves_along_normal() {
        let p = Vec3::new(100.0, -3.0, 0.001);
        let q = offset_ray_origin(p, Vec3::Z);
        assert!(q.z > p.z && (q - p).length() < 1e-3);
    }

    #[test]
    fn stream_purposes_are_unique() {
        let mut seen = std::collections::BTreeMap::new();
        for &(name, p) in purpose::ALL {
            if let Some(other) = seen.insert(p, name) {
                panic!("purposes {other} and {name} share {p}");
            }
        }
        // The render's passes use RENDER + 16 k.
        for k in 1..=64 {
            let p = purpose::RENDER + 16 * k;
            assert!(!seen.contains_key(&p), "render pass {k} meets {}", seen[&p]);
        }
    }
}
