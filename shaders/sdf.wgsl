// Sphere tracing of the level's signed distance field in the preview
// (issue #24; Hart 1996, "Sphere tracing"): soft shadows of the real-time
// lights, distance-field ambient occlusion on probe-lit (dynamic)
// surfaces, and the sdf debug view. The field is the bake's `sdf.ktx2`
// (metres; positive in free space, negative inside solids), uploaded as a
// filterable R16Float 3D texture over the box globals.sdf_min..sdf_max.
// Prefixed with common.wgsl by the Rust side.

@group(0) @binding(1) var sdf_texture: texture_3d<f32>;
@group(0) @binding(2) var sdf_sampler: sampler;

// The field at world point p: trilinear inside the box; outside it, the
// value at the nearest point of the box plus the distance to it (so a
// march from outside steps straight to the box).
fn sdf_at(p: vec3<f32>) -> f32 {
    let lo = globals.sdf_min.xyz;
    let hi = globals.sdf_max.xyz;
    let q = clamp(p, lo, hi);
    let d = textureSampleLevel(sdf_texture, sdf_sampler, (q - lo) / (hi - lo), 0.0).r;
    return d + length(p - q);
}

// The parameters t of the ray o + t dir inside the field's box (slab
// test); x > y where the ray misses it.
fn sdf_box(o: vec3<f32>, dir: vec3<f32>) -> vec2<f32> {
    let inv = 1.0 / dir;
    let a = (globals.sdf_min.xyz - o) * inv;
    let b = (globals.sdf_max.xyz - o) * inv;
    let t0 = min(a, b);
    let t1 = max(a, b);
    return vec2<f32>(max(max(t0.x, t0.y), max(t0.z, 0.0)), min(min(t1.x, t1.y), t1.z));
}

// The fraction of a light seen from surface point p (unit normal n) in
// the unit direction l, at most tmax away, whose disk has angular radius
// atan(tan_r) seen from p: the penumbra estimate from the closest
// approach along a sphere-traced ray (Quilez 2010, "penumbra shadows in
// raymarched SDFs"), made symmetric about the shadow's edge: a ray that
// passes an occluder at signed distance h at t sees the fraction
// 0.5 + 0.5 h / w of the light, w = t tan_r the radius of the cone from p
// to the light's disk at t (at least half a voxel, the field's own
// resolution). So the shadow's edge (h = 0) is where a ray cast to the
// light's centre grazes the occluder, as in the ray-cast reference, and
// the march steps on through the occluder (h < 0, by at least half a
// voxel) until the cone is covered. It starts 1.5 voxels off the
// receiver's plane, clear of its own zero crossing, on the ray from p
// itself (an offset along n alone would lift the ray and shrink the
// shadow by 1.5 voxels / tan of the light's elevation).
fn sdf_shadow(p: vec3<f32>, n: vec3<f32>, l: vec3<f32>, tmax: f32, tan_r: f32) -> f32 {
    let voxel = globals.sdf_min.w;
    // Leave the receiver along l (so the ray is the one from p) until
    // 1.5 voxels off its plane, or at most 4 voxels along l and the rest
    // along n (grazing light).
    let cos_l = max(dot(n, l), 1e-3);
    let t0 = min(1.5 * voxel / cos_l, 4.0 * voxel);
    let o = p + n * max(1.5 * voxel - t0 * cos_l, 0.0);
    let span = sdf_box(o, l);
    let t_end = min(tmax, span.y);
    var t = max(t0, span.x);
    var vis = 1.0;
    for (var i = 0; i < 160; i++) {
        if t >= t_end {
            break;
        }
        let h = sdf_at(o + l * t);
        let w = max(t * tan_r, 0.5 * voxel);
        vis = min(vis, clamp(0.5 + 0.5 * h / w, 0.0, 1.0));
        if vis <= 0.0 {
            break;
        }
        t += clamp(h, 0.5 * voxel, 64.0 * voxel);
    }
    return vis;
}

