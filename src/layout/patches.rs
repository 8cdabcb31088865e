//! Patches: texels grouped into k×k blocks of the atlas, never
//! across two charts (hence never across two instances or materials, since
//! charts never span materials). Each patch carries the area-weighted
//! centroid, normal, albedo and emission of its texels and their total area,
//! the quantities of the discrete radiosity equation (Goral et al. 1984).

use crate::layout::burial::Burial;
use crate::layout::texels::Texels;
use glam::Vec3;
use std::collections::HashMap;

/// A patch index.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct PatchId(pub u32);

/// Key of a block: (instance, region, block x, block y); a region lies in
/// one chart ([`crate::layout::burial::Burial::region`]).
pub type BlockKey = (u32, u32, u32, u32);

/// The patches (struct of arrays, indexed by [`PatchId`]).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Patches {
    /// Block size in texels (k).
    pub block: u32,
    /// Area-weighted centroid (world).
    pub p_ws: Vec<Vec3>,
    /// Exposed area Σ area × [`Burial::exposed`] over the valid texels:
    /// the area that receives and sheds light (`area` less what lies
    /// inside or under geometry).
    pub exposed_area: Vec<f32>,
    /// Area-weighted unit normal (world).
    pub n_ws: Vec<Vec3>,
    /// Area Aᵢ (m²).
    pub area: Vec<f32>,
    /// Area-weighted albedo ρᵢ.
    pub albedo: Vec<Vec3>,
    /// Area-weighted emitted radiance Eᵢ.
    pub emission: Vec<Vec3>,
    /// Block key of each patch.
    pub key: Vec<BlockKey>,
    /// Texels of patch i: `texels[texel_start[i]..texel_start[i + 1]]`.
    pub texel_start: Vec<u32>,
    /// Texel ids grouped by patch.
    pub texels: Vec<u32>,
    /// Patch of each texel.
    pub of_texel: Vec<PatchId>,
    /// Block key to patch.
    pub by_key: HashMap<BlockKey, PatchId>,
}

impl Patches {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.area.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.area.is_empty()
    }

    /// Texel ids of patch `i`.
    pub fn texels_of(&self, i: usize) -> &[u32] {
        &self.texels[self.texel_start[i] as usize..self.texel_start[i + 1] as usize]
    }

    /// Patch i's texels as a share of a whole k × k block's, at most 1:
    /// 1 for a whole block or a larger patch (a sliver merged into it),
    /// less for a block cut by a chart's border or a piece of one that
    /// burial planes split.
    pub fn block_share(&self, i: usize) -> f32 {
        let whole = (self.block * self.block).max(1) as f32;
        (self.texels_of(i).len() as f32 / whole).min(1.0)
    }
}

