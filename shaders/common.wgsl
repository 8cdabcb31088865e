// Shared pieces of the radbake preview shaders: the uniform structs (their
// Rust twins are in src/preview/gpu.rs; tests/preview.rs checks the layouts
// with naga), colour transforms and lightmap filtering.
//
// WGSL has no #include: the Rust side concatenates this file in front of
// each shader that uses it.

// Per frame (group 0, binding 0).
struct Globals {
    // clip_from_world (reverse-Z, infinite far plane).
    view_proj: mat4x4<f32>,
    // xyz: eye position (world); w: unused.
    camera_pos: vec4<f32>,
    // Linear exposure multiplier, 2^EV.
    exposure: f32,
    // VIEW_* below.
    view_mode: u32,
    // 0: bilinear, 1: bicubic (B-spline) lightmap filtering.
    bicubic: u32,
    // 0: ACES fitted, 1: none (clamp).
    tone_map: u32,
    // Render target size in pixels.
    viewport: vec2<f32>,
    // Lights used of `lights`.
    light_count: u32,
    _pad: f32,
    // world_from_clip (the inverse of view_proj): the sdf view's rays.
    inv_view_proj: mat4x4<f32>,
    // The level's signed distance field (shaders/sdf.wgsl): xyz its box's
    // minimum corner, w the voxel edge (0: no field).
    sdf_min: vec4<f32>,
    // xyz: the box's maximum corner; w: 1 where the real-time lights are
    // shadowed by sphere tracing the field, 0 where not.
    sdf_max: vec4<f32>,
    // x: the sdf view's slice height (world y); y: the reach of the
    // distance-field ambient occlusion on probe-lit surfaces (metres; 0:
    // none); z, w: unused.
    sdf_params: vec4<f32>,
    // The lights an engine draws in real time (modes indirect, realtime).
    lights: array<PreviewLight, 8>,
}

// One punctual light drawn in real time (Rust: gpu::PreviewLight).
struct PreviewLight {
    // xyz: position; w: 0 directional, 1 point, 2 spot.
    position_kind: vec4<f32>,
    // xyz: the direction the light points to; w: range (0: none).
    direction_range: vec4<f32>,
    // rgb: intensity (W/sr; W/m² for directional).
    intensity: vec4<f32>,
    // x, y: the spot cone's scale and offset; z: shadowmask channel
    // (0-3; -1: none); w: the light's size for soft shadows: tan of a
    // directional light's angular radius, a point or spot light's radius
    // (metres).
    cone: vec4<f32>,
}

// Irradiance / π at `p` (unit normal `n`) from the real-time lights, with
// the bake's falloff (direct::punctual_incident): E for a directional
// light; I / d² × KHR_lights_punctual's range window and cone falloff for
// point and spot lights; times cos θ / π; times the light's visibility. A
// shadowmask light on a surface with a shadowmask (`has_mask`) is masked
// by its channel of `mask`; every other light is shadowed by sphere
// tracing the level's distance field where there is one and shadows are
// on (sdf_shadow in sdf.wgsl), and unshadowed where not.
fn realtime_light(p: vec3<f32>, n: vec3<f32>, mask: vec4<f32>, has_mask: bool) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    let shadows = globals.sdf_min.w > 0.0 && globals.sdf_max.w > 0.5;
    for (var i = 0u; i < min(globals.light_count, 8u); i++) {
        let l = globals.lights[i];
        let kind = u32(l.position_kind.w + 0.5);
        var to_light = -l.direction_range.xyz;
        var e = l.intensity.rgb;
        // How far a shadow ray goes, and the tangent of the light's
        // angular radius seen from p.
        var tmax = 1e30;
        var tan_r = l.cone.w;
        if kind != 0u {
            let d = l.position_kind.xyz - p;
            let dist2 = dot(d, d);
            if dist2 <= 0.0 {
                continue;
            }
            let dist = sqrt(dist2);
            to_light = d / dist;
            tmax = dist;
            tan_r = l.cone.w / dist;
            var atten = 1.0 / dist2;
            let range = l.direction_range.w;
            if range > 0.0 {
                let x = dist / range;
                atten *= clamp(1.0 - x * x * x * x, 0.0, 1.0);
            }
            if kind == 2u {
                let a = clamp(dot(l.direction_range.xyz, -to_light) * l.cone.x + l.cone.y, 0.0, 1.0);
                atten *= a * a;
            }
            e = e * atten;
        }
        let cos_theta = max(dot(n, to_light), 0.0);
        if cos_theta <= 0.0 {
            continue;
        }
        let channel = i32(round(l.cone.z));
        if has_mask && channel >= 0 && channel < 4 {
            e = e * mask[channel];
        } else if shadows {
            e = e * sdf_shadow(p, n, to_light, tmax, tan_r);
        }
        sum += e * cos_theta / 3.14159265358979;
    }
    return sum;
}

// Per material (group 1, binding 0).
struct Material {
    // baseColorFactor (linear RGBA).
    base_color: vec4<f32>,
    // Emitted radiance factor (rgb); w unused.
    emissive: vec4<f32>,
    // KHR_texture_transform of the base colour texture as a 2×3 matrix:
    // uv' = (dot(row0.xy, uv) + row0.z, dot(row1.xy, uv) + row1.z).
    base_uv0: vec4<f32>,
    base_uv1: vec4<f32>,
    // The same for the emissive texture.
    emissive_uv0: vec4<f32>,
    emissive_uv1: vec4<f32>,
    // MOZ_lightmap KHR_texture_transform: xy offset (uv_rect min), zw scale.
    lightmap_rect: vec4<f32>,
    // Linear lightmap value = sRGB-decoded texel × this (MOZ_lightmap intensity / π).
    lightmap_scale: f32,
    // FLAG_* below.
    flags: u32,
    // alphaCutoff for MASK, or a negative number for OPAQUE and BLEND.
    alpha_cutoff: f32,
    _pad: f32,
}

