//! Real L2 spherical harmonics in three.js's `SphericalHarmonics3` order and
//! normalisation (orthonormal: ∫ Yᵢ Yⱼ dω = δᵢⱼ), and irradiance from
//! radiance SH by Ramamoorthi & Hanrahan (2001), "An Efficient
//! Representation for Irradiance Environment Maps", eq. 7–8:
//! E(n) = Σₗₘ Âₗ Lₗₘ Yₗₘ(n) with Â₀ = π, Â₁ = 2π/3, Â₂ = π/4.

use glam::Vec3;

/// Nine RGB coefficients of radiance (not irradiance), in the order Y₀₀,
/// Y₁₋₁ (y), Y₁₀ (z), Y₁₁ (x), Y₂₋₂ (xy), Y₂₋₁ (yz), Y₂₀ (3z² − 1),
/// Y₂₁ (xz), Y₂₂ (x² − y²).
pub type Sh9 = [Vec3; 9];

/// The nine basis functions at unit direction `d` (the runtime's
/// [`radbake_live::probes::basis`], which the live probes share).
#[inline]
pub fn basis(d: Vec3) -> [f32; 9] {
    radbake_live::probes::basis(d.to_array())
}

/// Adds radiance `l` arriving from direction `d` with weight `w` (a
/// quadrature weight in steradians, or 1 for a delta light's irradiance).
#[inline]
pub fn add(sh: &mut Sh9, d: Vec3, l: Vec3, w: f32) {
    for (c, y) in sh.iter_mut().zip(basis(d)) {
        *c += l * (y * w);
    }
}

/// Irradiance / π for a surface of normal `n` lit by radiance `sh`
/// (may be negative where L2 rings; callers clamp): the runtime's
/// [`radbake_live::probes::irradiance_over_pi`].
pub fn irradiance_over_pi(sh: &Sh9, n: Vec3) -> Vec3 {
    let sh = sh.map(|c| c.to_array());
    Vec3::from(radbake_live::probes::irradiance_over_pi(&sh, n.to_array()))
}

/// The six axis normals, in the ambient cube's face order
/// ([`radbake_live::probes::AXES`]).
pub const AXES: [Vec3; 6] = {
    let a = radbake_live::probes::AXES;
    [
        Vec3::from_array(a[0]),
        Vec3::from_array(a[1]),
        Vec3::from_array(a[2]),
        Vec3::from_array(a[3]),
        Vec3::from_array(a[4]),
        Vec3::from_array(a[5]),
    ]
};

/// The six faces of Valve's ambient cube (Mitchell 2006), +X, −X, +Y, −Y,
/// +Z, −Z ([`AXES`]): irradiance / π for each axis normal, clamped at zero.
pub fn ambient_cube(sh: &Sh9) -> [Vec3; 6] {
    AXES.map(|n| irradiance_over_pi(sh, n).max(Vec3::ZERO))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::sampling::Stream;

    fn random_dir(rng: &mut Stream) -> Vec3 {
        let u = rng.next_vec2();
        let z = 1.0 - 2.0 * u.x;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Orthonormality by Monte Carlo: ∫ Yᵢ Yⱼ dω ≈ δᵢⱼ.
    #[test]
    fn basis_is_orthonormal() {
        let mut rng = Stream::new(1, 0, 0);
        let n = 400_000;
        let mut m = [[0.0f64; 9]; 9];
        for _ in 0..n {
            let y = basis(random_dir(&mut rng));
            for i in 0..9 {
                for j in 0..9 {
                    m[i][j] += (y[i] * y[j]) as f64;
                }
            }
        }
        let w = 4.0 * std::f64::consts::PI / n as f64;
        for (i, row) in m.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v * w - want).abs() < 0.02, "({i},{j}): {}", v * w);
            }
        }
    }

    /// Uniform radiance L: E/π = L for every normal, and the cube faces too.
    #[test]
    fn uniform_radiance_gives_its_value() {
        let mut sh = [Vec3::ZERO; 9];
        // ∫ L Y₀₀ dω = L · 0.282095 · 4π.
        sh[0] = Vec3::splat(2.0 * 0.282_095 * 4.0 * std::f32::consts::PI);
        for f in ambient_cube(&sh) {
            assert!((f - Vec3::splat(2.0)).abs().max_element() < 1e-4, "{f}");
        }
    }

    /// A delta light of unit irradiance from direction d: by the addition
    /// theorem Σₘ Yₗₘ(d)² = (2l + 1)/4π, so the L2 E/π at normal d is
    /// Σₗ (Âₗ/π)(2l + 1)/4π.
    #[test]
    fn delta_light_projects_by_the_addition_theorem() {
        let d = Vec3::new(0.3, -0.5, 0.81).normalize();
        let mut sh = [Vec3::ZERO; 9];
        add(&mut sh, d, Vec3::ONE, 1.0);
        let got = irradiance_over_pi(&sh, d).x;
        let want = (1.0 + 3.0 * 2.0 / 3.0 + 5.0 * 0.25) / (4.0 * std::f32::consts::PI);
        assert!((got - want).abs() < 1e-5, "{got} vs {want}");
    }
}
