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
use crate::gather::{Gathered, Gatherer};
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
    /// own: upload, the kernel, readback (for `examples/gpu_rays.rs`).
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
                .map_err(|e| anyhow!("GPU wait failed: {e}"))
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
            .map_err(|e| anyhow!("GPU wait failed: {e}"))?;
        rx.recv()?
            .map_err(|e| anyhow!("cannot read the hits back: {e}"))?;
        let hits = {
            let view = slot
                .read
                .slice(..size)
                .get_mapped_range()
                .map_err(|e| anyhow!("cannot map the hits: {e:?}"))?;
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

/// Casts the rays of `count` items (patches, texels), `per_item` rays each,
/// in batches of about 2²⁰ rays, pipelined over two buffer slots: while the
/// GPU casts batch k, the CPU generates batch k + 1 (`generate`: the
/// batch's rays in the shader's layout, `per_item` per item in item order,
/// and whatever else `consume` needs) and, once that is submitted, hands
/// batch k's hits to `consume`. Batches are consumed in order, so results
/// do not depend on the timing.
fn pipelined<T>(
    gpu: &GpuRayCaster,
    count: usize,
    per_item: usize,
    generate: impl Fn(std::ops::Range<usize>) -> (T, Vec<GpuRay>),
    mut consume: impl FnMut(std::ops::Range<usize>, T, &[GpuHit]),
) -> Result<()> {
    let per_item = per_item.max(1);
    let per_batch = (BATCH / per_item).max(1);
    let batches: Vec<std::ops::Range<usize>> = (0..count)
        .step_by(per_batch)
        .map(|a| a..(a + per_batch).min(count))
        .collect();
    let Some(first) = batches.first() else {
        return Ok(());
    };
    let capacity = per_batch.min(count) * per_item;
    let slots = [gpu.slot(capacity), gpu.slot(capacity)];
    let (mut data, flat) = generate(first.clone());
    let mut pending = Some(gpu.submit(&slots[0], &flat));
    for (b, range) in batches.iter().enumerate() {
        let next = batches.get(b + 1).map(|r| generate(r.clone()));
        let this = pending
            .take()
            .ok_or_else(|| anyhow!("batch {b} was not submitted"))?;
        let hits = gpu
            .wait(&slots[b % 2], this)
            .context("GPU ray casting failed")?;
        let mut next_data = None;
        if let Some((d, next_flat)) = next {
            pending = Some(gpu.submit(&slots[(b + 1) % 2], &next_flat));
            next_data = Some(d);
        }
        consume(range.clone(), data, &hits);
        match next_data {
            Some(d) => data = d,
            None => break,
        }
    }
    Ok(())
}

/// A GPU hit, re-cast on the CPU where it landed on a cut-out (alpha-masked)
/// triangle, whose texture the shader does not test.
fn resolve_hit(
    s: &Surfaces,
    gpu: &GpuRayCaster,
    masked: &[bool],
    h: &GpuHit,
    o: Vec3,
    d: Vec3,
) -> Option<Hit> {
    match gpu.hit(h) {
        Some(hit) if masked[s.geometry.material[hit.tri as usize] as usize] => {
            s.rays.closest_hit(o, d, f32::INFINITY)
        }
        other => other,
    }
}

/// Per material: alpha-masked?
fn masked_materials(s: &Surfaces) -> Vec<bool> {
    s.scene
        .materials
        .iter()
        .map(|m| matches!(m.alpha, crate::scene::Alpha::Mask { .. }))
        .collect()
}

/// Form factors by ray casting with the rays cast on the GPU: the rows of
/// [`crate::form_factors::raycast::compute`], rays generated and hits
/// counted on the CPU, [`pipelined`].
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
    let rpp = rays_per_patch.max(1) as usize;
    let masked = masked_materials(s);
    let mut rows = Vec::with_capacity(n);
    let mut stats = FormFactorStats::default();
    pipelined(
        gpu,
        n,
        rpp,
        |range| {
            let rays: Vec<Vec<(Vec3, Vec3)>> = range
                .into_par_iter()
                .map(|i| row_rays(s, i, rays_per_patch, seed))
                .collect();
            let mut flat = vec![GpuRay::zeroed(); rays.len() * rpp];
            flat.par_chunks_mut(rpp).zip(&rays).for_each(|(out, row)| {
                for (g, &(o, d)) in out.iter_mut().zip(row) {
                    *g = gpu_ray(o, d);
                }
            });
            (rays, flat)
        },
        |range, rays, hits| {
            let results: Vec<_> = range
                .clone()
                .into_par_iter()
                .map(|i| {
                    let k0 = (i - range.start) * rpp;
                    let row = &rays[i - range.start];
                    let row_hits: Vec<Option<Hit>> = hits[k0..k0 + rpp]
                        .iter()
                        .zip(row)
                        .map(|(h, &(o, d))| resolve_hit(s, gpu, &masked, h, o, d))
                        .collect();
                    let r = row_from_hits(s, row, &row_hits);
                    advance(1);
                    r
                })
                .collect();
            for (r, st) in results {
                stats.add(&st);
                rows.push(r);
            }
        },
    )?;
    Ok(FormFactors::from_rows(n, rows, stats))
}

/// The final gather ([`crate::gather::gather`]) with its rays cast on the
/// GPU, [`pipelined`]: every ray a texel may cast is cast (the CPU stops
/// early on texels found invalid), then each texel's gather runs on the CPU
/// over those hits, in the same order, so the result is the CPU's.
///
/// # Errors
/// GPU failures (the caller falls back to the CPU).
pub(crate) fn gather(
    gatherer: &Gatherer,
    gpu: &GpuRayCaster,
    advance: &(dyn Fn(u64) + Sync),
) -> Result<Gathered> {
    let s = gatherer.s;
    let n = s.texels.len();
    let per = gatherer.rays.max(1) as usize;
    let masked = masked_materials(s);
    let mut texels = Vec::with_capacity(n);
    pipelined(
        gpu,
        n,
        per,
        |range| {
            let mut flat = vec![GpuRay::zeroed(); range.len() * per];
            flat.par_chunks_mut(per).zip(range).for_each_init(
                || vec![(Vec3::ZERO, Vec3::ZERO); per],
                |rays, (out, t)| {
                    gatherer.rays_of(t, rays);
                    for (g, &(o, d)) in out.iter_mut().zip(rays.iter()) {
                        *g = gpu_ray(o, d);
                    }
                },
            );
            ((), flat)
        },
        |range, (), hits| {
            let start = range.start;
            let done: Vec<_> = range
                .into_par_iter()
                .with_min_len(64)
                .map(|t| {
                    let k0 = (t - start) * per;
                    gatherer.texel(t, |k, o, d| {
                        resolve_hit(s, gpu, &masked, &hits[k0 + k as usize], o, d)
                    })
                })
                .collect();
            advance(done.len() as u64);
            texels.extend(done);
        },
    )?;
    Ok(gatherer.assemble(texels))
}