// Distance-field ambient occlusion (Evans 2006, "Fast approximations for
// global illumination on dynamic scenes"; the cones of Unreal's DFAO):
// five cones of half-angle 30° about n and tilted 45° from it, each
// marched in eight steps growing geometrically from 1.5 voxels to `reach`;
// a cone's visibility is the smallest 0.5 + 0.5 h / (t tan 30°) along it
// (as sdf_shadow's), the result their cosine-weighted mean. Lightmapped
// surfaces hold their occlusion already; this is for the probe-lit ones,
// whose probes sample the light metres apart and miss the contact with
// the level.
fn sdf_ao(p: vec3<f32>, n: vec3<f32>, reach: f32) -> f32 {
    let voxel = globals.sdf_min.w;
    let t0 = 1.5 * voxel;
    if reach <= t0 {
        return 1.0;
    }
    let up = select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(1.0, 0.0, 0.0), abs(n.y) > 0.9);
    let tx = normalize(cross(up, n));
    let ty = cross(n, tx);
    let tan_c = 0.57735;
    var sum = 0.0;
    var weights = 0.0;
    for (var c = 0; c < 5; c++) {
        var dir = n;
        var w = 1.0;
        if c > 0 {
            let a = f32(c - 1) * 1.5707963;
            dir = normalize(n + cos(a) * tx + sin(a) * ty);
            w = 0.70710678;
        }
        var vis = 1.0;
        for (var i = 0; i < 8; i++) {
            let t = t0 * pow(reach / t0, f32(i) / 7.0);
            let h = sdf_at(p + n * voxel + dir * t);
            vis = min(vis, clamp(0.5 + 0.5 * h / (t * tan_c), 0.0, 1.0));
        }
        sum += w * vis;
        weights += w;
    }
    return sum / weights;
}

// The march's constants: those of src/sdf/mod.rs (voxels; slopes
// unitless), so that the view shows the surfaces `Sdf::march` finds; the
// test `sdf::tests::shader_march_constants_match` compares them.
const SDF_MARCH_STEPS: i32 = 4096;
const SDF_MIN_STEP: f32 = 0.25;
const SDF_SURFACE_SLOPE: f32 = 1.3;
const SDF_NEAR: f32 = 0.75;
const SDF_UNSIGNED: f32 = 0.25;
const SDF_UNSIGNED_FLAT: f32 = 0.51;
const SDF_FLAT: f32 = 0.5;

// The field's gradient at q, by central differences half a voxel either
// side.
fn sdf_gradient(q: vec3<f32>) -> vec3<f32> {
    let h = 0.5 * globals.sdf_min.w;
    return vec3<f32>(
        sdf_at(q + vec3<f32>(h, 0.0, 0.0)) - sdf_at(q - vec3<f32>(h, 0.0, 0.0)),
        sdf_at(q + vec3<f32>(0.0, h, 0.0)) - sdf_at(q - vec3<f32>(0.0, h, 0.0)),
        sdf_at(q + vec3<f32>(0.0, 0.0, h)) - sdf_at(q - vec3<f32>(0.0, 0.0, h)),
    ) / (2.0 * h);
}

