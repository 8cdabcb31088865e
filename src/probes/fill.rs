//! Invalid probes (inside solids) take their valid neighbours' light, as
//! Unity and Godot fill them, so that interpolation between probes never
//! reads a black probe inside a wall: ring by ring, each unfilled probe with
//! filled neighbours among its 26 takes their mean (of the previous ring, so
//! the result does not depend on the visiting order).

use super::placement::Volume;
use super::sh::Sh9;
use glam::Vec3;
use radbake_live::format::ProbeGrid;

/// Fills the invalid probes of `volume` (its slice of `sh` and `valid`).
/// Returns how many could not be filled (a grid with no valid probe).
/// The rings are [`radbake_live::probes::fill_plan`]'s, which the live
/// probes' changes are filled by.
pub fn fill(volume: &Volume, sh: &mut [Sh9], valid: &[bool]) -> usize {
    let grid = ProbeGrid {
        first: 0,
        resolution: volume.resolution.to_array(),
    };
    let plan = radbake_live::probes::fill_plan(&[grid], valid);
    radbake_live::probes::apply_fill(&plan, sh, |from| {
        let mut sum: Sh9 = [Vec3::ZERO; 9];
        for s in from {
            for (a, b) in sum.iter_mut().zip(s) {
                *a += *b;
            }
        }
        sum.map(|v| v / from.len() as f32)
    });
    valid.iter().filter(|v| !**v).count() - plan.len()
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
