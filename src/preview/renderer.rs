//! The one render path: [`Renderer::render`] draws the model into any
//! colour target view (the window's surface texture or an offscreen
//! texture), so the window and `--headless` produce the same pixels.
//!
//! As three.js's `WebGLRenderer` (r187): the target is cleared to black,
//! opaque and masked batches are drawn first, then blended objects back to
//! front by the projected depth of their bounding-box centre, without depth
//! writes, double-sided ones back faces first; the shader writes
//! sRGB-encoded values to a plain 8-bit target (three.js's
//! `colorspace_fragment`), so blending mixes encoded values as on
//! three.js's canvas.

use super::camera::Camera;
use super::field::Field;
use super::gpu::{self, Globals, PreviewLight, Vertex};
use super::mips;
use super::model::Model;
use super::options::{Settings, ViewMode};
use super::probe_light;
use crate::probes::Probes;
use crate::scene::{Filter, Texture, Wrap};
use wgpu::util::DeviceExt as _;

/// Depth buffer format (reverse-Z: cleared to 0, `Greater` passes).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

struct DrawBatch {
    vertices: std::ops::Range<u32>,
    material: usize,
    /// Blended batches: the world position they are sorted by.
    origin: Option<glam::Vec3>,
}

/// The render pipelines, by blending and face culling.
struct Pipelines {
    /// Opaque and masked: [back faces culled, double-sided].
    opaque: [wgpu::RenderPipeline; 2],
    /// Blended, no depth writes: [back faces culled, front faces culled].
    blend: [wgpu::RenderPipeline; 2],
    /// The sdf view: one full-screen triangle (`fs_sdf_view`).
    sdf_view: wgpu::RenderPipeline,
}

/// The probe spheres on the GPU (indexed; drawn in the probes view only).
struct Spheres {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
    material: usize,
}

impl Spheres {
    /// Builds and uploads a sphere per probe ([`probe_light::spheres`]);
    /// None without any.
    fn upload(device: &wgpu::Device, probes: &Probes, material: usize) -> Option<Spheres> {
        let s = probe_light::spheres(probes);
        if s.indices.is_empty() {
            return None;
        }
        let buffer = |label, contents, usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        Some(Spheres {
            vertices: buffer(
                "probe sphere vertices",
                bytemuck::cast_slice(&s.vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: buffer(
                "probe sphere indices",
                bytemuck::cast_slice(&s.indices),
                wgpu::BufferUsages::INDEX,
            ),
            count: s.indices.len() as u32,
            material,
        })
    }
}

/// GPU resources of a loaded model and the pipeline that draws it.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    format: wgpu::TextureFormat,
    pipelines: Pipelines,
    globals: wgpu::Buffer,
    globals_group: wgpu::BindGroup,
    vertices: Option<wgpu::Buffer>,
    batches: Vec<DrawBatch>,
    /// The probes and their spheres' material, until the spheres are built
    /// (the first frame of the probes view: a few MB per thousand probes).
    probes: Option<(Probes, usize)>,
    spheres: Option<Spheres>,
    material_groups: Vec<wgpu::BindGroup>,
    double_sided: Vec<bool>,
    /// The scene's textures (kept for [`Renderer::texture_mip_levels`]).
    scene_textures: Vec<wgpu::Texture>,
    /// The linear lightmap pages' textures, per page (None: an sRGB page),
    /// for [`Renderer::write_linear_page`].
    linear_pages: Vec<Option<wgpu::Texture>>,
    depth: Option<(wgpu::TextureView, u32, u32)>,
    /// The lights drawn in real time ([`PreviewLight::realtime`]).
    lights: Vec<PreviewLight>,
    /// The distance field's box (min, max) and voxel edge, if one is loaded.
    field: Option<(glam::Vec3, glam::Vec3, f32)>,
    size: (u32, u32),
    /// The camera the next frame is drawn from.
    pub camera: Camera,
    /// Display settings of the next frame.
    pub settings: Settings,
}

/// The scene's lights that an engine draws in real time; a warning where
/// there are more than the preview draws.
fn realtime_lights(scene: &crate::scene::Scene, channels: &[Option<u8>]) -> Vec<PreviewLight> {
    let (lights, extra) = PreviewLight::realtime(scene, channels);
    if extra > 0 {
        eprintln!(
            "warning: the preview draws {} real-time lights; {extra} more are not drawn",
            gpu::MAX_LIGHTS
        );
    }
    lights
}

fn address_mode(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::Clamp => wgpu::AddressMode::ClampToEdge,
        Wrap::Mirror => wgpu::AddressMode::MirrorRepeat,
    }
}

