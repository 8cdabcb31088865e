//! `--device gpu` (feature `gpu`): closest-hit ray casting in a wgpu
//! compute shader (`shaders/raycast.wgsl`) over a binary BVH (obvhs PLOC
//! `Bvh2`), "wavefront" style: rays are generated on the CPU by the very
//! sampling code of the CPU path, cast in large batches on the GPU, and
//! their hits handed back in order ([`GpuBatches`], a [`BatchCaster`]).
//! Ray-cast form factors and the final gather use it (the bake's most
//! ray-heavy stages); both devices cast the same rays, so their lightmaps
//! agree up to floating-point ties.
//!
//! Cut-out (alpha-masked) triangles are tested on the CPU: a ray whose GPU
//! hit is masked is re-cast there. BVHs deeper than the shader's stack are
//! refused (the caller falls back to the CPU).

use super::batch::{batch_ranges, generate_rays, BatchCaster, Consume, Generate};
use super::{Hit, RayCaster};
use crate::error::{device_bail, device_error};
use crate::layout::geometry::Geometry;
use crate::scene::{Alpha, Scene};
use crate::Result;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use std::ops::Range;
use std::time::Duration;
use wgpu::util::DeviceExt as _;

/// The compute shader.
pub const SHADER: &str = include_str!("../../shaders/raycast.wgsl");

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
        Self::with_casters(geometry, None)
    }

    /// [`GpuRayCaster::new`] over the triangles `casters` only (all with
    /// `None`; see [`super::shadow_casters`]).
    ///
    /// # Errors
    /// As [`GpuRayCaster::new`].
    pub fn with_casters(geometry: &Geometry, casters: Option<&[u32]>) -> Result<GpuRayCaster> {
        if geometry.is_empty() || casters.is_some_and(|c| c.is_empty()) {
            device_bail!("no triangles");
        }
        let (adapter, device, queue) = crate::util::adapter::offscreen_device()?;
        let (nodes, ids) = gpu_bvh(geometry, casters)?;
        let gpu_tris = gpu_triangles(geometry, &ids);
        let (pipeline, layout) = pipeline(&device)?;
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
            adapter: crate::util::adapter::describe(&adapter),
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
        let slot = self.slot(rays.len().min(BATCH));
        let mut out = Vec::with_capacity(rays.len());
        for batch in rays.chunks(BATCH) {
            let gpu_rays: Vec<GpuRay> = batch.iter().map(|&(o, d)| gpu_ray(o, d)).collect();
            let pending = self.submit(&slot, &gpu_rays);
            out.extend(self.wait(&slot, pending)?.iter().map(|h| self.hit(h)));
        }
        Ok(out)
    }

    /// Casts `rays` and times the three steps apart, each waited for on its
    /// own: upload, the kernel, readback (for `tools/gpu_rays.rs`).
    ///
    /// # Errors
    /// A failed GPU wait or readback.
    pub fn timed_cast(&self, rays: &[(Vec3, Vec3)]) -> Result<(Vec<Option<Hit>>, CastTimes)> {
        let n = rays.len().min(BATCH);
        let slot = self.slot(n);
        let gpu_rays: Vec<GpuRay> = rays[..n].iter().map(|&(o, d)| gpu_ray(o, d)).collect();
        let wait = |i| {
            self.device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(i),
                    timeout: None,
                })
                .map_err(|e| device_error!("GPU wait failed: {e}"))
        };
        let t0 = std::time::Instant::now();
        self.queue
            .write_buffer(&slot.rays, 0, bytemuck::cast_slice(&gpu_rays));
        self.queue
            .write_buffer(&slot.params, 0, bytemuck::cast_slice(&[n as u32, 0, 0, 0]));
        wait(self.queue.submit([]))?;
        let upload = t0.elapsed().as_secs_f64();
        let t1 = std::time::Instant::now();
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.encode_dispatch(&mut encoder, &slot, n);
        wait(self.queue.submit([encoder.finish()]))?;
        let kernel = t1.elapsed().as_secs_f64();
        let t2 = std::time::Instant::now();
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let size = (n * std::mem::size_of::<GpuHit>()) as u64;
        encoder.copy_buffer_to_buffer(&slot.hits, 0, &slot.read, 0, size);
        let index = self.queue.submit([encoder.finish()]);
        let hits = self.wait(&slot, Pending { index, n })?;
        let readback = t2.elapsed().as_secs_f64();
        let out = hits.iter().map(|h| self.hit(h)).collect();
        Ok((
            out,
            CastTimes {
                upload,
                kernel,
                readback,
            },
        ))
    }

    /// A GPU hit as the CPU's [`Hit`] (global triangle id).
    fn hit(&self, h: &GpuHit) -> Option<Hit> {
        (h.tri != u32::MAX).then(|| Hit {
            tri: self.ids[h.tri as usize],
            t: h.t,
            u: h.u,
            v: h.v,
        })
    }

    /// Buffers for batches of up to `capacity` rays, reused batch after
    /// batch (two of them let the CPU fill one while the GPU casts the other).
    fn slot(&self, capacity: usize) -> Slot {
        let d = &self.device;
        let capacity = capacity.max(1);
        let buffer = |label, size: usize, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (capacity * size) as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let rays = buffer(
            "rays",
            std::mem::size_of::<GpuRay>(),
            U::STORAGE | U::COPY_DST,
        );
        let hits = buffer(
            "hits",
            std::mem::size_of::<GpuHit>(),
            U::STORAGE | U::COPY_SRC,
        );
        let read = buffer(
            "hits readback",
            std::mem::size_of::<GpuHit>(),
            U::MAP_READ | U::COPY_DST,
        );
        let params = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: 16,
            usage: U::UNIFORM | U::COPY_DST,
            mapped_at_creation: false,
        });
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout: &self.layout,
            entries: &[
                entry(0, &self.nodes),
                entry(1, &self.tris),
                entry(2, &rays),
                entry(3, &hits),
                entry(4, &params),
            ],
        });
        Slot {
            rays,
            hits,
            read,
            params,
            bind,
        }
    }

    /// Records the cast of the first `n` rays of `slot`.
    fn encode_dispatch(&self, encoder: &mut wgpu::CommandEncoder, slot: &Slot, n: usize) {
        let groups = (n as u32).div_ceil(GROUP);
        let (gx, gy) = (groups.min(65535), groups.div_ceil(65535));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("raycast"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &slot.bind, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
    }

    /// Uploads `rays` into `slot` and queues their cast and the copy of the
    /// hits to the readback buffer; returns at once.
    fn submit(&self, slot: &Slot, rays: &[GpuRay]) -> Pending {
        let n = rays.len();
        self.queue
            .write_buffer(&slot.rays, 0, bytemuck::cast_slice(rays));
        self.queue
            .write_buffer(&slot.params, 0, bytemuck::cast_slice(&[n as u32, 0, 0, 0]));
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("raycast"),
            });
        if n > 0 {
            self.encode_dispatch(&mut encoder, slot, n);
            let size = (n * std::mem::size_of::<GpuHit>()) as u64;
            encoder.copy_buffer_to_buffer(&slot.hits, 0, &slot.read, 0, size);
        }
        Pending {
            index: self.queue.submit([encoder.finish()]),
            n,
        }
    }

    /// Waits for `pending` (and only it) and reads its hits back.
    fn wait(&self, slot: &Slot, pending: Pending) -> Result<Vec<GpuHit>> {
        if pending.n == 0 {
            return Ok(Vec::new());
        }
        let size = (pending.n * std::mem::size_of::<GpuHit>()) as u64;
        let (tx, rx) = std::sync::mpsc::channel();
        slot.read
            .slice(..size)
            .map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(pending.index),
                timeout: None,
            })
            .map_err(|e| device_error!("GPU wait failed: {e}"))?;
        rx.recv()
            .map_err(|e| device_error!("GPU read-back: {e}"))?
            .map_err(|e| device_error!("cannot read the hits back: {e}"))?;
        let hits = {
            let view = slot
                .read
                .slice(..size)
                .get_mapped_range()
                .map_err(|e| device_error!("cannot map the hits: {e:?}"))?;
            bytemuck::cast_slice::<u8, GpuHit>(&view).to_vec()
        };
        slot.read.unmap();
        Ok(hits)
    }
}

