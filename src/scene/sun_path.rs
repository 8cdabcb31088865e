//! A live sun's path (`extras.radbake.sun_path` on its node): the
//! directions its sun table is precomputed for, in place of the whole
//! hemisphere's grid. Dense along the one curve the sun takes, so that
//! shadows move by a fraction of a patch between samples.
//!
//! Either a list of directions towards the sun, or a day at a latitude:
//! the sun's positions from sunrise to sunset, by the standard solar
//! geometry (declination δ = −23.44° cos(2π (day + 10) / 365), hour angle
//! H; Duffie & Beckman, *Solar Engineering of Thermal Processes*, 1.6):
//!
//! east = −cos δ sin H, north = cos φ sin δ − sin φ cos δ cos H,
//! up = sin φ sin δ + cos φ cos δ cos H,
//!
//! in the scene's frame +X east, +Y up, −Z north.

use glam::Vec3;

/// Samples of a day's path where none is given.
pub const DEFAULT_SAMPLES: u32 = crate::config::DEFAULT_SUN_PATH_SAMPLES;

/// A sun path as given on the node.
#[derive(Clone, Debug, PartialEq)]
pub enum SunPath {
    /// Directions towards the sun (unit), in order along the path.
    Directions(Vec<Vec3>),
    /// A day (1–366) at a latitude (degrees, −90 to 90), sampled
    /// `samples` times from sunrise to sunset.
    Day {
        latitude: f32,
        day: f32,
        samples: u32,
    },
}

impl From<crate::config::SunPathSetting> for SunPath {
    fn from(p: crate::config::SunPathSetting) -> SunPath {
        SunPath::Day {
            latitude: p.latitude,
            day: p.day,
            samples: p.samples,
        }
    }
}

impl SunPath {
    /// The path's directions towards the sun (unit, y ≥ 0), in order.
    ///
    /// # Errors
    /// A message where the sun never rises on the path (a polar night, or
    /// every direction given below the horizon).
    pub fn directions(&self) -> Result<Vec<Vec3>, String> {
        let dirs = match self {
            SunPath::Directions(d) => d.iter().copied().filter(|d| d.y >= 0.0).collect(),
            SunPath::Day {
                latitude,
                day,
                samples,
            } => day_path(*latitude, *day, *samples),
        };
        if dirs.is_empty() {
            return Err(match self {
                SunPath::Directions(_) => "every direction of the sun path is below the horizon (y < 0): the sun never rises".into(),
                SunPath::Day { latitude, day, .. } => format!(
                    "at latitude {latitude}° on day {day} the sun never rises (polar night)"
                ),
            });
        }
        Ok(dirs)
    }
}

/// The sun's directions from sunrise to sunset of `day` at `latitude`.
fn day_path(latitude: f32, day: f32, samples: u32) -> Vec<Vec3> {
    let phi = (latitude as f64).to_radians();
    let delta =
        (-23.44f64).to_radians() * (2.0 * std::f64::consts::PI * (day as f64 + 10.0) / 365.0).cos();
    // Sunrise hour angle: cos H₀ = −tan φ tan δ (clamped: midnight sun).
    let c = -phi.tan() * delta.tan();
    if c >= 1.0 {
        return Vec::new();
    }
    let h0 = c.max(-1.0).acos();
    let n = samples.max(2);
    (0..n)
        .filter_map(|k| {
            let h = -h0 + 2.0 * h0 * k as f64 / (n - 1) as f64;
            let east = -delta.cos() * h.sin();
            let north = phi.cos() * delta.sin() - phi.sin() * delta.cos() * h.cos();
            let up = phi.sin() * delta.sin() + phi.cos() * delta.cos() * h.cos();
            let d = Vec3::new(east as f32, up.max(0.0) as f32, -north as f32).normalize();
            d.is_finite().then_some(d)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equinox_at_the_equator_passes_the_zenith_from_east_to_west() {
        let d = SunPath::Day {
            latitude: 0.0,
            day: 80.0,
            samples: 101,
        }
        .directions()
        .unwrap();
        assert_eq!(d.len(), 101);
        assert!(
            d[0].x > 0.99 && d[0].y < 0.02,
            "sunrise in the east: {}",
            d[0]
        );
        assert!(d[100].x < -0.99, "sunset in the west: {}", d[100]);
        assert!(d[50].y > 0.99, "noon overhead: {}", d[50]);
    }

    #[test]
    fn noon_elevation_is_90_minus_latitude_plus_declination() {
        // Midsummer (day 172, δ ≈ +23.44°) at 43.7° N: 69.7° at noon, due south (+Z).
        let d = SunPath::Day {
            latitude: 43.7,
            day: 172.0,
            samples: 257,
        }
        .directions()
        .unwrap();
        let noon = d[128];
        assert!((noon.y.asin().to_degrees() - 69.74).abs() < 0.1, "{noon}");
        assert!(noon.z > 0.0 && noon.x.abs() < 1e-3, "{noon}");
    }

    #[test]
    fn a_polar_night_and_a_path_under_the_horizon_are_errors() {
        let night = SunPath::Day {
            latitude: 80.0,
            day: 355.0,
            samples: 64,
        };
        assert!(night.directions().unwrap_err().contains("never rises"));
        let under = SunPath::Directions(vec![Vec3::new(0.0, -1.0, 0.0)]);
        assert!(under.directions().unwrap_err().contains("never rises"));
    }
}