fn srgb_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    width: u32,
    height: u32,
    rgba: &[u8],
) -> wgpu::TextureView {
    rgba8_texture(device, queue, label, (width, height), &[rgba], true)
        .create_view(&Default::default())
}

/// A linear page ([`super::model::LinearPage`]) as an `Rgba16Float`
/// texture (filterable, as the sRGB pages are; half floats hold the
/// page's values to 2⁻¹¹ relative).
fn linear_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    page: &super::model::LinearPage,
) -> (wgpu::Texture, wgpu::TextureView) {
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: page.width,
            height: page.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba16Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    write_linear(queue, &texture, page);
    let view = texture.create_view(&Default::default());
    (texture, view)
}

/// `page` into `texture` (Rgba16Float, its size).
fn write_linear(queue: &wgpu::Queue, texture: &wgpu::Texture, page: &super::model::LinearPage) {
    let texels: Vec<u16> = (page.rgb.iter())
        .flat_map(|v| [v.x, v.y, v.z, 1.0])
        .map(|x| half::f16::from_f32(x).to_bits())
        .collect();
    queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(&texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(8 * page.width),
            rows_per_image: Some(page.height),
        },
        texture.size(),
    );
}

/// An RGBA8 texture, sRGB-decoded on sampling or not (data maps), with
/// `levels` as its mip levels (level 0 first, each max(1, ⌊size / 2ⁿ⌋)).
fn rgba8_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    (width, height): (u32, u32),
    levels: &[&[u8]],
    srgb: bool,
) -> wgpu::Texture {
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: if srgb {
            wgpu::TextureFormat::Rgba8UnormSrgb
        } else {
            wgpu::TextureFormat::Rgba8Unorm
        },
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, rgba) in levels.iter().enumerate() {
        let (w, h) = ((width >> level).max(1), (height >> level).max(1));
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: level as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * w),
                rows_per_image: Some(h),
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
    texture
}

/// The scene's base colour / emissive textures with their full mip chains
/// ([`mips::mip_chain`], filtered in linear space; built in parallel).
fn scene_textures(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    textures: &[Texture],
) -> Vec<wgpu::Texture> {
    use rayon::prelude::*;
    let chains: Vec<Vec<Vec<u8>>> = textures
        .par_iter()
        .map(|t| mips::mip_chain(t.width, t.height, bytemuck::cast_slice(&t.rgba), true))
        .collect();
    textures
        .iter()
        .zip(&chains)
        .enumerate()
        .map(|(i, (t, chain))| {
            let levels: Vec<&[u8]> = std::iter::once(bytemuck::cast_slice(&t.rgba))
                .chain(chain.iter().map(Vec::as_slice))
                .collect();
            let label = format!("texture{i}");
            rgba8_texture(device, queue, &label, (t.width, t.height), &levels, true)
        })
        .collect()
}

/// The lightmaps' and "no texture" sampler: bilinear, clamped, level 0.
fn clamp_sampler(device: &wgpu::Device) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("clamp"),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    })
}

/// A scene texture's sampler, as three.js sets it from the glTF sampler:
/// wrap modes, `magFilter`, `minFilter` (by default `LINEAR` and
/// `LINEAR_MIPMAP_LINEAR`: trilinear; a `minFilter` without mipmaps reads
/// level 0 only), anisotropy 1 (three.js's `Texture.anisotropy` default).
fn texture_sampler(device: &wgpu::Device, t: &Texture) -> wgpu::Sampler {
    let filter = |f: Filter| match f {
        Filter::Nearest => wgpu::FilterMode::Nearest,
        Filter::Linear => wgpu::FilterMode::Linear,
    };
    let f = t.filters;
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("texture"),
        address_mode_u: address_mode(t.wrap_s),
        address_mode_v: address_mode(t.wrap_t),
        mag_filter: filter(f.mag),
        min_filter: filter(f.min),
        mipmap_filter: match f.mipmap {
            Some(Filter::Linear) => wgpu::MipmapFilterMode::Linear,
            _ => wgpu::MipmapFilterMode::Nearest,
        },
        lod_max_clamp: if f.mipmap.is_some() { 32.0 } else { 0.0 },
        anisotropy_clamp: 1,
        ..Default::default()
    })
}

