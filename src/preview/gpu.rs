//! Every struct the GPU reads, `#[repr(C)]` and [`bytemuck::Pod`], in the
//! layout of its WGSL twin in `shaders/common.wgsl` / `shaders/preview.wgsl`
//! (`tests/preview.rs` checks sizes and offsets with naga).

use bytemuck::{Pod, Zeroable};

/// The shader source: `shaders/common.wgsl`, `shaders/sdf.wgsl` and
/// `shaders/preview.wgsl` (WGSL has no includes).
pub const SHADER: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    "\n",
    include_str!("../../shaders/sdf.wgsl"),
    "\n",
    include_str!("../../shaders/preview.wgsl")
);

/// WGSL `Globals` (group 0, binding 0): per-frame camera and display settings.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Globals {
    /// clip_from_world, column-major (reverse-Z, infinite far plane).
    pub view_proj: [[f32; 4]; 4],
    /// Eye position (xyz), w unused.
    pub camera_pos: [f32; 4],
    /// Linear exposure multiplier 2^EV.
    pub exposure: f32,
    /// Debug view ([`super::options::ViewMode`] as u32).
    pub view_mode: u32,
    /// 1 for bicubic lightmap filtering, 0 for bilinear.
    pub bicubic: u32,
    /// 0: ACES fitted, 1: none (clamp).
    pub tone_map: u32,
    /// Render target size in pixels.
    pub viewport: [f32; 2],
    /// Lights used of `lights`.
    pub light_count: u32,
    /// Padding to the WGSL struct's 16-byte alignment.
    pub _pad: f32,
    /// world_from_clip (the inverse of `view_proj`): the sdf view's rays.
    pub inv_view_proj: [[f32; 4]; 4],
    /// The level's distance field ([`super::field`]): its box's minimum
    /// corner (xyz) and voxel edge (w; 0: no field).
    pub sdf_min: [f32; 4],
    /// The box's maximum corner (xyz); w: 1 where the real-time lights are
    /// shadowed by sphere tracing the field, 0 where not.
    pub sdf_max: [f32; 4],
    /// x: the sdf view's slice height (world y); y: the distance-field
    /// ambient occlusion's reach on probe-lit surfaces (metres; 0: none).
    pub sdf_params: [f32; 4],
    /// The lights the engine draws in real time (modes `indirect` and
    /// `realtime`, [`crate::scene::LightMode`]): their direct light,
    /// masked by the shadowmask or shadowed by the distance field where
    /// there is one, is added to the lightmap's.
    pub lights: [PreviewLight; MAX_LIGHTS],
}

/// Most real-time lights the preview draws.
pub const MAX_LIGHTS: usize = 8;

/// WGSL `PreviewLight`: one punctual light drawn in real time, with the
/// bake's own falloff ([`crate::light::lights::punctual_incident`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PreviewLight {
    /// xyz: position (point, spot); w: 0 directional, 1 point, 2 spot.
    pub position_kind: [f32; 4],
    /// xyz: the direction the light points to; w: range (0: none).
    pub direction_range: [f32; 4],
    /// rgb: intensity (W/sr; W/m² for directional); w unused.
    pub intensity: [f32; 4],
    /// x, y: the spot cone's scale and offset (KHR_lights_punctual's
    /// falloff: (cos θ · scale + offset)², clamped); z: the light's
    /// shadowmask channel (0–3; −1: none); w: the light's size for soft
    /// shadows: tan of a directional light's angular radius, a point or
    /// spot light's radius (metres).
    pub cone: [f32; 4],
}

