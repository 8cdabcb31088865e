//! Rays cast in large batches: the interface ([`BatchCaster`]) through
//! which the ray-heavy stages reach a caster off the CPU (the GPU of
//! `device = "gpu"`, [`super::gpu`]), and [`CpuBatches`], the same batches
//! cast on the CPU.

use super::{Hit, RayCaster};
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

/// Writes item `i`'s rays (origin, unit direction) into its slice of a
/// batch ([`BatchCaster::cast_batches`]).
pub type Generate<'g> = dyn Fn(usize, &mut [(Vec3, Vec3)]) + Sync + 'g;
/// Receives a batch: its items, their rays (`per_item` each, in item
/// order) and those rays' closest hits.
pub type Consume<'c> = dyn FnMut(Range<usize>, &[(Vec3, Vec3)], &[Option<Hit>]) + 'c;

/// Casts closest-hit rays in large batches: the interface through which the
/// ray-heavy stages (ray-cast form factors, the final gather) reach a caster
/// off the CPU ([`super::gpu::GpuBatches`] with `device = "gpu"`). A stage
/// generates its rays item by item and reads the hits back batch by batch,
/// in item order, so its result does not depend on which caster cast them.
/// [`CpuBatches`] casts the same batches on the CPU.
pub trait BatchCaster: Sync {
    /// The device, for the report's warnings.
    fn describe(&self) -> &str;

    /// Casts the rays of `count` items, `per_item` rays each (`generate`
    /// writes an item's), and hands every batch to `consume`, in order.
    ///
    /// # Errors
    /// The device failed (the stage then casts its rays on the CPU).
    fn cast_batches(
        &self,
        count: usize,
        per_item: usize,
        generate: &Generate,
        consume: &mut Consume,
    ) -> crate::Result<()>;
}

/// [`BatchCaster`] on the CPU's [`RayCaster`], in batches of `batch`
/// items: the reference the GPU's batches are tested against, and a test
/// that a stage's batched path equals its CPU path.
pub struct CpuBatches<'a> {
    /// The caster.
    pub rays: &'a RayCaster,
    /// Items per batch.
    pub batch: usize,
}

impl BatchCaster for CpuBatches<'_> {
    fn describe(&self) -> &str {
        "CPU (batched)"
    }

    fn cast_batches(
        &self,
        count: usize,
        per_item: usize,
        generate: &Generate,
        consume: &mut Consume,
    ) -> crate::Result<()> {
        let per_item = per_item.max(1);
        for items in batch_ranges(count, self.batch) {
            let rays = generate_rays(items.clone(), per_item, generate);
            let hits: Vec<Option<Hit>> = rays
                .par_iter()
                .map(|&(o, d)| self.rays.closest_hit(o, d, f32::INFINITY))
                .collect();
            consume(items, &rays, &hits);
        }
        Ok(())
    }
}

/// `0..count` in consecutive ranges of `per_batch` items (the last one
/// short).
pub fn batch_ranges(count: usize, per_batch: usize) -> Vec<Range<usize>> {
    let per_batch = per_batch.max(1);
    (0..count)
        .step_by(per_batch)
        .map(|a| a..(a + per_batch).min(count))
        .collect()
}

/// The rays of `items`, `per_item` each in item order, generated in
/// parallel.
pub fn generate_rays(
    items: Range<usize>,
    per_item: usize,
    generate: &Generate,
) -> Vec<(Vec3, Vec3)> {
    let mut rays = vec![(Vec3::ZERO, Vec3::ZERO); items.len() * per_item];
    rays.par_chunks_mut(per_item)
        .zip(items)
        .for_each(|(out, i)| generate(i, out));
    rays
}
