//! Burial planes: which part of each texel lies in open space, so that no
//! ray of the bake ever starts inside a solid.
//!
//! Game levels run floors under walls and columns, and join rooms back to
//! back. A texel that lies partly under a wall has sample points inside it,
//! and a ray from there rises inside the wall to whatever closes it: the
//! ceiling strip over the wall, half of which belongs to the room on the
//! other side. That is light through a wall (issue #19: 8.7e-4 of the lit
//! room's floor light in the sealed room with a 0.2 m wall).
//!
//! This stage is what Bakery calls adjusting sample positions. From each
//! texel's centre, lifted a hair off its surface, eight rays run along the
//! surface for one texel width. Whatever they meet crosses the texel: the
//! surface there is a *burial plane*, the line where the surface met
//! ([`Clip`]), and the part of the texel beyond it is on the other side of
//! a wall, under a column, or through a back-to-back partition. When the
//! centre itself is inside a solid (the rays meet back faces, and most of
//! a few hemisphere rays do too), it is moved out through the nearest back
//! face first. Every sample point of the texel (form factors, direct light,
//! validity, final gather, the references) is then folded into the exposed
//! part ([`fold`]) before a ray leaves it.
//!
//! The stage also gives each texel's *exposed fraction*: the share of its
//! area in front of its planes. The report's per-instance `mean` weighs each
//! texel by it: buried area receives nothing.

use crate::layout::burial::{Burial, BurialStats, Clip, Side};
use crate::surface::Surfaces;
use crate::util::sampling::{cosine_hemisphere, stratified, to_world, Stream};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Stream purpose id of the burial test's hemisphere rays and area points.
const PURPOSE: u64 = crate::util::sampling::purpose::BURIAL;

/// Rays along the surface per texel.
const TANGENT_RAYS: u32 = 8;

/// Hemisphere rays that judge whether a centre is inside a solid.
const HEMISPHERE_RAYS: u32 = 8;

/// Times a buried centre may be moved out through a back face.
const MOVES: usize = 2;

/// Points per texel that estimate its exposed fraction.
const AREA_POINTS: u32 = 16;

/// Height of the tangent rays over the surface and how far in front of a
/// plane a folded point stays, in texel widths.
const LIFT: f32 = 0.01;

/// A texel's width in metres: √(world area / lightmap area) of its main
/// triangle (lightmap UVs are in texels).
fn texel_width(s: &Surfaces, t: usize) -> f32 {
    let g = s.geometry;
    let tri = s.texels.triangle[t] as usize;
    let p = &g.p_ws[tri];
    let uv = &g.uv_lm[tri];
    let world = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let lm = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
    if lm > 0.0 && world > 0.0 {
        (world / lm).sqrt()
    } else {
        0.0
    }
}

/// What one ray along the surface met: its distance, the plane it gives,
/// and whether it was a back face.
struct Crossing {
    t: f32,
    dir: Vec3,
    clip: Clip,
    back: bool,
}

/// The eight rays along the surface from `o`, reaching `reach`. Only
/// surfaces at more than 30° to the texel's count: a wall, a column, a
/// step; not the texel's own surface curving up (the inside of a sphere)
/// or a gentle ramp.
fn crossings(s: &Surfaces, o: Vec3, ng: Vec3, reach: f32) -> Vec<Crossing> {
    let (tx, ty) = crate::util::sampling::frame(ng);
    let mut out = Vec::new();
    for k in 0..TANGENT_RAYS {
        let a = std::f32::consts::TAU * k as f32 / TANGENT_RAYS as f32;
        let dir = tx * a.cos() + ty * a.sin();
        let Some(hit) = s.rays.closest_hit(o, dir, reach) else {
            continue;
        };
        let tri = hit.tri as usize;
        let nh = s.geometry.ng_ws[tri];
        let back =
            nh.dot(dir) > 0.0 && !s.scene.materials[s.geometry.material[tri] as usize].double_sided;
        // The plane of the surface met, within the texel's plane: exact for
        // a planar wall at any angle; the ray's own direction where the
        // surface met lies nearly along the texel's.
        // The plane of the surface met, within the texel's plane: exact
        // for a planar wall at any angle.
        let inplane = nh - ng * nh.dot(ng);
        if inplane.length_squared() <= 0.25 {
            continue;
        }
        let n = inplane.normalize();
        let n = if n.dot(dir) < 0.0 { -n } else { n };
        let q = o + dir * hit.t;
        out.push(Crossing {
            t: hit.t,
            dir,
            clip: Clip { n, k: n.dot(q) },
            back,
        });
    }
    out
}

