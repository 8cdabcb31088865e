//! Sampling shared by every stage that casts random rays: seeded streams,
//! stratified cosine-weighted hemisphere directions, orthonormal frames and
//! robust ray origins.

use glam::{Vec2, Vec3};
use rand::{Rng as _, SeedableRng};

/// A deterministic random stream: one per (seed, purpose, item), so results
/// do not depend on which thread handles which item.
pub struct Stream(rand_pcg::Pcg32);

/// SplitMix64 finaliser, to turn (seed, ids) into well-mixed stream seeds.
fn mix(mut z: u64) -> u64 {
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
}