/// Seconds of one timed batch ([`GpuRayCaster::timed_cast`]).
#[derive(Clone, Copy, Debug)]
pub struct CastTimes {
    /// Rays to the GPU.
    pub upload: f64,
    /// The compute dispatch.
    pub kernel: f64,
    /// Hits back to the CPU.
    pub readback: f64,
}

/// One batch's buffers ([`GpuRayCaster::slot`]).
struct Slot {
    rays: wgpu::Buffer,
    hits: wgpu::Buffer,
    read: wgpu::Buffer,
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
}

/// A submitted batch.
struct Pending {
    index: wgpu::SubmissionIndex,
    n: usize,
}

/// A ray in the shader's layout: `tmin` 0, `tmax` unbounded; −0.0
/// direction components made +0.0 (1/d then is +inf, as on the CPU).
fn gpu_ray(o: Vec3, d: Vec3) -> GpuRay {
    let d = d + Vec3::ZERO;
    GpuRay {
        origin: [o.x, o.y, o.z, 0.0],
        dir: [d.x, d.y, d.z, 3.0e38],
    }
}

/// The GPU caster of a bake: [`GpuRayCaster`] with the CPU's caster for
/// the hits it cannot judge (cut-out triangles), as a [`BatchCaster`].
pub struct GpuBatches<'a> {
    gpu: GpuRayCaster,
    cpu: &'a RayCaster,
    /// Per global triangle: alpha-masked (its GPU hits are re-cast on the CPU)?
    masked: Vec<bool>,
}

