//! The wgpu instance, adapter and device, shared by the GPU ray caster
//! ([`crate::raycast::gpu`], feature `gpu`) and the preview (feature
//! `preview`, which brings `gpu`): hardware first, a software adapter
//! (Mesa's lavapipe or llvmpipe) otherwise.

use crate::error::device_error;
use crate::{Error, Result};

/// A wgpu instance for `backends` (overridden by `WGPU_BACKEND` and the
/// other wgpu environment variables), optionally tied to a display
/// connection (needed by GL for windows).
pub fn instance(
    backends: wgpu::Backends,
    display: Option<Box<dyn wgpu::wgt::WgpuHasDisplayHandle>>,
) -> wgpu::Instance {
    let mut desc = match display {
        Some(d) => wgpu::InstanceDescriptor::new_with_display_handle(d),
        None => wgpu::InstanceDescriptor::new_without_display_handle(),
    };
    desc.backends = backends;
    wgpu::Instance::new(desc.with_env())
}

/// An adapter compatible with `surface` (hardware first, any software one
/// otherwise) and its device.
pub fn device(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue)> {
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: surface,
        ..Default::default()
    }))
    .map_err(|e| {
        Error::NoAdapter(format!(
            "{e} (install a GPU driver, or Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1)"
        ))
    })?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("radbake preview"),
        required_limits: adapter.limits(),
        ..Default::default()
    }))
    .map_err(|e| device_error!("cannot create the GPU device: {e}"))?;
    Ok((adapter, device, queue))
}

/// A device for offscreen rendering: Vulkan/Metal/DX12 first, GL only when
/// none of those has an adapter (GL's EGL probing is noisy without a
/// display); `WGPU_BACKEND` overrides.
pub fn offscreen_device() -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue)> {
    let primary = device(&instance(wgpu::Backends::PRIMARY, None), None);
    match primary {
        Err(Error::NoAdapter(_)) if std::env::var_os("WGPU_BACKEND").is_none() => {
            device(&instance(wgpu::Backends::GL, None), None)
        }
        r => r,
    }
}

/// One-line adapter description.
pub fn describe(adapter: &wgpu::Adapter) -> String {
    let info = adapter.get_info();
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

/// A single-sample 2D texture of `size` to render into.
pub fn render_target(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// A reversed-Z depth attachment (Reed 2015): cleared to 0, the far
/// plane, so nearer is greater; not kept after the pass.
pub fn reversed_z_depth(view: &wgpu::TextureView) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations {
            load: wgpu::LoadOp::Clear(0.0),
            store: wgpu::StoreOp::Discard,
        }),
        stencil_ops: None,
    }
}