impl Renderer {
    /// Uploads `model` and builds the pipeline for colour targets of `format`,
    /// a plain (not sRGB) 8-bit format: the shader writes sRGB-encoded
    /// values itself, as three.js's `colorspace_fragment` does for its
    /// canvas, so blended materials blend the encoded values as there.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        format: wgpu::TextureFormat,
        model: &Model,
        camera: Camera,
        settings: Settings,
    ) -> Renderer {
        let (globals_layout, material_layout) = bind_group_layouts(device);
        let pipelines = pipelines(device, &globals_layout, &material_layout, format);
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let field_view = field_texture(device, queue, model.field.as_ref());
        let globals_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &globals_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&field_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&clamp_sampler(device)),
                },
            ],
        });
        let mut textures = Textures::upload(device, queue, model);
        let material_groups = material_groups(device, &material_layout, model, &textures);
        let scene_textures = std::mem::take(&mut textures.textures);
        let linear_pages = std::mem::take(&mut textures.linear);
        let vertices = (!model.vertices.is_empty()).then(|| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vertices"),
                contents: bytemuck::cast_slice(&model.vertices),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            })
        });
        Renderer {
            device: device.clone(),
            queue: queue.clone(),
            format,
            pipelines,
            globals,
            globals_group,
            vertices,
            batches: model
                .batches
                .iter()
                .map(|b| DrawBatch {
                    vertices: b.vertices.clone(),
                    material: b.material,
                    origin: b.origin,
                })
                .collect(),
            probes: model.probes.clone().zip(model.probe_material),
            lights: realtime_lights(&model.scene, &model.light_channels),
            field: model
                .field
                .as_ref()
                .map(|f| (f.bounds.0, f.bounds.1, f.voxel)),
            spheres: None,
            material_groups,
            double_sided: model.materials.iter().map(|m| m.double_sided).collect(),
            scene_textures,
            linear_pages,
            depth: None,
            size: (1, 1),
            camera,
            settings,
        }
    }

    /// Replaces linear lightmap page `index` with `page` (its size); false
    /// where the page is not a linear one of that size (nothing written).
    /// Rewrites the model's vertices from `first` on (a live sun's probe
    /// light: [`super::live::LiveView::move_probes`]).
    pub fn write_vertices(&self, first: usize, vertices: &[super::gpu::Vertex]) {
        if let Some(buffer) = &self.vertices {
            let offset = (first * std::mem::size_of::<super::gpu::Vertex>()) as u64;
            self.queue
                .write_buffer(buffer, offset, bytemuck::cast_slice(vertices));
        }
    }

    /// New probes for the probes view: its spheres are built again from
    /// them at the next frame that shows them.
    pub fn set_probes(&mut self, probes: &Probes) {
        if let Some((p, _)) = &mut self.probes {
            p.clone_from(probes);
        } else if let Some(s) = self.spheres.take() {
            self.probes = Some((probes.clone(), s.material));
        }
        self.spheres = None;
    }

    pub fn write_linear_page(&self, index: usize, page: &super::model::LinearPage) -> bool {
        match self.linear_pages.get(index) {
            Some(Some(t)) if (t.width(), t.height()) == (page.width, page.height) => {
                write_linear(&self.queue, t, page);
                true
            }
            _ => false,
        }
    }

    /// The real-time lights again from `scene` (a live sun moved).
    pub fn set_lights(&mut self, scene: &crate::scene::Scene, channels: &[Option<u8>]) {
        self.lights = realtime_lights(scene, channels);
    }

    /// The mip level count of each of the scene's textures
    /// ([`crate::scene::Scene::textures`]) as uploaded: a full chain, to 1 × 1.
    pub fn texture_mip_levels(&self) -> Vec<u32> {
        self.scene_textures
            .iter()
            .map(wgpu::Texture::mip_level_count)
            .collect()
    }

    /// The blended batches in three.js's drawing order for the current
    /// camera: back to front by their origin's depth
    /// (`reversePainterSortStable` on the projected z of the object's
    /// bounding-sphere centre; z/w of a perspective projection grows with
    /// the view depth d as 1 − 2n/d, so points behind the eye, d < 0, sort
    /// as farther than every point in front), ties in model order.
    fn blended_order(&self, view_proj: glam::Mat4) -> Vec<usize> {
        let key = |origin: glam::Vec3| {
            let d = (view_proj * origin.extend(1.0)).w;
            if d == 0.0 {
                f32::INFINITY
            } else {
                1.0 - 2.0 / d
            }
        };
        let mut order: Vec<(usize, f32)> = self
            .batches
            .iter()
            .enumerate()
            .filter_map(|(i, b)| Some((i, key(b.origin?))))
            .collect();
        order.sort_by(|a, b| b.1.total_cmp(&a.1));
        order.into_iter().map(|(i, _)| i).collect()
    }

    /// The colour format the pipeline was built for (not sRGB: the shader encodes).
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// The size of the targets the next frames are drawn into.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.size = (width.max(1), height.max(1));
    }

    /// The current target size.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    fn depth_view(&mut self) -> wgpu::TextureView {
        let (w, h) = self.size;
        match &self.depth {
            Some((view, dw, dh)) if (*dw, *dh) == (w, h) => view.clone(),
            _ => {
                let texture = crate::util::adapter::render_target(
                    &self.device,
                    "depth",
                    (w, h),
                    DEPTH_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT,
                );
                let view = texture.create_view(&Default::default());
                self.depth = Some((view.clone(), w, h));
                view
            }
        }
    }

    /// Draws one frame from [`Self::camera`] with [`Self::settings`] into
    /// `target` (of [`Self::format`] and [`Self::size`]) and submits it.
    pub fn render(&mut self, target: &wgpu::TextureView) -> wgpu::SubmissionIndex {
        let (w, h) = self.size;
        let s = &self.settings;
        let view = s.view;
        if view == ViewMode::Probes && self.spheres.is_none() {
            if let Some((probes, material)) = self.probes.take() {
                self.spheres = Spheres::upload(&self.device, &probes, material);
            }
        }
        let view_proj = self.camera.view_proj(w as f32 / h as f32);
        let globals = self.globals(view_proj);
        self.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
        let depth = self.depth_view();
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("preview"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        // three.js's default clear colour (WebGLBackground.js).
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(crate::util::adapter::reversed_z_depth(&depth)),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.globals_group, &[]);
            if view == ViewMode::Sdf {
                pass.set_pipeline(&self.pipelines.sdf_view);
                pass.draw(0..3, 0..1);
            } else {
                self.draw_scene(&mut pass, view_proj);
            }
        }
        self.queue.submit([encoder.finish()])
    }

    /// Moves the sdf view's slice plane by `steps` voxels (from a voxel
    /// below the field's box, where it is not seen, to a voxel above it);
    /// nothing without a field.
    pub fn move_slice(&mut self, steps: f32) {
        if let Some((lo, hi, voxel)) = self.field {
            let y = self.settings.sdf_slice.unwrap_or(lo.y - voxel);
            self.settings.sdf_slice = Some((y + steps * voxel).clamp(lo.y - voxel, hi.y + voxel));
        }
    }

    /// The frame's uniforms: camera, display settings, lights, field.
    fn globals(&self, view_proj: glam::Mat4) -> Globals {
        let (w, h) = self.size;
        let s = &self.settings;
        let (lo, hi, voxel) = self
            .field
            .unwrap_or((glam::Vec3::ZERO, glam::Vec3::ONE, 0.0));
        let slice = s.sdf_slice.unwrap_or(lo.y - voxel);
        Globals {
            view_proj: view_proj.to_cols_array_2d(),
            camera_pos: self.camera.eye.extend(1.0).to_array(),
            exposure: 2f32.powf(s.exposure_ev),
            view_mode: s.view as u32,
            bicubic: s.bicubic as u32,
            tone_map: s.tone_map as u32,
            viewport: [w as f32, h as f32],
            light_count: if self.settings.realtime_lights {
                self.lights.len() as u32
            } else {
                0
            },
            _pad: 0.0,
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            sdf_min: lo.extend(voxel).to_array(),
            sdf_max: hi.extend(f32::from(u8::from(s.sdf_shadows))).to_array(),
            sdf_params: [slice, s.dfao_reach, 0.0, 0.0],
            lights: std::array::from_fn(|i| self.lights.get(i).copied().unwrap_or_default()),
        }
    }

    /// The scene's batches (and in the probes view the probe spheres).
    fn draw_scene(&self, pass: &mut wgpu::RenderPass<'_>, view_proj: glam::Mat4) {
        let view = self.settings.view;
        // As three.js: the opaque (and masked) objects, then the
        // blended ones back to front without depth writes, a
        // double-sided one in two passes, back faces first
        // (WebGLRenderer.renderObject).
        if let Some(vertices) = &self.vertices {
            pass.set_vertex_buffer(0, vertices.slice(..));
            for b in self.batches.iter().filter(|b| b.origin.is_none()) {
                let pipeline = &self.pipelines.opaque[self.double_sided[b.material] as usize];
                pass.set_pipeline(pipeline);
                pass.set_bind_group(1, &self.material_groups[b.material], &[]);
                pass.draw(b.vertices.clone(), 0..1);
            }
        }
        if let Some(sp) = self.spheres.as_ref().filter(|_| view == ViewMode::Probes) {
            pass.set_pipeline(&self.pipelines.opaque[0]);
            pass.set_bind_group(1, &self.material_groups[sp.material], &[]);
            pass.set_vertex_buffer(0, sp.vertices.slice(..));
            pass.set_index_buffer(sp.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..sp.count, 0, 0..1);
        }
        if let Some(vertices) = &self.vertices {
            pass.set_vertex_buffer(0, vertices.slice(..));
            for i in self.blended_order(view_proj) {
                let b = &self.batches[i];
                pass.set_bind_group(1, &self.material_groups[b.material], &[]);
                let sides: &[usize] = if self.double_sided[b.material] {
                    &[1, 0]
                } else {
                    &[0]
                };
                for &side in sides {
                    pass.set_pipeline(&self.pipelines.blend[side]);
                    pass.draw(b.vertices.clone(), 0..1);
                }
            }
        }
    }

    /// Renders one frame offscreen at the current size and reads it back as
    /// tightly packed RGBA8 (sRGB-encoded) rows.
    pub fn render_to_image(&mut self) -> anyhow::Result<Vec<u8>> {
        let (w, h) = self.size;
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        self.render(&texture.create_view(&Default::default()));
        read_back(&self.device, &self.queue, &texture)
    }

    /// The device.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }
}

