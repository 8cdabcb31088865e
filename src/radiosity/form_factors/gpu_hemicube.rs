//! `--device gpu --form-factors hemicube` (feature `gpu`): hemicubes
//! rasterised by the GPU's ordinary rasteriser, as lightmapper.h renders
//! them (`shaders/hemicube.wgsl`). A batch of hemicubes is laid out in one
//! atlas of render targets, each in a 3N × N cell (the N × N top face, and
//! the four N × N/2 half side faces two by two); every face is one draw of
//! every triangle with its own viewport. The targets are an item buffer
//! (triangle id + 1, 0 where nothing is seen) and the perspective-correct
//! barycentric weights at the pixel centre, behind a reversed, unbounded
//! depth test. They are read back and handed to the CPU hemicube's own
//! [`Resolve`], which lands each pixel on its texel's patch and adds the
//! pixel's delta form factor: so the GPU's rows are the CPU's rows wherever
//! the two rasterisers cover the same pixels with the same triangle.

use super::hemicube::{cameras, Cameras, Hemicube, Pixel, Resolve, RowBatches, Rows, Setup, EMPTY};
use super::FormFactorStats;
use crate::error::{device_bail, device_error};
use crate::layout::geometry::Geometry;
use crate::surface::Surfaces;
use crate::Result;
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use std::sync::Mutex;
use wgpu::util::DeviceExt as _;

/// The render pipeline's shader.
pub const SHADER: &str = include_str!("../../../shaders/hemicube.wgsl");

/// Largest side of the atlas of render targets, in pixels.
const ATLAS: u32 = 2048;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuFace {
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
    eye: [f32; 4],
}

/// The atlas's targets and the buffers that read them back.
struct Targets {
    item: wgpu::Texture,
    bary: wgpu::Texture,
    depth: wgpu::TextureView,
    item_read: wgpu::Buffer,
    bary_read: wgpu::Buffer,
    faces: wgpu::Buffer,
    bind: wgpu::BindGroup,
}

/// Hemicubes on the GPU for one scene and resolution.
pub struct GpuHemicubes {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::RenderPipeline,
    n: u32,
    /// Hemicube cells per atlas row and column.
    cols: u32,
    rows: u32,
    /// Atlas size (width padded for the read-back's 256-byte rows).
    width: u32,
    vertices: u32,
    targets: Mutex<Targets>,
    adapter: String,
}

impl GpuHemicubes {
    /// Uploads `geometry`'s triangles and builds the pipeline and the
    /// atlas for hemicubes of top-face resolution `n` (even).
    ///
    /// # Errors
    /// No adapter, a driver that refuses the pipeline (storage buffers in
    /// the vertex stage, say), or a resolution the atlas cannot hold.
    pub fn new(geometry: &Geometry, n: u32) -> Result<GpuHemicubes> {
        if geometry.is_empty() {
            device_bail!("no triangles");
        }
        let n = Hemicube::new(n.min(ATLAS)).n;
        if 3 * n > ATLAS {
            device_bail!(
                "hemicube resolution {n} is above the GPU atlas's {}",
                ATLAS / 3
            );
        }
        let (adapter, device, queue) = crate::util::adapter::offscreen_device()?;
        let (cols, rows) = (ATLAS / (3 * n), ATLAS / n);
        let width = (cols * 3 * n).div_ceil(64) * 64;
        let height = rows * n;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipeline = pipeline(&device);
        let corners: Vec<[f32; 4]> = (geometry.p_ws.iter())
            .flat_map(|t| t.map(|p| [p.x, p.y, p.z, 1.0]))
            .collect();
        let corners = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hemicube corners"),
            contents: bytemuck::cast_slice(&corners),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let targets = targets(&device, &pipeline, &corners, width, height, 5 * cols * rows);
        if let Some(e) = pollster::block_on(scope.pop()) {
            device_bail!("the hemicube pipeline does not build here: {e}");
        }
        Ok(GpuHemicubes {
            device,
            queue,
            pipeline,
            n,
            cols,
            rows,
            width,
            vertices: 3 * geometry.len() as u32,
            targets: Mutex::new(targets),
            adapter: crate::util::adapter::describe(&adapter),
        })
    }

