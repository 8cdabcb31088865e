//! The precomputed sun directions: an n × n grid over the upper
//! hemisphere (y up, as glTF) in the hemi-octahedral parameterisation
//! (Engelhardt & Dachsbacher 2008, "Octahedron environment maps", folded
//! to one hemisphere as in Cigolle et al. 2014). A direction's light is
//! interpolated bilinearly between the four grid nodes around it: exact at
//! a node, continuous everywhere, the horizon on the square's border.

/// Direction (towards the sun, unit, y up) of grid node (`i`, `j`) of an
/// `n` × `n` grid (`n` ≥ 2).
pub fn node_direction(n: u32, i: u32, j: u32) -> [f32; 3] {
    let s = (n - 1) as f32;
    let u = -1.0 + 2.0 * i as f32 / s;
    let v = -1.0 + 2.0 * j as f32 / s;
    from_square(u, v)
}

/// The direction at (u, v) ∈ [−1, 1]²: p = ((u + v)/2, (u − v)/2) is a
/// point of the diamond |pₓ| + |p_z| ≤ 1, lifted to y = 1 − |pₓ| − |p_z|.
pub fn from_square(u: f32, v: f32) -> [f32; 3] {
    let (x, z) = ((u + v) * 0.5, (u - v) * 0.5);
    let y = (1.0 - x.abs() - z.abs()).max(0.0);
    let len = (x * x + y * y + z * z).sqrt();
    [x / len, y / len, z / len]
}

/// (u, v) ∈ [−1, 1]² of a unit direction with y ≥ 0 (the inverse of
/// [`from_square`]).
pub fn to_square(d: [f32; 3]) -> (f32, f32) {
    let s = d[0].abs() + d[1].abs() + d[2].abs();
    let (x, z) = (d[0] / s, d[2] / s);
    (x + z, x - z)
}

/// The grid nodes around direction `d` (towards the sun, unit) and their
/// bilinear weights (summing to 1), as (node index j·n + i, weight); None
/// for a sun below the horizon (y < 0), which lights nothing.
pub fn weights(n: u32, d: [f32; 3]) -> Option<[(u32, f32); 4]> {
    if d[1] < 0.0 {
        return None;
    }
    let (u, v) = to_square(d);
    let s = (n - 1) as f32;
    let (fu, fv) = (
        ((u + 1.0) * 0.5 * s).clamp(0.0, s),
        ((v + 1.0) * 0.5 * s).clamp(0.0, s),
    );
    let (i0, j0) = (
        (fu.floor() as u32).min(n - 2),
        (fv.floor() as u32).min(n - 2),
    );
    let (wu, wv) = (fu - i0 as f32, fv - j0 as f32);
    let at = |i: u32, j: u32| j * n + i;
    Some([
        (at(i0, j0), (1.0 - wu) * (1.0 - wv)),
        (at(i0 + 1, j0), wu * (1.0 - wv)),
        (at(i0, j0 + 1), (1.0 - wu) * wv),
        (at(i0 + 1, j0 + 1), wu * wv),
    ])
}

/// The two samples of a sun `path` (unit directions in order along it)
/// around direction `d` and their weights: the point of the path's
/// polyline nearest to `d` (by chord distance), interpolated linearly
/// between the segment's ends. A sun off its path takes the nearest point
/// of it. None for a sun below the horizon.
pub fn path_weights(path: &[[f32; 3]], d: [f32; 3]) -> Option<[(u32, f32); 2]> {
    if d[1] < 0.0 || path.is_empty() {
        return None;
    }
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if path.len() == 1 {
        return Some([(0, 1.0), (0, 0.0)]);
    }
    let mut best = (f32::INFINITY, 0u32, 0.0f32);
    for (k, w) in path.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let ab = sub(b, a);
        let len2 = dot(ab, ab);
        let t = if len2 > 0.0 {
            (dot(sub(d, a), ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
        let e = sub(d, p);
        let dist = dot(e, e);
        if dist < best.0 {
            best = (dist, k as u32, t);
        }
    }
    let (_, k, t) = best;
    Some([(k, 1.0 - t), (k + 1, t)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_interpolates_between_its_nearest_samples() {
        let path = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]];
        let w = path_weights(&path, [0.0, 1.0, 0.0]).unwrap();
        assert!(
            w.iter().any(|&(k, x)| k == 1 && (x - 1.0).abs() < 1e-6),
            "{w:?}"
        );
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let w = path_weights(&path, [-h, h, 0.0]).unwrap();
        assert_eq!((w[0].0, w[1].0), (1, 2));
        assert!((w[0].1 - 0.5).abs() < 1e-6 && (w[1].1 - 0.5).abs() < 1e-6);
        assert!(path_weights(&path, [0.0, -1.0, 0.0]).is_none());
    }

    #[test]
    fn nodes_are_unit_upper_and_round_trip() {
        let n = 9;
        for j in 0..n {
            for i in 0..n {
                let d = node_direction(n, i, j);
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                assert!((len - 1.0).abs() < 1e-6);
                assert!(d[1] >= 0.0);
                let w = weights(n, d).unwrap();
                let own = w
                    .iter()
                    .filter(|(k, _)| *k == j * n + i)
                    .map(|(_, w)| w)
                    .sum::<f32>();
                assert!(own > 0.9999, "node ({i}, {j}): own weight {own}");
            }
        }
        // The zenith is the centre node of an odd grid.
        let z = node_direction(n, 4, 4);
        assert!((z[1] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn weights_sum_to_one_and_below_the_horizon_is_none() {
        for d in [[0.3f32, 0.8, -0.52], [0.0, 0.0, 1.0], [-0.7, 0.1, 0.7]] {
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let d = [d[0] / l, d[1] / l, d[2] / l];
            let w = weights(12, d).unwrap();
            let sum: f32 = w.iter().map(|x| x.1).sum();
            assert!((sum - 1.0).abs() < 1e-6);
            assert!(w.iter().all(|x| x.1 >= 0.0 && x.0 < 144));
        }
        assert!(weights(12, [0.0, -0.1, 0.995]).is_none());
    }
}