/// More than half of `HEMISPHERE_RAYS` cosine-distributed rays from `o`
/// meet back faces: `o` is inside a solid.
fn inside(s: &Surfaces, o: Vec3, ng: Vec3, rng: &mut Stream) -> bool {
    let mut back = 0;
    for k in 0..HEMISPHERE_RAYS {
        let dir = to_world(
            cosine_hemisphere(stratified(k, HEMISPHERE_RAYS, rng.next_vec2())),
            ng,
        );
        if s.meets_back_face(o, dir) {
            back += 1;
        }
    }
    back * 2 > HEMISPHERE_RAYS
}

/// One texel's planes, exposed fraction, rays cast, and whether its centre
/// moved.
fn texel(s: &Surfaces, t: usize, seed: u64) -> TexelBurial {
    let width = texel_width(s, t);
    if width <= 0.0 || !width.is_finite() {
        return TexelBurial::default();
    }
    let sampler = s.texel_sampler(t as u32);
    let ng = sampler.ng;
    let lift = LIFT * width;
    let (centre, _) = sampler.sample(Vec2::splat(0.5));
    let mut o = centre + ng * lift;
    let mut rng = Stream::new(seed, PURPOSE, t as u64);
    let mut rays = 0u64;
    let mut moved = false;
    let mut found = crossings(s, o, ng, width);
    rays += TANGENT_RAYS as u64;
    for _ in 0..MOVES {
        let Some(exit) = found
            .iter()
            .filter(|c| c.back)
            .min_by(|a, b| a.t.total_cmp(&b.t))
        else {
            break;
        };
        // A back face along the surface: the centre is inside a solid, or
        // beside open one-sided geometry seen from behind (then most of its
        // hemisphere is open, and it stays).
        rays += HEMISPHERE_RAYS as u64;
        if !inside(s, o, ng, &mut rng) {
            break;
        }
        o += exit.dir * (exit.t + 2.0 * lift);
        moved = true;
        found = crossings(s, o, ng, width);
        rays += TANGENT_RAYS as u64;
    }
    let planes: Vec<Clip> = found.iter().map(|c| c.clip).collect();
    if planes.is_empty() {
        return TexelBurial {
            planes,
            exposed: 1.0,
            margin: lift,
            rays,
            moved,
        };
    }
    let tri = s.texels.triangle[t] as usize;
    let side = Side::new(&planes, ng, s.geometry.p_ws[tri][0], lift);
    // Points of the texel's square on its largest triangle's plane (the
    // fast sampler's, clamped onto the triangle): the planes cut that plane.
    let mut exposed = 0u32;
    for k in 0..AREA_POINTS {
        let jitter = stratified(k, AREA_POINTS, rng.next_vec2());
        let (p, _) = sampler.sample(jitter);
        if !side.across(p, 0.0) {
            exposed += 1;
        }
    }
    TexelBurial {
        planes,
        exposed: exposed as f32 / AREA_POINTS as f32,
        margin: lift,
        rays,
        moved,
    }
}

/// One texel's part of [`Burial`].
struct TexelBurial {
    planes: Vec<Clip>,
    exposed: f32,
    margin: f32,
    rays: u64,
    moved: bool,
}

impl Default for TexelBurial {
    fn default() -> Self {
        TexelBurial {
            planes: Vec::new(),
            exposed: 1.0,
            margin: 0.0,
            rays: 0,
            moved: false,
        }
    }
}