/// Copies `texture` (RGBA8 or BGRA8, sRGB or not) to the CPU as RGBA8 rows.
pub fn read_back(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> anyhow::Result<Vec<u8>> {
    let (w, h) = (texture.width(), texture.height());
    let row = 4 * w;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: padded as u64 * h as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("readback"),
    });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        texture.size(),
    );
    queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow::anyhow!("GPU wait failed: {e}"))?;
    rx.recv()?
        .map_err(|e| anyhow::anyhow!("cannot map the readback buffer: {e}"))?;
    let bgra = matches!(
        texture.format(),
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    );
    let mut out = Vec::with_capacity((row * h) as usize);
    {
        let data = buffer
            .slice(..)
            .get_mapped_range()
            .map_err(|e| anyhow::anyhow!("cannot read the readback buffer: {e}"))?;
        for y in 0..h {
            let start = (y * padded) as usize;
            out.extend_from_slice(&data[start..start + row as usize]);
        }
    }
    buffer.unmap();
    if bgra {
        for px in out.chunks_exact_mut(4) {
            px.swap(0, 2);
        }
    }
    Ok(out)
}

/// The bind group layouts: per frame (globals, and the distance field
/// with its sampler) and per material (its
/// uniform, base colour, emissive, lightmap and debug map with samplers,
/// and the shadowmask, read with the lightmap's sampler).
fn bind_group_layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let uniform = |binding, visibility| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let texture = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    let sampler_entry = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    };
    let globals_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("globals"),
        entries: &[
            uniform(0, wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT),
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D3,
                    multisampled: false,
                },
                count: None,
            },
            sampler_entry(2),
        ],
    });
    let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("material"),
        entries: &[
            uniform(0, wgpu::ShaderStages::FRAGMENT),
            texture(1),
            sampler_entry(2),
            texture(3),
            sampler_entry(4),
            texture(5),
            sampler_entry(6),
            texture(7),
            texture(8),
        ],
    });
    (globals_layout, material_layout)
}

