// The preview's one shader: base colour × lightmap + emissive, tone mapped,
// with the debug views. It follows three.js r187's MeshLambertMaterial with
// no lights but the lightmap (meshlambert.glsl.js): diffuseColor =
// baseColorFactor × map × COLOR_0 (map_fragment, color_fragment), alpha
// test for MASK (alphatest_fragment), outgoing = diffuseColor.rgb ×
// lightmap irradiance / π + emissive × emissiveMap (lights_fragment_maps,
// BRDF_Lambert, emissivemap_fragment), alpha = diffuseColor.a for BLEND. Probe-lit vertices (dynamic nodes, probe spheres)
// carry their light, irradiance / π from the bake's probes computed per
// vertex on the CPU, in place of the lightmap. Prefixed with common.wgsl
// and sdf.wgsl by the Rust side.

@group(0) @binding(0) var<uniform> globals: Globals;

@group(1) @binding(0) var<uniform> material: Material;
@group(1) @binding(1) var base_texture: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;
@group(1) @binding(3) var emissive_texture: texture_2d<f32>;
@group(1) @binding(4) var emissive_sampler: sampler;
@group(1) @binding(5) var lightmap_texture: texture_2d<f32>;
@group(1) @binding(6) var lightmap_sampler: sampler;
// The bake's debug map (`--debug-maps`): rgb patch colour, alpha 1 valid
// texel, 0.5 invalid texel, 0 no texel (or no map: a transparent texel).
@group(1) @binding(7) var debug_texture: texture_2d<f32>;
// The bake's shadowmask page (linear RGBA: each channel one shadowmask
// light's visibility), read with the lightmap's sampler; a white texel
// where the page has none.
@group(1) @binding(8) var shadowmask_texture: texture_2d<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv0: vec2<f32>,
    @location(3) uv1: vec2<f32>,
    // Bits 0-1: the vertex's corner in its triangle; bits 2-4: which of the
    // triangle's edges (edge k joins corners k and k+1) are chart borders.
    @location(4) corner_edges: u32,
    // rgb: irradiance / π from the probes (per vertex, clamped at 0);
    // w: PROBE_NONE (lightmapped), PROBE_LIT or PROBE_INVALID.
    @location(5) probe: vec4<f32>,
    // COLOR_0, linear RGBA (white where the mesh has none).
    @location(6) color: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv0: vec2<f32>,
    @location(3) uv1: vec2<f32>,
    @location(4) bary: vec3<f32>,
    @location(5) @interpolate(flat) edges: u32,
    @location(6) probe: vec4<f32>,
    @location(7) color: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.uv0 = v.uv0;
    out.uv1 = v.uv1;
    let corner = v.corner_edges & 3u;
    out.bary = vec3<f32>(f32(corner == 0u), f32(corner == 1u), f32(corner == 2u));
    out.edges = v.corner_edges >> 2u;
    out.probe = v.probe;
    out.color = v.color;
    return out;
}

fn lightmap_at(uv: vec2<f32>) -> vec3<f32> {
    var lm: vec4<f32>;
    if globals.bicubic != 0u {
        lm = sample_bicubic(lightmap_texture, lightmap_sampler, uv);
    } else {
        lm = textureSampleLevel(lightmap_texture, lightmap_sampler, uv, 0.0);
    }
    return lm.rgb * material.lightmap_scale;
}