impl<'a> GpuBatches<'a> {
    /// The GPU caster over `geometry`, re-casting on `cpu` the hits on
    /// `scene`'s alpha-masked triangles.
    ///
    /// # Errors
    /// As [`GpuRayCaster::new`].
    pub fn new(scene: &Scene, geometry: &Geometry, cpu: &'a RayCaster) -> Result<Self> {
        let gpu = GpuRayCaster::with_casters(geometry, cpu.casters())?;
        let masked = geometry
            .material
            .iter()
            .map(|&m| matches!(scene.materials[m as usize].alpha, Alpha::Mask { .. }))
            .collect();
        Ok(GpuBatches { gpu, cpu, masked })
    }

    /// A GPU hit, re-cast on the CPU where it landed on a cut-out
    /// (alpha-masked) triangle, whose texture the shader does not test.
    fn resolve(&self, h: &GpuHit, (o, d): (Vec3, Vec3)) -> Option<Hit> {
        match self.gpu.hit(h) {
            Some(hit) if self.masked[hit.tri as usize] => self.cpu.closest_hit(o, d, f32::INFINITY),
            other => other,
        }
    }

    /// A batch's rays, generated on the CPU, in the shader's layout.
    fn generate(&self, items: Range<usize>, per_item: usize, generate: &Generate) -> Batch {
        let rays = generate_rays(items.clone(), per_item, generate);
        let flat = rays.par_iter().map(|&(o, d)| gpu_ray(o, d)).collect();
        Batch { items, rays, flat }
    }
}

/// One batch of [`BatchCaster::cast_batches`] on its way to the GPU.
struct Batch {
    items: Range<usize>,
    rays: Vec<(Vec3, Vec3)>,
    flat: Vec<GpuRay>,
}

impl BatchCaster for GpuBatches<'_> {
    fn describe(&self) -> &str {
        &self.gpu.adapter
    }

    /// In batches of about 2²⁰ rays, pipelined over two buffer slots: while
    /// the GPU casts batch k, the CPU generates batch k + 1 and, once that
    /// is submitted, hands batch k's hits to `consume`. Batches are
    /// consumed in order, so results do not depend on the timing.
    fn cast_batches(
        &self,
        count: usize,
        per_item: usize,
        generate: &Generate,
        consume: &mut Consume,
    ) -> Result<()> {
        let per_item = per_item.max(1);
        let per_batch = (BATCH / per_item).max(1);
        let batches = batch_ranges(count, per_batch);
        let Some(first) = batches.first() else {
            return Ok(());
        };
        let capacity = per_batch.min(count) * per_item;
        let slots = [self.gpu.slot(capacity), self.gpu.slot(capacity)];
        let mut batch = self.generate(first.clone(), per_item, generate);
        let mut pending = Some(self.gpu.submit(&slots[0], &batch.flat));
        for b in 0..batches.len() {
            let next = batches
                .get(b + 1)
                .map(|r| self.generate(r.clone(), per_item, generate));
            let this = pending
                .take()
                .ok_or_else(|| device_error!("batch {b} was not submitted"))?;
            let hits = self
                .gpu
                .wait(&slots[b % 2], this)
                .map_err(|e| device_error!("GPU ray casting failed: {e}"))?;
            if let Some(n) = &next {
                pending = Some(self.gpu.submit(&slots[(b + 1) % 2], &n.flat));
            }
            let hits: Vec<Option<Hit>> = hits
                .par_iter()
                .zip(&batch.rays)
                .map(|(h, &ray)| self.resolve(h, ray))
                .collect();
            consume(batch.items.clone(), &batch.rays, &hits);
            match next {
                Some(n) => batch = n,
                None => break,
            }
        }
        Ok(())
    }
}

/// radbake's BVH (obvhs, over `casters` or every triangle) as the
/// shader's flat node array, and each leaf slot's world triangle.
///
/// # Errors
/// A BVH deeper than the shader's traversal stack.
fn gpu_bvh(geometry: &Geometry, casters: Option<&[u32]>) -> Result<(Vec<GpuNode>, Vec<u32>)> {
    let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(
        &super::obvhs_triangles(geometry, casters),
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
        device_bail!("BVH depth {depth} exceeds the GPU traversal stack ({STACK})");
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
    let ids: Vec<u32> = match casters {
        Some(c) => bvh
            .primitive_indices
            .iter()
            .map(|&i| c[i as usize])
            .collect(),
        None => bvh.primitive_indices.clone(),
    };
    Ok((nodes, ids))
}

/// The triangles in the BVH's leaf order, as the shader's Möller–Trumbore
/// test reads them (a vertex, two edges, the normal).
fn gpu_triangles(geometry: &Geometry, ids: &[u32]) -> Vec<GpuTri> {
    ids.iter()
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
        .collect()
}

/// The ray-casting compute pipeline and its bind group layout: nodes,
/// triangles, rays (read), hits (written), the uniform ray count.
///
/// # Errors
/// A shader or pipeline the driver rejects (validation errors captured).
fn pipeline(device: &wgpu::Device) -> Result<(wgpu::ComputePipeline, wgpu::BindGroupLayout)> {
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
        device_bail!("the ray-casting shader does not compile here: {e}");
    }
    Ok((pipeline, layout))
}
