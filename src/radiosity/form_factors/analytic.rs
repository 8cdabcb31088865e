//! Closed-form view factors from Howell, *A Catalog of Radiation Heat
//! Transfer Configuration Factors* (3rd ed.), used as exact answers by the
//! tests. All in f64.

use std::f64::consts::PI;

/// C-11: directly opposed parallel rectangles `a × b` at distance `c`.
pub fn parallel_rectangles(a: f64, b: f64, c: f64) -> f64 {
    let x = a / c;
    let y = b / c;
    let (x2, y2) = (x * x, y * y);
    2.0 / (PI * x * y)
        * (((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// C-14: perpendicular rectangles with a common edge of length `l`; the
/// emitting one is `w` wide, the receiving one `h` wide. Returns F(w → h).
pub fn perpendicular_rectangles(l: f64, w: f64, h: f64) -> f64 {
    let ww = w / l;
    let hh = h / l;
    let (w2, h2) = (ww * ww, hh * hh);
    let a = (1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2);
    let b = (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).powf(w2);
    let c = (h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2))).powf(h2);
    1.0 / (PI * ww)
        * (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan()
            - (h2 + w2).sqrt() * (1.0 / (h2 + w2).sqrt()).atan()
            + 0.25 * (a * b * c).ln())
}

/// B-3: differential area to a parallel rectangle `x × y` at distance `d`,
/// with the normal through one corner of the rectangle.
pub fn point_to_rectangle_corner(x: f64, y: f64, d: f64) -> f64 {
    let (x, y) = (x / d, y / d);
    let sx = (1.0 + x * x).sqrt();
    let sy = (1.0 + y * y).sqrt();
    1.0 / (2.0 * PI) * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan())
}

/// Differential area at `(px, py)` facing a parallel rectangle
/// `[0, a] × [0, b]` at distance `d`: B-3 summed over the four rectangles
/// around the foot of the normal (points outside handled by signs).
pub fn point_to_rectangle(px: f64, py: f64, a: f64, b: f64, d: f64) -> f64 {
    let f =
        |x: f64, y: f64| x.signum() * y.signum() * point_to_rectangle_corner(x.abs(), y.abs(), d);
    f(a - px, b - py) - f(-px, b - py) - f(a - px, -py) + f(-px, -py)
}

/// C-41: coaxial parallel disks, radius `r1` (emitter) and `r2` at distance `h`.
pub fn coaxial_disks(r1: f64, r2: f64, h: f64) -> f64 {
    let (ra, rb) = (r1 / h, r2 / h);
    let s = 1.0 + (1.0 + rb * rb) / (ra * ra);
    0.5 * (s - (s * s - 4.0 * (rb / ra).powi(2)).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_cube_closure() {
        let opposite = parallel_rectangles(1.0, 1.0, 1.0);
        let adjacent = perpendicular_rectangles(1.0, 1.0, 1.0);
        assert!((opposite - 0.199_825).abs() < 1e-6, "{opposite}");
        assert!((adjacent - 0.200_044).abs() < 1e-6, "{adjacent}");
        assert!((opposite + 4.0 * adjacent - 1.0).abs() < 1e-5);
    }

    #[test]
    fn point_values_match_expected_json() {
        let centre = point_to_rectangle(0.5, 0.5, 1.0, 1.0, 1.0);
        let corner = point_to_rectangle(0.0, 0.0, 1.0, 1.0, 1.0);
        assert!((centre - 0.239_456_470_460_773_5).abs() < 1e-9, "{centre}");
        assert!((corner - 0.138_531_605_994_893).abs() < 1e-9, "{corner}");
    }

    #[test]
    fn disks_limit() {
        // A huge receiving disk catches everything.
        assert!((coaxial_disks(1.0, 1e4, 1.0) - 1.0).abs() < 1e-3);
        // Reciprocity: A1 F12 = A2 F21.
        let (r1, r2, h) = (0.5, 1.5, 0.7);
        let lhs = r1 * r1 * coaxial_disks(r1, r2, h);
        let rhs = r2 * r2 * coaxial_disks(r2, r1, h);
        assert!((lhs - rhs).abs() < 1e-12);
    }
}