/// Groups `texels` into `k × k` blocks per chart. A block covering less
/// than half a full block (`full_texel_area[instance]` is a whole texel's
/// world area on that instance)
/// joins its largest full neighbour in the same chart, so no patch is a
/// sliver: slivers make noisy shooting targets and put a hemicube's eye on
/// the very edge of a face.
///
/// Blocks are per region ([`Burial::region`]):
/// a block that a wall cuts in two is two patches.
pub fn build(texels: &Texels, burial: &Burial, k: u32, full_texel_area: &[f32]) -> Patches {
    let k = k.max(1);
    let region = |t: usize| burial.region(texels, t);
    let block_of = |t: usize| {
        let [x, y] = texels.xy[t];
        (texels.instance[t], region(t), x / k, y / k)
    };
    // Block areas, in order of first appearance.
    let mut block_area: HashMap<BlockKey, f32> = HashMap::new();
    let mut order: Vec<BlockKey> = Vec::new();
    for t in 0..texels.len() {
        let key = block_of(t);
        let a = block_area.entry(key).or_insert_with(|| {
            order.push(key);
            0.0
        });
        *a += texels.area[t];
    }
    let threshold = |inst: u32| 0.5 * (k * k) as f32 * full_texel_area[inst as usize];
    let mut target: HashMap<BlockKey, BlockKey> = HashMap::new();
    for &key in &order {
        let (inst, chart, bx, by) = key;
        let threshold = threshold(inst);
        if block_area[&key] >= threshold {
            continue;
        }
        let mut best: Option<(f32, BlockKey)> = None;
        for (dx, dy) in [
            (-1i64, 0i64),
            (1, 0),
            (0, -1),
            (0, 1),
            (-1, -1),
            (1, -1),
            (-1, 1),
            (1, 1),
        ] {
            let (nx, ny) = (bx as i64 + dx, by as i64 + dy);
            if nx < 0 || ny < 0 {
                continue;
            }
            let nk = (inst, chart, nx as u32, ny as u32);
            if let Some(&a) = block_area.get(&nk) {
                if a >= threshold && best.is_none_or(|(ba, _)| a > ba) {
                    best = Some((a, nk));
                }
            }
        }
        if let Some((_, nk)) = best {
            target.insert(key, nk);
        }
    }
    let mut by_key: HashMap<BlockKey, PatchId> = HashMap::new();
    let mut keys: Vec<BlockKey> = Vec::new();
    let mut of_texel = Vec::with_capacity(texels.len());
    for t in 0..texels.len() {
        let block = block_of(t);
        let key = target.get(&block).copied().unwrap_or(block);
        let id = *by_key.entry(key).or_insert_with(|| {
            keys.push(key);
            PatchId(keys.len() as u32 - 1)
        });
        by_key.insert(block, id);
        of_texel.push(id);
    }
    let n = keys.len();
    // Counting sort of texels by patch (stable: texel order within a patch).
    let mut texel_start = vec![0u32; n + 1];
    for p in &of_texel {
        texel_start[p.0 as usize + 1] += 1;
    }
    for i in 0..n {
        texel_start[i + 1] += texel_start[i];
    }
    let mut fill = texel_start.clone();
    let mut grouped = vec![0u32; texels.len()];
    for (t, p) in of_texel.iter().enumerate() {
        grouped[fill[p.0 as usize] as usize] = t as u32;
        fill[p.0 as usize] += 1;
    }
    let mut patches = Patches {
        block: k,
        p_ws: Vec::with_capacity(n),
        exposed_area: Vec::with_capacity(n),
        n_ws: Vec::with_capacity(n),
        area: Vec::with_capacity(n),
        albedo: Vec::with_capacity(n),
        emission: Vec::with_capacity(n),
        key: keys,
        texel_start,
        texels: grouped,
        of_texel,
        by_key,
    };
    for i in 0..n {
        let (mut a, mut p, mut nrm, mut rho, mut e) =
            (0.0f32, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        let mut exposed = 0.0f32;
        for &t in patches.texels_of(i) {
            let t = t as usize;
            let w = texels.area[t];
            exposed += w * burial.exposed(t);
            a += w;
            p += texels.p_ws[t] * w;
            nrm += texels.n_ws[t] * w;
            rho += texels.albedo[t] * w;
            e += texels.emission[t] * w;
        }
        patches.area.push(a);
        patches.exposed_area.push(exposed);
        patches.p_ws.push(p / a);
        patches.n_ws.push(nrm.normalize_or(Vec3::Y));
        patches.albedo.push(rho / a);
        patches.emission.push(e / a);
    }
    patches
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A whole block and a larger patch have a share of 1; a partial
    /// block or a piece of a split one its texels over k².
    #[test]
    fn patches_share_by_texels() {
        let p = Patches {
            block: 4,
            texel_start: vec![0, 16, 36, 46, 49],
            texels: (0..49).collect(),
            ..Default::default()
        };
        let shares: Vec<f32> = (0..4).map(|i| p.block_share(i)).collect();
        assert_eq!(shares, vec![1.0, 1.0, 0.625, 0.1875]);
    }

    #[test]
    fn blocks_split_by_chart_and_size() {
        let mut t = Texels::default();
        for (x, y, chart) in [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 1, 0), (1, 1, 1)] {
            t.page.push(0);
            t.xy.push([x, y]);
            t.instance.push(0);
            t.chart.push(chart);
            t.triangle.push(0);
            t.p_ws.push(Vec3::new(x as f32, y as f32, 0.0));
            t.n_ws.push(Vec3::Z);
            t.area.push(1.0);
            t.albedo.push(Vec3::splat(0.5));
            t.emission.push(Vec3::ZERO);
        }
        let p = build(&t, &Burial::open(), 2, &[0.25]);
        // (0,0),(1,0) chart 0 | (2,0),(3,1) chart 0 | (1,1) chart 1
        assert_eq!(p.len(), 3);
        assert_eq!(p.texels_of(0), &[0, 1]);
        assert_eq!(p.area.iter().sum::<f32>(), 5.0);
        assert_eq!(p.of_texel[4], PatchId(2));
        assert!((p.p_ws[0] - Vec3::new(0.5, 0.0, 0.0)).length() < 1e-6);
    }
}
