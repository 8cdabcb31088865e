//! The caster of a bake's batches of rays for `device = "gpu"`: the GPU
//! ([`GpuBatches`]) where the `gpu` feature is built and an adapter exists.
//! The one place that knows whether the feature is there, so the stages
//! carry no `cfg`.

use super::batch::BatchCaster;
#[cfg(feature = "gpu")]
use super::gpu::GpuBatches;
use super::RayCaster;
use crate::layout::geometry::Geometry;
use crate::scene::Scene;

/// The batch caster of `device = "gpu"` over `geometry` (cut-out hits
/// re-cast on `cpu`).
///
/// # Errors
/// No adapter, a shader the driver refuses, or a build without the `gpu`
/// feature: the caller casts every ray on the CPU.
pub fn gpu_batches<'a>(
    scene: &Scene,
    geometry: &Geometry,
    cpu: &'a RayCaster,
) -> crate::Result<Box<dyn BatchCaster + 'a>> {
    #[cfg(feature = "gpu")]
    return Ok(Box::new(GpuBatches::new(scene, geometry, cpu)?));
    #[cfg(not(feature = "gpu"))]
    {
        let _ = (scene, geometry, cpu);
        crate::error::device_bail!("radbake was built without the `gpu` feature")
    }
}
