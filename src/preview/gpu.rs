//! Every struct the GPU reads, `#[repr(C)]` and [`bytemuck::Pod`], in the
//! layout of its WGSL twin in `shaders/common.wgsl` / `shaders/preview.wgsl`
//! (`tests/preview.rs` checks sizes and offsets with naga).

use bytemuck::{Pod, Zeroable};

/// The shader source: `shaders/common.wgsl` followed by `shaders/preview.wgsl`
/// (WGSL has no includes).
pub const SHADER: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
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
    /// Padding to the WGSL struct's 16-byte alignment.
    pub _pad: [f32; 2],
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
                ("_pad", offset_of!(Globals, _pad)),
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