    /// Slot k's face f: its viewport (x, y, width, height) in the atlas.
    fn viewport(&self, k: u32, f: u32) -> [u32; 4] {
        let (n, h) = (self.n, self.n / 2);
        let (x0, y0) = ((k % self.cols) * 3 * n, (k / self.cols) * n);
        match f {
            0 => [x0, y0, n, n],
            _ => [x0 + n + ((f - 1) / 2) * n, y0 + ((f - 1) % 2) * h, n, h],
        }
    }

    /// Renders one atlas of hemicubes, the five faces of each of `cams`
    /// (`None`: a slot left empty), and reads its two targets back: each
    /// pixel's item and barycentrics.
    fn render(&self, cams: &[Option<Cameras>]) -> Result<(Vec<u32>, Vec<[f32; 2]>)> {
        let t = self
            .targets
            .lock()
            .map_err(|_| device_error!("GPU hemicube lock"))?;
        self.upload_faces(&t, cams);
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.draw_faces(&t, &mut encoder, cams);
        // Only the atlas rows this batch used are read back.
        let used = (cams.len() as u32).div_ceil(self.cols) * self.n;
        let size = wgpu::Extent3d {
            width: self.width,
            height: used,
            depth_or_array_layers: 1,
        };
        for (texture, buffer, bytes) in [(&t.item, &t.item_read, 4), (&t.bary, &t.bary_read, 8)] {
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.width * bytes),
                        rows_per_image: Some(used),
                    },
                },
                size,
            );
        }
        let index = self.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            device_bail!("GPU hemicubes: {e}");
        }
        self.read_back(&t, index, used)
    }

    /// Each camera's five face frames into `t.faces` (zeros for `None`).
    fn upload_faces(&self, t: &Targets, cams: &[Option<Cameras>]) {
        let v = |x: glam::Vec3, w: f32| [x.x, x.y, x.z, w];
        let mut faces = vec![GpuFace::zeroed(); 5 * cams.len()];
        for (k, c) in cams.iter().enumerate() {
            let Some(c) = c else { continue };
            for (f, face) in c.faces.iter().enumerate() {
                faces[5 * k + f] = GpuFace {
                    right: v(face.right, if face.side { 1.0 } else { 0.0 }),
                    up: v(face.up, 0.0),
                    forward: v(face.forward, 0.0),
                    eye: v(c.eye, 1.0),
                };
            }
        }
        self.queue
            .write_buffer(&t.faces, 0, bytemuck::cast_slice(&faces));
    }

    /// One render pass: every face of every camera in its viewport of the
    /// atlas, depth-tested (reversed Z, cleared to 0).
    fn draw_faces(
        &self,
        t: &Targets,
        encoder: &mut wgpu::CommandEncoder,
        cams: &[Option<Cameras>],
    ) {
        let item = t.item.create_view(&Default::default());
        let bary = t.bary.create_view(&Default::default());
        let color = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("hemicubes"),
            color_attachments: &[color(&item), color(&bary)],
            depth_stencil_attachment: Some(crate::util::adapter::reversed_z_depth(&t.depth)),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &t.bind, &[]);
        for (k, c) in cams.iter().enumerate() {
            if c.is_none() {
                continue;
            }
            for f in 0..5u32 {
                let [x, y, w, h] = self.viewport(k as u32, f);
                pass.set_viewport(x as f32, y as f32, w as f32, h as f32, 0.0, 1.0);
                pass.set_scissor_rect(x, y, w, h);
                let face = 5 * k as u32 + f;
                pass.draw(0..self.vertices, face..face + 1);
            }
        }
    }

    /// Waits for submission `index` and reads the first `used` atlas rows
    /// of items and barycentrics back.
    fn read_back(
        &self,
        t: &Targets,
        index: wgpu::SubmissionIndex,
        used: u32,
    ) -> Result<(Vec<u32>, Vec<[f32; 2]>)> {
        let (tx, rx) = std::sync::mpsc::channel();
        let bytes = |b: u32| (self.width * used * b) as u64;
        for (buffer, b) in [(&t.item_read, 4), (&t.bary_read, 8)] {
            let tx = tx.clone();
            buffer
                .slice(..bytes(b))
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
        }
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })
            .map_err(|e| device_error!("GPU wait failed: {e}"))?;
        for _ in 0..2 {
            rx.recv()
                .map_err(|e| device_error!("GPU read-back: {e}"))?
                .map_err(|e| device_error!("cannot read the hemicubes back: {e}"))?;
        }
        let read = |b: &wgpu::Buffer, size: u64| -> Result<Vec<u8>> {
            let view = (b.slice(..size).get_mapped_range())
                .map_err(|e| device_error!("cannot map the hemicubes: {e:?}"))?;
            Ok(view.to_vec())
        };
        let (items, barys) = (read(&t.item_read, bytes(4))?, read(&t.bary_read, bytes(8))?);
        t.item_read.unmap();
        t.bary_read.unmap();
        Ok((
            bytemuck::pod_collect_to_vec(&items),
            bytemuck::pod_collect_to_vec(&barys),
        ))
    }

    /// Slot k's face f as the CPU rasteriser would leave it: rows along
    /// `up` from the face's lower edge (the atlas's rows run downwards).
    fn face_pixels(&self, items: &[u32], barys: &[[f32; 2]], k: u32, f: u32, buf: &mut [Pixel]) {
        let [x, y, w, h] = self.viewport(k, f);
        for r in 0..h {
            let fb = ((y + h - 1 - r) * self.width + x) as usize;
            for c in 0..w as usize {
                let item = items[fb + c];
                buf[(r * w) as usize + c] = if item == 0 {
                    EMPTY
                } else {
                    Pixel {
                        depth: 0.0,
                        tri: item - 1,
                        u: barys[fb + c][0],
                        v: barys[fb + c][1],
                    }
                };
            }
        }
    }
}