// The debug map's texel under atlas coordinate `uv` (nearest, no filtering).
fn debug_at(uv: vec2<f32>) -> vec4<f32> {
    let size = textureDimensions(debug_texture, 0);
    let t = clamp(vec2<i32>(floor(uv * vec2<f32>(size))), vec2<i32>(0), vec2<i32>(size) - 1);
    return textureLoad(debug_texture, t, 0);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // Derivatives first, in uniform control flow: fwidth, and the
    // trilinear (mipmapped) texture samples, whose branches depend on the
    // material uniform only.
    let bary_width = fwidth(in.bary);
    let flags = material.flags;

    var base = material.base_color * in.color;
    if (flags & FLAG_BASE_TEXTURE) != 0u {
        let uv_set = select(in.uv0, in.uv1, (flags & FLAG_BASE_UV1) != 0u);
        let uv = apply_uv_transform(material.base_uv0, material.base_uv1, uv_set);
        base = base * textureSample(base_texture, base_sampler, uv);
    }
    var emissive = material.emissive.rgb;
    if (flags & FLAG_EMISSIVE_TEXTURE) != 0u {
        let uv_set = select(in.uv0, in.uv1, (flags & FLAG_EMISSIVE_UV1) != 0u);
        let uv = apply_uv_transform(material.emissive_uv0, material.emissive_uv1, uv_set);
        emissive = emissive * textureSample(emissive_texture, emissive_sampler, uv).rgb;
    }
    if material.alpha_cutoff >= 0.0 && base.a < material.alpha_cutoff {
        discard;
    }
    let atlas_uv = material.lightmap_rect.xy + in.uv1 * material.lightmap_rect.zw;
    // The light: the lightmap's irradiance / π, or the probes' for
    // probe-lit vertices (their material may be lightmapped elsewhere, but
    // their TEXCOORD_1 means nothing).
    let probe_lit = in.probe.w > 0.5 * (PROBE_NONE + PROBE_LIT);
    let has_lightmap = (material.flags & FLAG_LIGHTMAP) != 0u && !probe_lit;
    var lightmap = vec3<f32>(0.0);
    if has_lightmap {
        lightmap = lightmap_at(atlas_uv);
    }
    let n = normalize(in.normal);
    if probe_lit {
        lightmap = in.probe.rgb;
        // Distance-field ambient occlusion where the level's field is
        // loaded and it is on (sdf.wgsl).
        if globals.sdf_min.w > 0.0 && globals.sdf_params.y > 0.0 && in.probe.w < 0.5 * (PROBE_LIT + PROBE_INVALID) {
            lightmap *= sdf_ao(in.world, n, globals.sdf_params.y);
        }
    }
    // The lights an engine draws in real time add their direct light (the
    // lightmap and probes hold only their bounces). Shadowmask lights are
    // masked by their channel on lightmapped surfaces; the others, and
    // all on probe-lit surfaces, are shadowed by sphere tracing the
    // level's field where there is one, and unshadowed where not.
    var mask = vec4<f32>(1.0);
    if has_lightmap {
        mask = textureSampleLevel(shadowmask_texture, lightmap_sampler, atlas_uv, 0.0);
    }
    let realtime = realtime_light(in.world, n, mask, has_lightmap);
    var lit = base.rgb * (lightmap + realtime) + emissive;
    // An invalid probe's sphere: plain red radiance.
    if in.probe.w > 0.5 * (PROBE_LIT + PROBE_INVALID) {
        lightmap = vec3<f32>(1.0, 0.0, 0.0);
        lit = lightmap;
    }

    var color: vec3<f32>;
    switch globals.view_mode {
        case VIEW_LIGHTMAP: {
            color = tone_map(lightmap, globals.exposure, globals.tone_map);
        }
        case VIEW_ALBEDO: {
            color = base.rgb;
        }
        case VIEW_CHECKER: {
            // One checker square per lightmap texel; surfaces without a
            // lightmap are magenta.
            if has_lightmap {
                let size = vec2<f32>(textureDimensions(lightmap_texture, 0));
                let t = vec2<i32>(floor(atlas_uv * size));
                let odd = ((t.x + t.y) & 1) != 0;
                let shade = tone_map(lit, globals.exposure, globals.tone_map);
                color = select(shade * 0.55 + 0.1, shade * 0.85 + 0.15, odd);
            } else {
                color = vec3<f32>(1.0, 0.0, 1.0);
            }
        }
        case VIEW_CHARTS: {
            color = tone_map(lit, globals.exposure, globals.tone_map) * 0.8;
            // Distance (in pixels) to each edge: edge k is opposite corner k+2.
            let d = in.bary.zxy / max(bary_width.zxy, vec3<f32>(1e-6));
            var border = false;
            for (var k = 0u; k < 3u; k++) {
                if ((in.edges >> k) & 1u) != 0u && d[k] < 1.5 {
                    border = true;
                }
            }
            if border {
                color = vec3<f32>(1.0, 0.02, 0.0);
            }
        }
        case VIEW_PATCHES: {
            let d = select(debug_at(atlas_uv), vec4<f32>(0.0), probe_lit);
            let shade = tone_map(lit, globals.exposure, globals.tone_map);
            if d.a > 0.0 {
                color = mix(d.rgb, shade, 0.3);
            } else {
                // No texel here, or no debug map: magenta stripes.
                color = select(shade * 0.3, vec3<f32>(1.0, 0.0, 1.0), fract(in.clip.x * 0.05 + in.clip.y * 0.05) < 0.5);
            }
        }
        case VIEW_INVALID: {
            let d = select(debug_at(atlas_uv), vec4<f32>(0.0), probe_lit);
            color = tone_map(lit, globals.exposure, globals.tone_map) * 0.8;
            if d.a > 0.25 && d.a < 0.75 {
                color = vec3<f32>(1.0, 0.05, 0.0);
            } else if textureDimensions(debug_texture, 0).x <= 1u {
                color = select(color, vec3<f32>(1.0, 0.0, 1.0), fract(in.clip.x * 0.05 + in.clip.y * 0.05) < 0.5);
            }
        }
        default: {
            color = tone_map(lit, globals.exposure, globals.tone_map);
        }
    }
    // The render target is plain 8-bit: encode here (three.js's
    // colorspace_fragment), so BLEND materials blend encoded values, as in
    // three.js's canvas. Opaque and masked materials write alpha 1, and so
    // do the debug views (the web viewer draws them with opaque materials).
    let lit_view = globals.view_mode == VIEW_LIT || globals.view_mode == VIEW_PROBES;
    let alpha = select(1.0, base.a, (flags & FLAG_BLEND) != 0u && lit_view);
    return vec4<f32>(srgb_encode(color), alpha);
}
