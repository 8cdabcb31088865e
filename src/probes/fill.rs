//! Invalid probes (inside solids) take their valid neighbours' light, as
//! Unity and Godot fill them, so that interpolation between probes never
//! reads a black probe inside a wall: ring by ring, each unfilled probe with
//! filled neighbours among its 26 takes their mean (of the previous ring, so
//! the result does not depend on the visiting order).

use super::placement::Volume;
use super::sh::Sh9;
use glam::{IVec3, Vec3};

/// Fills the invalid probes of `volume` (its slice of `sh` and `valid`).
/// Returns how many could not be filled (a grid with no valid probe).
pub fn fill(volume: &Volume, sh: &mut [Sh9], valid: &[bool]) -> usize {
    let mut filled: Vec<bool> = valid.to_vec();
    let r = volume.resolution.as_ivec3();
    loop {
        let mut next: Vec<(usize, Sh9)> = Vec::new();
        for i in 0..sh.len() {
            if filled[i] {
                continue;
            }
            let c = volume.coords(i).as_ivec3();
            let mut sum: Sh9 = [Vec3::ZERO; 9];
            let mut n = 0u32;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let q = c + IVec3::new(dx, dy, dz);
                        if q == c || q.cmplt(IVec3::ZERO).any() || q.cmpge(r).any() {
                            continue;
                        }
                        let j = volume.index(q.as_uvec3());
                        if filled[j] {
                            for (a, b) in sum.iter_mut().zip(&sh[j]) {
                                *a += *b;
                            }
                            n += 1;
                        }
                    }
                }
            }
            if n > 0 {
                next.push((i, sum.map(|v| v / n as f32)));
            }
        }
        if next.is_empty() {
            break;
        }
        for (i, v) in next {
            sh[i] = v;
            filled[i] = true;
        }
    }
    filled.iter().filter(|f| !**f).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat4, UVec3};

    #[test]
    fn invalid_probes_take_their_neighbours_light() {
        let v = Volume {
            name: "t".into(),
            world_from_box: Mat4::IDENTITY,
            resolution: UVec3::new(3, 1, 1),
            first: 0,
        };
        let mut sh = vec![[Vec3::ZERO; 9]; 3];
        sh[0][0] = Vec3::ONE;
        sh[2][0] = Vec3::splat(3.0);
        assert_eq!(fill(&v, &mut sh, &[true, false, true]), 0);
        assert_eq!(sh[1][0], Vec3::splat(2.0));
        let mut none = vec![[Vec3::ZERO; 9]; 3];
        assert_eq!(fill(&v, &mut none, &[false; 3]), 3);
    }
}