impl RowBatches for GpuHemicubes {
    fn rows(&self, s: &Surfaces, setup: &Setup, patches: &[usize]) -> Result<Rows> {
        if setup.cube.n != self.n {
            device_bail!(
                "GPU hemicubes were built for {} pixels, asked for {}",
                self.n,
                setup.cube.n
            );
        }
        let mut out = Vec::with_capacity(patches.len());
        for chunk in patches.chunks((self.cols * self.rows) as usize) {
            let cams: Vec<Option<Cameras>> = chunk.iter().map(|&i| cameras(s, i)).collect();
            let (items, barys) = self.render(&cams)?;
            let n = self.n;
            let rows: Vec<_> = (cams.par_iter().enumerate())
                .map(|(k, c)| {
                    let Some(c) = c else {
                        return (Vec::new(), FormFactorStats::default());
                    };
                    let mut resolve = Resolve::new(s, setup, c.eye);
                    let mut buf = vec![EMPTY; (n * n) as usize];
                    for (f, face) in c.faces.iter().enumerate() {
                        let pixels = (n * if face.side { n / 2 } else { n }) as usize;
                        self.face_pixels(&items, &barys, k as u32, f as u32, &mut buf[..pixels]);
                        resolve.face(face, &buf[..pixels]);
                    }
                    resolve.finish()
                })
                .collect();
            out.extend(rows);
        }
        Ok(out)
    }

    fn describe(&self) -> String {
        format!(
            "{}, {} hemicubes of {}² per pass",
            self.adapter,
            self.cols * self.rows,
            self.n
        )
    }
}

fn pipeline(device: &wgpu::Device) -> wgpu::RenderPipeline {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("hemicube.wgsl"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let target = |format| {
        Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("hemicube"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &shader,
            entry_point: Some("vs_face"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &shader,
            entry_point: Some("fs_item"),
            compilation_options: Default::default(),
            targets: &[
                target(wgpu::TextureFormat::R32Uint),
                target(wgpu::TextureFormat::Rg32Float),
            ],
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn targets(
    device: &wgpu::Device,
    pipeline: &wgpu::RenderPipeline,
    corners: &wgpu::Buffer,
    width: u32,
    height: u32,
    faces: u32,
) -> Targets {
    let texture = |format, usage| {
        crate::util::adapter::render_target(
            device,
            "hemicube atlas",
            (width, height),
            format,
            usage,
        )
    };
    let color = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
    let read = |bytes: u32| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hemicube read-back"),
            size: (width * height * bytes) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let faces = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("hemicube faces"),
        size: (faces as usize * std::mem::size_of::<GpuFace>()) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("hemicube"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: faces.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: corners.as_entire_binding(),
            },
        ],
    });
    let depth = texture(
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    Targets {
        item: texture(wgpu::TextureFormat::R32Uint, color),
        bary: texture(wgpu::TextureFormat::Rg32Float, color),
        depth: depth.create_view(&Default::default()),
        item_read: read(4),
        bary_read: read(8),
        faces,
        bind,
    }
}
