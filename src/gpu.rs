//! `--device gpu`: closest-hit ray casting in a wgpu compute shader
//! (`shaders/raycast.wgsl`) over a binary BVH (obvhs PLOC `Bvh2`),
//! "wavefront" style: rays are generated on the CPU by the very sampling
//! code of the CPU path, cast in large batches on the GPU, and their hits
//! turned into patches on the CPU. Form factors use it (the bake's most
//! ray-heavy stage before the final gather); both devices cast the same
//! rays, so their lightmaps agree up to floating-point ties.
//!
//! Cut-out (alpha-masked) triangles are tested on the CPU: a ray whose GPU
//! hit is masked is re-cast there. BVHs deeper than the shader's stack are
//! refused (the caller falls back to the CPU).

use crate::form_factors::raycast::{row_from_hits, row_rays, Surfaces};
use crate::form_factors::{FormFactorStats, FormFactors};
use crate::geometry::Geometry;
use crate::raycast::Hit;
use anyhow::{anyhow, bail, Context as _, Result};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use std::time::Duration;
use wgpu::util::DeviceExt as _;

/// The compute shader.
pub const SHADER: &str = include_str!("../shaders/raycast.wgsl");

/// Traversal stack depth of the shader.
const STACK: usize = 64;
/// Rays per dispatch.
const BATCH: usize = 1 << 20;
/// Invocations per workgroup (the shader's `@workgroup_size`).
const GROUP: u32 = 64;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuNode {
    min: [f32; 3],
    prim_count: u32,
    max: [f32; 3],
    first_index: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuTri {
    v0: [f32; 4],
    e1: [f32; 4],
    e2: [f32; 4],
    n: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuRay {
    origin: [f32; 4],
    dir: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct GpuHit {
    t: f32,
    u: f32,
    v: f32,
    tri: u32,
}

/// A scene's triangles and BVH on the GPU.
pub struct GpuRayCaster {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    nodes: wgpu::Buffer,
    tris: wgpu::Buffer,
    /// BVH order → global triangle id.
    ids: Vec<u32>,
    /// Adapter, for the report.
    pub adapter: String,
}

impl GpuRayCaster {
    /// Builds the BVH over `geometry` and uploads it to the first adapter
    /// (hardware first, a software one otherwise).
    ///
    /// # Errors
    /// No adapter, or a BVH deeper than the shader's stack.
    pub fn new(geometry: &Geometry) -> Result<GpuRayCaster> {
        if geometry.is_empty() {
            bail!("no triangles");
        }
        let (adapter, device, queue) = crate::preview::offscreen_device()?;
        let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(
            &crate::raycast::obvhs_triangles(geometry),
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        // The real depth (`Bvh2::max_depth` is only a stack-size hint).
        let mut depth = 0usize;
        let mut todo = vec![(0u32, 1usize)];
        while let Some((i, d)) = todo.pop() {
            depth = depth.max(d);
            let n = &bvh.nodes[i as usize];
            if n.prim_count == 0 {
                todo.push((n.first_index, d + 1));
                todo.push((n.first_index + 1, d + 1));
            }
        }
        if depth > STACK {
            bail!("BVH depth {depth} exceeds the GPU traversal stack ({STACK})");
        }
        let nodes: Vec<GpuNode> = bvh
            .nodes
            .iter()
            .map(|n| GpuNode {
                min: Vec3::from(n.aabb.min).to_array(),
                prim_count: n.prim_count,
                max: Vec3::from(n.aabb.max).to_array(),
                first_index: n.first_index,
            })
            .collect();
        let ids = bvh.primitive_indices.clone();
        let gpu_tris: Vec<GpuTri> = ids
            .iter()
            .map(|&g| {
                let p = geometry.p_ws[g as usize];
                let e1 = p[0] - p[1];
                let e2 = p[2] - p[0];
                let n = e1.cross(e2);
                let v = |x: Vec3| [x.x, x.y, x.z, 0.0];
                GpuTri {
                    v0: v(p[0]),
                    e1: v(e1),
                    e2: v(e2),
                    n: v(n),
                }
            })
            .collect();
        // Validation errors (a driver without storage buffers, say) are
        // captured and returned, not left to wgpu's panicking handler.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raycast.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raycast"),
            entries: &[
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("raycast"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("raycast"),
            layout: Some(&pipeline_layout),
            module: &shader,
            entry_point: Some("cast_rays"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!("the ray-casting shader does not compile here: {e}");
        }
        let nodes = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh nodes"),
            contents: bytemuck::cast_slice(&nodes),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let tris = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("triangles"),
            contents: bytemuck::cast_slice(&gpu_tris),
            usage: wgpu::BufferUsages::STORAGE,
        });
        Ok(GpuRayCaster {
            adapter: crate::preview::describe(&adapter),
            device,
            queue,
            pipeline,
            layout,
            nodes,
            tris,
            ids,
        })
    }

    /// Closest hits of `rays` (origin, unit direction), `t ∈ [0, tmax]`.
    ///
    /// # Errors
    /// A failed GPU wait or readback.
    pub fn closest_hits(&self, rays: &[(Vec3, Vec3)]) -> Result<Vec<Option<Hit>>> {
        let mut out = Vec::with_capacity(rays.len());
        for batch in rays.chunks(BATCH) {
            out.extend(self.cast_batch(batch)?);
        }
        Ok(out)
    }

    fn cast_batch(&self, rays: &[(Vec3, Vec3)]) -> Result<Vec<Option<Hit>>> {
        let n = rays.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let gpu_rays: Vec<GpuRay> = rays
            .iter()
            .map(|(o, d)| {
                // −0.0 components made +0.0 (1/d then is +inf, as on the CPU).
                let d = *d + Vec3::ZERO;
                GpuRay {
                    origin: [o.x, o.y, o.z, 0.0],
                    dir: [d.x, d.y, d.z, 3.0e38],
                }
            })
            .collect();
        let d = &self.device;
        let ray_buf = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("rays"),
            contents: bytemuck::cast_slice(&gpu_rays),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let size = (n * std::mem::size_of::<GpuHit>()) as u64;
        let hit_buf = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let read_buf = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::cast_slice(&[n as u32, 0, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.nodes.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.tris.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ray_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: hit_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        let groups = (n as u32).div_ceil(GROUP);
        let (gx, gy) = (groups.min(65535), groups.div_ceil(65535));
        let mut encoder = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("raycast"),
        });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("raycast"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        encoder.copy_buffer_to_buffer(&hit_buf, 0, &read_buf, 0, size);
        self.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        read_buf.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        d.poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("GPU wait failed: {e}"))?;
        rx.recv()?
            .map_err(|e| anyhow!("cannot read the hits back: {e}"))?;
        let view = read_buf
            .slice(..)
            .get_mapped_range()
            .map_err(|e| anyhow!("cannot map the hits: {e:?}"))?;
        let hits: &[GpuHit] = bytemuck::cast_slice(&view);
        let out = hits
            .iter()
            .map(|h| {
                (h.tri != u32::MAX).then(|| Hit {
                    tri: self.ids[h.tri as usize],
                    t: h.t,
                    u: h.u,
                    v: h.v,
                })
            })
            .collect();
        drop(view);
        read_buf.unmap();
        Ok(out)
    }
}

/// Form factors by ray casting with the rays cast on the GPU: the rows of
/// [`crate::form_factors::raycast::compute`], rays generated and hits
/// counted on the CPU, patches in batches of about a million rays.
///
/// # Errors
/// GPU failures (the caller falls back to the CPU).
pub fn form_factors(
    s: &Surfaces,
    gpu: &GpuRayCaster,
    rays_per_patch: u32,
    seed: u64,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<FormFactors> {
    let n = s.patches.len();
    let per_batch = (BATCH / rays_per_patch.max(1) as usize).max(1);
    let masked: Vec<bool> = s
        .scene
        .materials
        .iter()
        .map(|m| matches!(m.alpha, crate::scene::Alpha::Mask { .. }))
        .collect();
    let mut rows = Vec::with_capacity(n);
    let mut stats = FormFactorStats::default();
    for start in (0..n).step_by(per_batch) {
        let end = (start + per_batch).min(n);
        let rays: Vec<Vec<(Vec3, Vec3)>> = (start..end)
            .into_par_iter()
            .map(|i| row_rays(s, i, rays_per_patch, seed))
            .collect();
        let flat: Vec<(Vec3, Vec3)> = rays.iter().flatten().copied().collect();
        let hits = gpu.closest_hits(&flat).context("GPU ray casting failed")?;
        let results: Vec<_> = (start..end)
            .into_par_iter()
            .map(|i| {
                let k0 = (i - start) * rays_per_patch as usize;
                let row_hits: Vec<Option<Hit>> = (0..rays_per_patch as usize)
                    .map(|k| {
                        let h = hits[k0 + k];
                        match h {
                            // Cut-outs are tested on the CPU.
                            Some(hit) if masked[s.geometry.material[hit.tri as usize] as usize] => {
                                let (o, d) = flat[k0 + k];
                                s.rays.closest_hit(o, d, f32::INFINITY)
                            }
                            other => other,
                        }
                    })
                    .collect();
                let r = row_from_hits(s, &rays[i - start], &row_hits);
                advance(1);
                r
            })
            .collect();
        for (r, st) in results {
            stats.add(&st);
            rows.push(r);
        }
    }
    Ok(FormFactors::from_rows(n, rows, stats))
}