/// Every texel's burial planes and validity (see the module
/// documentation). `s` is read for its geometry, texels and ray caster;
/// its own burial is not used. The validity estimate
/// ([`crate::surface::validity::validity`], `validity_rays` per texel) casts from
/// points folded by the new planes; invalid texels (inside a solid) count
/// as not exposed at all; `tolerance` is the back-face tolerance.
pub fn compute(s: &Surfaces, seed: u64, validity_rays: u32, tolerance: f32) -> Burial {
    let mut burial = planes(s, seed);
    let folded = Surfaces {
        burial: &burial,
        ..*s
    };
    let judged = crate::surface::validity::validity(&folded, validity_rays, seed, tolerance);
    let (valid, rays) = (judged.valid, judged.rays);
    burial.enclosed = judged.enclosed;
    for (e, &v) in burial.exposed.iter_mut().zip(&valid) {
        if !v {
            *e = 0.0;
        }
    }
    burial.stats.buried = burial.exposed.iter().filter(|&&e| e == 0.0).count() as u64;
    burial.stats.validity_rays = rays;
    burial.valid = valid;
    burial.region = regions(s, &burial);
    burial.stats.regions = {
        let mut r = burial.region.clone();
        r.sort_unstable();
        r.dedup();
        r.len() as u64
    };
    burial
}

/// Every texel's region: valid texels of one chart joined wherever two
/// neighbours (8-connected in the lightmap) lie on the same side of each
/// other's burial planes. A wall standing on a floor, or a partition
/// between two rooms modelled as one mesh, cuts the floor's chart into
/// regions; patches, their interpolation and the denoiser never mix two
/// regions, so no light crosses the wall through them. Invalid texels
/// (inside solids) form one region per chart. Ids: the smallest texel of a
/// region, or `texels.len()` + the chart's owner id for the invalid ones.
fn regions(s: &Surfaces, burial: &Burial) -> Vec<u32> {
    let texels = s.texels;
    let n = texels.len();
    // Each texel's side, and its centroid folded to it.
    let with = Surfaces { burial, ..*s };
    let sides: Vec<Side> = (0..n).map(|t| with.side(t)).collect();
    let rep: Vec<Vec3> = (0..n)
        .into_par_iter()
        .map(|t| sides[t].fold(texels.p_ws[t]))
        .collect();
    let in_front = |t: usize, u: usize| !sides[t].across(rep[u], 0.0);
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    }
    for t in 0..n {
        if !burial.valid[t] {
            continue;
        }
        let [x, y] = texels.xy[t];
        for (dx, dy) in [(1i64, 0i64), (-1, 1), (0, 1), (1, 1)] {
            let Some(u) = texels.at(texels.page[t], x as i64 + dx, y as i64 + dy) else {
                continue;
            };
            let u = u as usize;
            if burial.valid[u]
                && texels.instance[u] == texels.instance[t]
                && texels.chart[u] == texels.chart[t]
                && in_front(t, u)
                && in_front(u, t)
            {
                let (a, b) = (root(&mut parent, t as u32), root(&mut parent, u as u32));
                // The smaller id becomes the root: ids do not depend on
                // the order of the unions.
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi as usize] = lo;
            }
        }
    }
    (0..n)
        .map(|t| {
            if burial.valid[t] {
                root(&mut parent, t as u32)
            } else {
                (n as u32).wrapping_add(texels.owner(texels.instance[t], texels.chart[t]))
            }
        })
        .collect()
}

/// Every texel's planes and exposed fraction.
fn planes(s: &Surfaces, seed: u64) -> Burial {
    let n = s.texels.len();
    let chunk = 1024;
    let parts: Vec<Vec<TexelBurial>> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            (c * chunk..((c + 1) * chunk).min(n))
                .map(|t| texel(s, t, seed))
                .collect()
        })
        .collect();
    let mut burial = Burial {
        start: Vec::with_capacity(n + 1),
        planes: Vec::new(),
        exposed: Vec::with_capacity(n),
        margin: Vec::with_capacity(n),
        split: vec![0; n.div_ceil(64)],
        clipped: vec![0; n.div_ceil(64)],
        valid: Vec::new(),
        region: Vec::new(),
        enclosed: Vec::new(),
        stats: BurialStats::default(),
    };
    burial.start.push(0);
    for (t, x) in parts.into_iter().flatten().enumerate() {
        if !x.planes.is_empty() {
            burial.clipped[t / 64] |= 1 << (t % 64);
            if x.exposed < 1.0 {
                burial.split[t / 64] |= 1 << (t % 64);
            }
        }
        let st = &mut burial.stats;
        st.rays += x.rays;
        st.clipped += !x.planes.is_empty() as u64;
        st.moved += x.moved as u64;
        burial.planes.extend(x.planes);
        burial.start.push(burial.planes.len() as u32);
        burial.exposed.push(x.exposed);
        burial.margin.push(x.margin);
    }
    burial
}