// The zero crossing between steps a and b (x: t, y: the field, of opposite
// signs): bisected to a 32nd of a voxel, then linear. -1 where it is no
// surface: the field's slope along the ray there, or its gradient, longer
// than SDF_SURFACE_SLOPE (a distance's gradient is a unit vector; a sign
// flip in open air has a far steeper one). `Sdf::crossing`.
fn sdf_crossing(o: vec3<f32>, dir: vec3<f32>, a: vec2<f32>, b: vec2<f32>) -> f32 {
    let voxel = globals.sdf_min.w;
    var lo = a;
    var hi = b;
    for (var k = 0; k < 16; k++) {
        if hi.x - lo.x <= voxel / 32.0 {
            break;
        }
        let tm = 0.5 * (lo.x + hi.x);
        let dm = sdf_at(o + dir * tm);
        if (dm < 0.0) == (lo.y < 0.0) {
            lo = vec2<f32>(tm, dm);
        } else {
            hi = vec2<f32>(tm, dm);
        }
    }
    let sum = abs(lo.y) + abs(hi.y);
    if sum > SDF_SURFACE_SLOPE * (hi.x - lo.x) + 1e-3 * voxel {
        return -1.0;
    }
    var t = lo.x;
    if sum > 0.0 {
        t = lo.x + (hi.x - lo.x) * abs(lo.y) / sum;
    }
    if length(sdf_gradient(o + dir * t)) > SDF_SURFACE_SLOPE {
        return -1.0;
    }
    return t;
}

// The t in [a, b] where s * field is least (golden-section search, 10
// steps), and the field there. `Sdf::minimum`.
fn sdf_minimum(o: vec3<f32>, dir: vec3<f32>, s: f32, a0: f32, b0: f32) -> vec2<f32> {
    let r = 0.618034;
    var a = a0;
    var b = b0;
    var c = b - r * (b - a);
    var e = a + r * (b - a);
    var fc = sdf_at(o + dir * c);
    var fe = sdf_at(o + dir * e);
    for (var k = 0; k < 10; k++) {
        if s * fc < s * fe {
            b = e;
            e = c;
            fe = fc;
            c = b - r * (b - a);
            fc = sdf_at(o + dir * c);
        } else {
            a = c;
            c = e;
            fc = fe;
            e = a + r * (b - a);
            fe = sdf_at(o + dir * e);
        }
    }
    if s * fc < s * fe {
        return vec2<f32>(c, fc);
    }
    return vec2<f32>(e, fe);
}

// At a local minimum of |field| between step a (t, field) and tb, on the
// side s (±1): the hit there, or -1. `Sdf::unsigned`.
fn sdf_unsigned(o: vec3<f32>, dir: vec3<f32>, a: vec2<f32>, s: f32, tb: f32) -> f32 {
    let voxel = globals.sdf_min.w;
    let m = sdf_minimum(o, dir, s, a.x, tb);
    if m.y * s < 0.0 {
        return sdf_crossing(o, dir, a, m);
    }
    if abs(m.y) >= SDF_UNSIGNED_FLAT * voxel {
        return -1.0;
    }
    // Beside a sign flip the field is steep: no surface.
    let slope = length(sdf_gradient(o + dir * m.x));
    if (abs(m.y) < SDF_UNSIGNED * voxel && slope <= SDF_SURFACE_SLOPE) || slope < SDF_FLAT {
        return m.x;
    }
    return -1.0;
}

// The first surface along o + t dir within the field's box, or -1: the
// CPU's march (`Sdf::march` in src/sdf.rs, whose comment gives the
// reasons), step for step. Sphere tracing (Hart 1996) by the |field| less
// half a voxel, at least a quarter voxel; a hit is a sign change whose
// crossing has a distance's slope (either way round: a ray from behind a
// one-sided face meets it where the field turns positive), or a local
// minimum of |field| near zero (double-sided and back-to-back faces,
// which have no sign change).
fn sdf_trace(o: vec3<f32>, dir: vec3<f32>) -> f32 {
    let voxel = globals.sdf_min.w;
    let span = sdf_box(o, dir);
    if span.x > span.y {
        return -1.0;
    }
    let leave = span.y;
    var t = span.x;
    var d = sdf_at(o + dir * t);
    // The step before (t, d), once there is one.
    var before = vec2<f32>(0.0);
    var has_before = false;
    for (var i = 0; i < SDF_MARCH_STEPS; i++) {
        if t >= leave {
            return -1.0;
        }
        let next_t = min(t + max(abs(d) - 0.5 * voxel, SDF_MIN_STEP * voxel), leave);
        let next_d = sdf_at(o + dir * next_t);
        if (d < 0.0) != (next_d < 0.0) {
            let hit = sdf_crossing(o, dir, vec2<f32>(t, d), vec2<f32>(next_t, next_d));
            if hit >= 0.0 {
                return hit;
            }
        } else if has_before && (before.y < 0.0) == (d < 0.0) && abs(d) < SDF_NEAR * voxel
            && abs(d) < abs(before.y) && abs(d) <= abs(next_d) {
            let hit = sdf_unsigned(o, dir, before, select(1.0, -1.0, d < 0.0), next_t);
            if hit >= 0.0 {
                return hit;
            }
        }
        before = vec2<f32>(t, d);
        has_before = true;
        t = next_t;
        d = next_d;
    }
    return -1.0;
}