impl PreviewLight {
    /// The preview's copy of `light`, with its shadowmask `channel`.
    pub fn of(light: &crate::scene::Light, channel: Option<u8>) -> PreviewLight {
        use crate::scene::LightKind;
        let (kind, cone) = match light.kind {
            LightKind::Directional => (0.0, [0.0; 4]),
            LightKind::Point => (1.0, [0.0; 4]),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let scale = 1.0 / (inner_cone_angle.cos() - outer_cone_angle.cos()).max(0.001);
                (2.0, [scale, -outer_cone_angle.cos() * scale, 0.0, 0.0])
            }
        };
        let mut cone = cone;
        cone[2] = channel.map_or(-1.0, f32::from);
        cone[3] = match light.kind {
            LightKind::Directional => (0.5 * light.angle).tan(),
            _ => light.radius,
        };
        PreviewLight {
            position_kind: light.position.extend(kind).to_array(),
            direction_range: light
                .direction
                .extend(light.range.filter(|r| *r > 0.0).unwrap_or(0.0))
                .to_array(),
            intensity: light.intensity.extend(0.0).to_array(),
            cone,
        }
    }

    /// The lights of `scene` the engine draws in real time (every mode but
    /// `baked`), each with its shadowmask channel from `channels` (per
    /// scene light; may be empty), at most [`MAX_LIGHTS`], and how many
    /// more there were.
    pub fn realtime(
        scene: &crate::scene::Scene,
        channels: &[Option<u8>],
    ) -> (Vec<PreviewLight>, usize) {
        let all: Vec<PreviewLight> = scene
            .lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.mode != crate::scene::LightMode::Baked)
            .map(|(i, l)| PreviewLight::of(l, channels.get(i).copied().flatten()))
            .collect();
        let extra = all.len().saturating_sub(MAX_LIGHTS);
        (all.into_iter().take(MAX_LIGHTS).collect(), extra)
    }
}

/// `Material::flags`: the base colour texture is used.
pub const FLAG_BASE_TEXTURE: u32 = 1;
/// `Material::flags`: the emissive texture is used.
pub const FLAG_EMISSIVE_TEXTURE: u32 = 2;
/// `Material::flags`: the material has a lightmap (`MOZ_lightmap`).
pub const FLAG_LIGHTMAP: u32 = 4;
/// `Material::flags`: glTF `alphaMode` `BLEND`: the fragment's alpha is
/// written for alpha blending (three.js `transparent: true`), not cut out.
pub const FLAG_BLEND: u32 = 8;
/// `Material::flags`: the base colour texture is read through `TEXCOORD_1`.
pub const FLAG_BASE_UV1: u32 = 16;
/// `Material::flags`: the emissive texture is read through `TEXCOORD_1`.
pub const FLAG_EMISSIVE_UV1: u32 = 32;

/// WGSL `Material` (group 1, binding 0).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Material {
    /// baseColorFactor (linear RGBA).
    pub base_color: [f32; 4],
    /// Emitted radiance factor (rgb), w unused.
    pub emissive: [f32; 4],
    /// Base colour `KHR_texture_transform` as two rows of a 2×3 matrix.
    pub base_uv0: [f32; 4],
    /// Second row.
    pub base_uv1: [f32; 4],
    /// Emissive `KHR_texture_transform`, first row.
    pub emissive_uv0: [f32; 4],
    /// Second row.
    pub emissive_uv1: [f32; 4],
    /// Lightmap rectangle: offset (xy) and scale (zw) of `MOZ_lightmap`'s transform.
    pub lightmap_rect: [f32; 4],
    /// `MOZ_lightmap.intensity / π`: linear value = sRGB-decoded texel × this.
    pub lightmap_scale: f32,
    /// `FLAG_*`.
    pub flags: u32,
    /// alphaCutoff for MASK, negative for OPAQUE and BLEND.
    pub alpha_cutoff: f32,
    /// Padding.
    pub _pad: f32,
}

/// One vertex (world space; triangles are not indexed, so each vertex knows
/// its corner for the chart-border view).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct Vertex {
    /// World position.
    pub position: [f32; 3],
    /// World normal.
    pub normal: [f32; 3],
    /// `TEXCOORD_0`.
    pub uv0: [f32; 2],
    /// `TEXCOORD_1` (the instance's [0, 1] lightmap UV).
    pub uv1: [f32; 2],
    /// Bits 0–1: corner (0, 1, 2); bits 2–4: edges of the triangle on a
    /// chart border (edge k joins corners k and k + 1).
    pub corner_edges: u32,
    /// Probe light: rgb = irradiance / π from the bake's probes at this
    /// vertex (computed on the CPU, clamped at 0), w = [`PROBE_NONE`],
    /// [`PROBE_LIT`] or [`PROBE_INVALID`].
    pub probe: [f32; 4],
    /// `COLOR_0` (linear RGBA; white where the mesh has none), multiplied
    /// into the base colour.
    pub color: [f32; 4],
}