/// The render pipelines: opaque with back faces culled, and not
/// (double-sided); blended (three.js `NormalBlending` without premultiplied
/// alpha: colour SRC_ALPHA, ONE_MINUS_SRC_ALPHA; alpha ONE,
/// ONE_MINUS_SRC_ALPHA; no depth writes) with back or front faces culled.
fn pipelines(
    device: &wgpu::Device,
    globals_layout: &wgpu::BindGroupLayout,
    material_layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> Pipelines {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("preview.wgsl"),
        source: wgpu::ShaderSource::Wgsl(gpu::SHADER.into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("preview"),
        bind_group_layouts: &[Some(globals_layout), Some(material_layout)],
        immediate_size: 0,
    });
    let pipeline = |cull_mode, blend: Option<wgpu::BlendState>| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("preview"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(Vertex::layout())],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(blend.is_none()),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let normal = wgpu::BlendState {
        color: wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::SrcAlpha,
            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
            operation: wgpu::BlendOperation::Add,
        },
        alpha: wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
            operation: wgpu::BlendOperation::Add,
        },
    };
    Pipelines {
        opaque: [pipeline(Some(wgpu::Face::Back), None), pipeline(None, None)],
        blend: [
            pipeline(Some(wgpu::Face::Back), Some(normal)),
            pipeline(Some(wgpu::Face::Front), Some(normal)),
        ],
        sdf_view: sdf_view_pipeline(device, &shader, globals_layout, format),
    }
}