struct FullscreenOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) ndc: vec2<f32>,
}

// One triangle covering the viewport.
@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> FullscreenOut {
    let ndc = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    var out: FullscreenOut;
    out.clip = vec4<f32>(ndc, 0.0, 1.0);
    out.ndc = ndc;
    return out;
}

// The sdf view: the sphere-traced zero set, shaded by its normal (the
// field's gradient) and a head light; and a section: where a ray crosses
// the horizontal plane y = sdf_params.x inside the field's box, the field
// on that plane (whatever lies between the eye and the plane is cut
// away): orange outside (d > 0), blue inside, contour lines every four
// voxels, white at the surface. Black where the field's box is not seen;
// magenta stripes without a field.
@fragment
fn fs_sdf_view(in: FullscreenOut) -> @location(0) vec4<f32> {
    let voxel = globals.sdf_min.w;
    if voxel <= 0.0 {
        let stripe = fract(in.clip.x * 0.05 + in.clip.y * 0.05) < 0.5;
        return vec4<f32>(select(vec3<f32>(0.0), vec3<f32>(1.0, 0.0, 1.0), stripe), 1.0);
    }
    let near = globals.inv_view_proj * vec4<f32>(in.ndc, 1.0, 1.0);
    let far = globals.inv_view_proj * vec4<f32>(in.ndc, 0.5, 1.0);
    let o = near.xyz / near.w;
    let dir = normalize(far.xyz / far.w - o);
    let hit = sdf_trace(o, dir);
    let span = sdf_box(o, dir);
    var color = vec3<f32>(0.0);
    let t_slice = (globals.sdf_params.x - o.y) / dir.y;
    let slice_seen = t_slice > span.x && t_slice < span.y;
    if slice_seen {
        let d = sdf_at(o + dir * t_slice);
        let k = 4.0 * voxel;
        color = select(vec3<f32>(0.3, 0.55, 0.95), vec3<f32>(0.95, 0.6, 0.3), d > 0.0);
        color *= 0.75 + 0.25 * cos(6.2831853 * d / k);
        color = mix(color, vec3<f32>(1.0), 1.0 - smoothstep(0.0, 0.5 * voxel, abs(d)));
    } else if hit >= 0.0 {
        let p = o + dir * hit;
        let e = 0.5 * voxel;
        let g = vec3<f32>(
            sdf_at(p + vec3<f32>(e, 0.0, 0.0)) - sdf_at(p - vec3<f32>(e, 0.0, 0.0)),
            sdf_at(p + vec3<f32>(0.0, e, 0.0)) - sdf_at(p - vec3<f32>(0.0, e, 0.0)),
            sdf_at(p + vec3<f32>(0.0, 0.0, e)) - sdf_at(p - vec3<f32>(0.0, 0.0, e)),
        );
        let n = normalize(g + vec3<f32>(0.0, 1e-9, 0.0));
        color = (0.55 + 0.45 * n) * (0.25 + 0.75 * max(dot(n, -dir), 0.0));
    }
    return vec4<f32>(srgb_encode(color), 1.0);
}