/// [`Vertex::probe`] w: lightmapped geometry (the probe rgb is unused).
pub const PROBE_NONE: f32 = 0.0;
/// [`Vertex::probe`] w: lit by the probe rgb in place of the lightmap (a
/// dynamic node, or a valid probe's sphere).
pub const PROBE_LIT: f32 = 1.0;
/// [`Vertex::probe`] w: the sphere of an invalid probe, drawn red.
pub const PROBE_INVALID: f32 = 2.0;

impl Default for Vertex {
    /// All zeros but a white `color` (no vertex colour).
    fn default() -> Self {
        Vertex {
            color: [1.0; 4],
            ..Zeroable::zeroed()
        }
    }
}

impl Vertex {
    /// The vertex buffer layout matching `VertexIn` in `shaders/preview.wgsl`.
    pub const ATTRIBUTES: [wgpu::VertexAttribute; 7] = wgpu::vertex_attr_array![
        0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x2, 4 => Uint32,
        5 => Float32x4, 6 => Float32x4
    ];

    /// The vertex buffer layout.
    pub fn layout() -> wgpu::VertexBufferLayout<'static> {
        wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &Self::ATTRIBUTES,
        }
    }
}

/// A Rust struct's layout: (name, size, (field, offset) in declaration order).
pub type Layout = (&'static str, usize, Vec<(&'static str, usize)>);

/// Rust struct layouts, for the WGSL layout test.
pub fn layouts() -> Vec<Layout> {
    use std::mem::{offset_of, size_of};
    vec![
        (
            "Globals",
            size_of::<Globals>(),
            vec![
                ("view_proj", offset_of!(Globals, view_proj)),
                ("camera_pos", offset_of!(Globals, camera_pos)),
                ("exposure", offset_of!(Globals, exposure)),
                ("view_mode", offset_of!(Globals, view_mode)),
                ("bicubic", offset_of!(Globals, bicubic)),
                ("tone_map", offset_of!(Globals, tone_map)),
                ("viewport", offset_of!(Globals, viewport)),
                ("light_count", offset_of!(Globals, light_count)),
                ("_pad", offset_of!(Globals, _pad)),
                ("inv_view_proj", offset_of!(Globals, inv_view_proj)),
                ("sdf_min", offset_of!(Globals, sdf_min)),
                ("sdf_max", offset_of!(Globals, sdf_max)),
                ("sdf_params", offset_of!(Globals, sdf_params)),
                ("lights", offset_of!(Globals, lights)),
            ],
        ),
        (
            "PreviewLight",
            size_of::<PreviewLight>(),
            vec![
                ("position_kind", offset_of!(PreviewLight, position_kind)),
                ("direction_range", offset_of!(PreviewLight, direction_range)),
                ("intensity", offset_of!(PreviewLight, intensity)),
                ("cone", offset_of!(PreviewLight, cone)),
            ],
        ),
        (
            "Material",
            size_of::<Material>(),
            vec![
                ("base_color", offset_of!(Material, base_color)),
                ("emissive", offset_of!(Material, emissive)),
                ("base_uv0", offset_of!(Material, base_uv0)),
                ("base_uv1", offset_of!(Material, base_uv1)),
                ("emissive_uv0", offset_of!(Material, emissive_uv0)),
                ("emissive_uv1", offset_of!(Material, emissive_uv1)),
                ("lightmap_rect", offset_of!(Material, lightmap_rect)),
                ("lightmap_scale", offset_of!(Material, lightmap_scale)),
                ("flags", offset_of!(Material, flags)),
                ("alpha_cutoff", offset_of!(Material, alpha_cutoff)),
                ("_pad", offset_of!(Material, _pad)),
            ],
        ),
    ]
}

/// `Vertex` field offsets in attribute (shader location) order.
pub fn vertex_offsets() -> [usize; 7] {
    use std::mem::offset_of;
    [
        offset_of!(Vertex, position),
        offset_of!(Vertex, normal),
        offset_of!(Vertex, uv0),
        offset_of!(Vertex, uv1),
        offset_of!(Vertex, corner_edges),
        offset_of!(Vertex, probe),
        offset_of!(Vertex, color),
    ]
}