/// The sdf view's pipeline: a full-screen triangle (`vs_fullscreen`,
/// `fs_sdf_view`) reading only the globals group; depth always passes and
/// is not written.
fn sdf_view_pipeline(
    device: &wgpu::Device,
    shader: &wgpu::ShaderModule,
    globals_layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("sdf view"),
        bind_group_layouts: &[Some(globals_layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("sdf view"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: shader,
            entry_point: Some("fs_sdf_view"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The distance field as a filterable `R16Float` 3D texture
/// ([`Field::halves`]); a 1 × 1 × 1 texture of a large distance without
/// one (the shaders then see `sdf_min.w == 0` and do not read it).
fn field_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    field: Option<&Field>,
) -> wgpu::TextureView {
    let (dims, texels) = match field {
        Some(f) => (f.dims, f.halves()),
        None => ([1; 3], vec![half::f16::from_f32(1e4).to_bits()]),
    };
    let texture = device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("distance field"),
            size: wgpu::Extent3d {
                width: dims[0],
                height: dims[1],
                depth_or_array_layers: dims[2],
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format: wgpu::TextureFormat::R16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck::cast_slice(&texels),
    );
    texture.create_view(&Default::default())
}

/// Every texture a material may bind, on the GPU.
struct Textures {
    /// A white texel for "none".
    white: wgpu::TextureView,
    clamp: wgpu::Sampler,
    /// The scene's textures (sRGB base colour / emissive, full mip chains).
    textures: Vec<wgpu::Texture>,
    /// Their views and samplers.
    scene: Vec<(wgpu::TextureView, wgpu::Sampler)>,
    /// The lightmap pages (sRGB PNG, or linear where the model has
    /// [`Model::linear_pages`]).
    lightmaps: Vec<wgpu::TextureView>,
    /// The linear pages' textures (None: an sRGB page).
    linear: Vec<Option<wgpu::Texture>>,
    /// A transparent texel for "no debug map".
    no_debug: wgpu::TextureView,
    /// Debug maps (patches, validity; not colour data) per page.
    debug: Vec<Option<wgpu::TextureView>>,
    /// Shadowmasks (linear visibility) per page; `white` where none.
    shadowmasks: Vec<Option<wgpu::TextureView>>,
    /// An unoccluded (linear white) texel for "no shadowmask".
    no_mask: wgpu::TextureView,
}

impl Textures {
    fn upload(device: &wgpu::Device, queue: &wgpu::Queue, model: &Model) -> Textures {
        // Textures: the scene's (sRGB base colour / emissive), the lightmap
        // pages (sRGB PNG), and a white texel for "none".
        let white = srgb_texture(device, queue, "white", 1, 1, &[255; 4]);
        let clamp = clamp_sampler(device);
        let textures = scene_textures(device, queue, &model.scene.textures);
        let scene: Vec<(wgpu::TextureView, wgpu::Sampler)> = textures
            .iter()
            .zip(&model.scene.textures)
            .map(|(gpu, t)| {
                let view = gpu.create_view(&Default::default());
                (view, texture_sampler(device, t))
            })
            .collect();
        let mut linear_pages = Vec::new();
        let lightmaps: Vec<wgpu::TextureView> = model
            .lightmaps
            .iter()
            .enumerate()
            .map(|(i, l)| match model.linear_pages.get(i) {
                Some(Some(page)) => {
                    let (t, v) = linear_texture(device, queue, &format!("lightmap{i}"), page);
                    linear_pages.push(Some(t));
                    v
                }
                _ => {
                    linear_pages.push(None);
                    srgb_texture(
                        device,
                        queue,
                        &format!("lightmap{i}"),
                        l.width,
                        l.height,
                        &l.rgba,
                    )
                }
            })
            .collect();
        // Debug maps (patches, validity; not colour data), and a
        // transparent texel for "none".
        let no_debug = rgba8_texture(device, queue, "no debug map", (1, 1), &[&[0; 4]], false)
            .create_view(&Default::default());
        let debug: Vec<Option<wgpu::TextureView>> = model
            .debug_maps
            .iter()
            .enumerate()
            .map(|(i, d)| {
                d.as_ref().map(|d| {
                    rgba8_texture(
                        device,
                        queue,
                        &format!("debug{i}"),
                        (d.width, d.height),
                        &[&d.rgba],
                        false,
                    )
                    .create_view(&Default::default())
                })
            })
            .collect();
        let linear = |name: &str, img: &super::model::Image| {
            rgba8_texture(
                device,
                queue,
                name,
                (img.width, img.height),
                &[&img.rgba],
                false,
            )
            .create_view(&Default::default())
        };
        let shadowmasks = model
            .shadowmasks
            .iter()
            .enumerate()
            .map(|(i, m)| m.as_ref().map(|m| linear(&format!("shadowmask{i}"), m)))
            .collect();
        let no_mask = rgba8_texture(device, queue, "no shadowmask", (1, 1), &[&[255; 4]], false)
            .create_view(&Default::default());
        Textures {
            white,
            clamp,
            textures,
            scene,
            lightmaps,
            linear: linear_pages,
            no_debug,
            debug,
            shadowmasks,
            no_mask,
        }
    }
}

/// One bind group per material: its uniform and textures (white, or the
/// transparent texel, where it has none).
fn material_groups(
    device: &wgpu::Device,
    material_layout: &wgpu::BindGroupLayout,
    model: &Model,
    tx: &Textures,
) -> Vec<wgpu::BindGroup> {
    model
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(&format!("material{i}")),
                contents: bytemuck::bytes_of(&m.gpu),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let tex = |t: Option<u32>| {
                t.and_then(|t| tx.scene.get(t as usize))
                    .map_or((&tx.white, &tx.clamp), |(v, s)| (v, s))
            };
            let (base_view, base_sampler) = tex(m.base_texture);
            let (emissive_view, emissive_sampler) = tex(m.emissive_texture);
            let lightmap_view = m
                .lightmap
                .and_then(|p| tx.lightmaps.get(p))
                .unwrap_or(&tx.white);
            let debug_view = m
                .lightmap
                .and_then(|p| tx.debug.get(p))
                .and_then(Option::as_ref)
                .unwrap_or(&tx.no_debug);
            let mask_view = m
                .lightmap
                .and_then(|p| tx.shadowmasks.get(p))
                .and_then(Option::as_ref)
                .unwrap_or(&tx.no_mask);
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&format!("material{i}")),
                layout: material_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(base_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::Sampler(base_sampler),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(emissive_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::Sampler(emissive_sampler),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: wgpu::BindingResource::TextureView(lightmap_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 6,
                        resource: wgpu::BindingResource::Sampler(&tx.clamp),
                    },
                    wgpu::BindGroupEntry {
                        binding: 7,
                        resource: wgpu::BindingResource::TextureView(debug_view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 8,
                        resource: wgpu::BindingResource::TextureView(mask_view),
                    },
                ],
            })
        })
        .collect()
}