const VIEW_LIT: u32 = 0u;
const VIEW_LIGHTMAP: u32 = 1u;
const VIEW_ALBEDO: u32 = 2u;
const VIEW_CHECKER: u32 = 3u;
const VIEW_CHARTS: u32 = 4u;
const VIEW_PATCHES: u32 = 5u;
const VIEW_INVALID: u32 = 6u;
// The lit scene plus a sphere per light probe (the spheres are drawn only
// in this view; the shading is the default branch's).
const VIEW_PROBES: u32 = 7u;
// The level's distance field alone (a full-screen pass, fs_sdf_view in
// sdf.wgsl): its sphere-traced surface and a horizontal slice.
const VIEW_SDF: u32 = 8u;

// VertexIn.probe.w: lightmapped; lit by probe.rgb (irradiance / π from the
// bake's probes) in place of the lightmap; an invalid probe's red sphere.
const PROBE_NONE: f32 = 0.0;
const PROBE_LIT: f32 = 1.0;
const PROBE_INVALID: f32 = 2.0;

const FLAG_BASE_TEXTURE: u32 = 1u;
const FLAG_EMISSIVE_TEXTURE: u32 = 2u;
const FLAG_LIGHTMAP: u32 = 4u;
// alphaMode BLEND: output the alpha for blending, no cut-out.
const FLAG_BLEND: u32 = 8u;
// The base colour / emissive texture is read through TEXCOORD_1.
const FLAG_BASE_UV1: u32 = 16u;
const FLAG_EMISSIVE_UV1: u32 = 32u;

fn apply_uv_transform(row0: vec4<f32>, row1: vec4<f32>, uv: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(dot(row0.xy, uv) + row0.z, dot(row1.xy, uv) + row1.z);
}

// ACES filmic tone map, Stephen Hill's fit of the RRT + ODT (input and
// output matrices included); linear sRGB in, linear display values in [0, 1] out.
fn tone_map_aces(color: vec3<f32>) -> vec3<f32> {
    let aces_in = mat3x3<f32>(
        vec3<f32>(0.59719, 0.07600, 0.02840),
        vec3<f32>(0.35458, 0.90834, 0.13383),
        vec3<f32>(0.04823, 0.01566, 0.83777),
    );
    let aces_out = mat3x3<f32>(
        vec3<f32>(1.60475, -0.10208, -0.00327),
        vec3<f32>(-0.53108, 1.10813, -0.07276),
        vec3<f32>(-0.07367, -0.00605, 1.07602),
    );
    let v = aces_in * color;
    let a = v * (v + 0.0245786) - 0.000090537;
    let b = v * (0.983729 * v + 0.4329510) + 0.238081;
    return clamp(aces_out * (a / b), vec3<f32>(0.0), vec3<f32>(1.0));
}

// The sRGB transfer function (IEC 61966-2-1) with three.js's constants
// (sRGBTransferOETF in colorspace_pars_fragment.glsl.js, r187): the preview
// encodes in the shader into a plain 8-bit target, as three.js does for its
// canvas, so blending (alphaMode BLEND) mixes encoded values as there.
fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let v = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(pow(v, vec3<f32>(0.41666)) * 1.055 - vec3<f32>(0.055), v * 12.92, v <= vec3<f32>(0.0031308));
}

fn tone_map(color: vec3<f32>, exposure: f32, mode: u32) -> vec3<f32> {
    let c = max(color * exposure, vec3<f32>(0.0));
    if mode == 0u {
        return tone_map_aces(c);
    }
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

// Cubic B-spline filtering from four bilinear taps (Sigg & Hadwiger, GPU
// Gems 2 ch. 20): smooth across texel boundaries, slightly blurrier than
// bilinear, no ringing. Level 0 only (lightmaps have no mips).
fn sample_bicubic(t: texture_2d<f32>, s: sampler, uv: vec2<f32>) -> vec4<f32> {
    let size = vec2<f32>(textureDimensions(t, 0));
    let p = uv * size - 0.5;
    let i = floor(p);
    let f = p - i;
    let f2 = f * f;
    let f3 = f2 * f;
    let w0 = (-f3 + 3.0 * f2 - 3.0 * f + 1.0) / 6.0;
    let w1 = (3.0 * f3 - 6.0 * f2 + 4.0) / 6.0;
    let w2 = (-3.0 * f3 + 3.0 * f2 + 3.0 * f + 1.0) / 6.0;
    let w3 = f3 / 6.0;
    let g0 = w0 + w1;
    let g1 = w2 + w3;
    // Texel-centre coordinates of the two combined taps per axis.
    let c0 = (i - 1.0 + w1 / g0 + 0.5) / size;
    let c1 = (i + 1.0 + w3 / g1 + 0.5) / size;
    let s00 = textureSampleLevel(t, s, vec2<f32>(c0.x, c0.y), 0.0);
    let s10 = textureSampleLevel(t, s, vec2<f32>(c1.x, c0.y), 0.0);
    let s01 = textureSampleLevel(t, s, vec2<f32>(c0.x, c1.y), 0.0);
    let s11 = textureSampleLevel(t, s, vec2<f32>(c1.x, c1.y), 0.0);
    return g0.y * (g0.x * s00 + g1.x * s10) + g1.y * (g0.x * s01 + g1.x * s11);
}
