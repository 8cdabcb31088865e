//! A 4- or 8-wide BVH for casting single rays on the CPU with SIMD: 4 wide
//! with `wide`'s `f32x4` (SSE on x86-64, NEON on AArch64), 8 wide with AVX
//! where the CPU has AVX2 (chosen at run time, as Embree does).
//!
//! Built from obvhs's binary BVH (PLOC, Meister & Bittner 2018, with
//! reinsertion; at most 4 triangles per leaf) by a cost-minimal collapse to
//! W children per node and leaves of up to 8 triangles: dynamic programming
//! over the binary tree chooses, for every subtree, between a leaf, an inner
//! node and a split over its parent's slots so as to minimise the
//! surface-area cost (MacDonald & Booth 1990; the collapse of Ylitie, Karras
//! & Laine 2017). A node holds its children's boxes in SoA form so one ray
//! meets all W at once; a leaf is one or two [`Tri4`]: four triangles in
//! SoA form, intersected at once (the layout of Embree's `Triangle4`,
//! Möller–Trumbore as arranged by madmann91's bvh, the division left to the
//! lanes that hit). Closest-hit traversal is nearest child first; stack
//! entries keep their entry distance so that entries beyond the closest hit
//! so far are skipped; of hits at one distance the first in BVH order wins,
//! so both widths give the same answers. Occlusion traversal takes children
//! in node order: any hit ends it, and sorting costs more than it saves.
//! Every child a node's test finds is prefetched at once, so the cache
//! misses of a node's children overlap instead of following each other.
//!
//! This replaced obvhs's own CWBVH traversal for CPU rays: on the same
//! PLOC build, the same rays and the same triangle test it casts more rays
//! per second (docs/performance.md, "Ray casting vs Embree").

use glam::Vec3;
use std::mem::MaybeUninit;
use wide::{f32x4, CmpGe, CmpGt, CmpLe};

/// Flag of a child reference that is a leaf.
const LEAF: u32 = 1 << 31;
/// A child slot that holds nothing.
const EMPTY: u32 = u32::MAX;
/// Bits of a leaf reference holding its packet count minus one.
const COUNT_SHIFT: u32 = 28;
/// Traversal stack on the call stack: enough for a BVH4 of depth 85 (3
/// entries per level); deeper ones get a heap stack.
const STACK: usize = 256;

/// W children's boxes (SoA) and references.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node<const W: usize> {
    /// Box minima per axis (0..3), then maxima (3..6), one lane per child.
    b: [[f32; W]; 6],
    /// Inner node index, `LEAF | count−1 << 28 | first packet`, or `EMPTY`.
    child: [u32; W],
}

/// Four triangles in SoA form (v0, e1 = v0 − v1, e2 = v2 − v0, n = e1 × e2
/// per axis); unused lanes are zero and never hit. The normal is stored:
/// computing it at each test instead (three cache lines a packet rather
/// than four, `b52fe39`) measured 0.98 × on Sponza then, but 1.03–1.06 ×
/// the time of storing it later (two builds timed alternately, 2 × 3
/// pairs; the Cornell gather's rays 0.93 × as fast), with the same hits.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Tri4 {
    v0: [[f32; 4]; 3],
    e1: [[f32; 4]; 3],
    e2: [[f32; 4]; 3],
    n: [[f32; 4]; 3],
    /// Triangle index in the caller's (BVH) order per lane, with [`MASKED`]
    /// set for alpha-masked triangles; `u32::MAX` unused.
    pub(crate) id: [u32; 4],
}

/// Flag of a lane id whose triangle is alpha-masked: only those lanes'
/// hits are handed to the caller's cut-out test, so opaque hits cost no
/// look-up outside the packet.
const MASKED: u32 = 1 << 31;

/// A hit inside a packet: (lane's triangle id, t, u, v).
pub(crate) type LaneHit = (u32, f32, f32, f32);

/// The W-wide BVH.
#[derive(Clone, Debug)]
pub(crate) struct Bvh<const W: usize> {
    nodes: Vec<Node<W>>,
    pub(crate) packets: Vec<Tri4>,
    /// Reference of the root (an inner node, a leaf, or `EMPTY`).
    root: u32,
    /// Traversal stack entries the deepest path can need (W − 1 per level).
    stack_needed: usize,
}

/// The 4-wide BVH (SSE, NEON).
pub(crate) type Bvh4 = Bvh<4>;
/// The 8-wide BVH (AVX; built on x86-64 only).
#[cfg(target_arch = "x86_64")]
pub(crate) type Bvh8 = Bvh<8>;

/// The shape of a [`Bvh`]: what its traversal cost depends on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Inner nodes.
    pub nodes: usize,
    /// Child slots of inner nodes that hold something (≤ W per node).
    pub used_slots: usize,
    /// Leaves.
    pub leaves: usize,
    /// Triangle packets (≥ one per leaf).
    pub packets: usize,
    /// Triangles (used packet lanes).
    pub triangles: usize,
    /// Inner-node levels on the deepest path.
    pub depth: usize,
    /// Surface-area cost relative to the root box (MacDonald & Booth 1990):
    /// Σ over inner nodes of area(node)/area(root) (each costs one W-box
    /// test) and over packets of area(leaf)/area(root) (one 4-triangle
    /// test): the expected box tests and packet tests of a random ray.
    pub sah_nodes: f64,
    /// The packets' share of that cost.
    pub sah_packets: f64,
}

/// A ray prepared for box tests.
pub(crate) struct Prepared {
    origin: [f32x4; 3],
    dir: [f32x4; 3],
    inv: [f32x4; 3],
    /// −origin / dir, so that t = box · inv + neg_org_inv (one FMA).
    neg_org_inv: [f32x4; 3],
    /// `inv` and `neg_org_inv` as scalars (for wider box tests).
    inv_s: [f32; 3],
    neg_org_inv_s: [f32; 3],
    /// Per axis, the row of `Node::b` holding the near plane (the
    /// maximum for a negative direction) and the far one.
    near: [usize; 3],
    far: [usize; 3],
}

impl Prepared {
    fn new(origin: Vec3, dir: Vec3) -> Prepared {
        // A zero component would give 0 · ∞ = NaN on a box plane through the
        // origin; a tiny one gives a huge but finite slope instead.
        let d = dir.to_array().map(|c| {
            if c.abs() < 1e-30 {
                1e-30f32.copysign(c + 0.0)
            } else {
                c
            }
        });
        let o = origin.to_array();
        let inv = d.map(|c| 1.0 / c);
        Prepared {
            origin: o.map(f32x4::splat),
            dir: dir.to_array().map(f32x4::splat),
            inv: inv.map(f32x4::splat),
            neg_org_inv: [0, 1, 2].map(|a| f32x4::splat(-o[a] * inv[a])),
            inv_s: inv,
            neg_org_inv_s: [0, 1, 2].map(|a| -o[a] * inv[a]),
            near: [0, 1, 2].map(|a| if d[a] < 0.0 { a + 3 } else { a }),
            far: [0, 1, 2].map(|a| if d[a] < 0.0 { a } else { a + 3 }),
        }
    }
}

/// The slab test of a node's W child boxes against a ray at once.
pub(crate) trait BoxTest {
    /// Entry distances, one per child.
    type Near: Copy + std::ops::Index<usize, Output = f32>;
    /// Entry distances of the children and the mask of those the segment
    /// [0, tmax] meets.
    fn boxes(&self, ray: &Prepared, tmax: f32) -> (Self::Near, i32);
}

impl BoxTest for Node<4> {
    type Near = [f32; 4];
    #[inline(always)]
    fn boxes(&self, ray: &Prepared, tmax: f32) -> ([f32; 4], i32) {
        let mut near = f32x4::splat(0.0);
        let mut far = f32x4::splat(tmax);
        for a in 0..3 {
            let tn = f32x4::new(self.b[ray.near[a]]).mul_add(ray.inv[a], ray.neg_org_inv[a]);
            let tf = f32x4::new(self.b[ray.far[a]]).mul_add(ray.inv[a], ray.neg_org_inv[a]);
            near = near.fast_max(tn);
            far = far.fast_min(tf);
        }
        // Slightly widened exit (Ize 2013): rounding in the slab distances
        // must not lose a box the ray grazes.
        let far = far * f32x4::splat(1.000_000_4);
        (near.to_array(), near.cmp_le(far).move_mask())
    }
}

/// AVX: all eight boxes in one 256-bit lane set. The slab distances are
/// a multiply and an add (no FMA), as in the 4-wide test, so a box is kept
/// or culled alike on every path. Called only from functions compiled for
/// AVX2 (`Bvh8::closest_hit_avx2`, `Bvh8::unoccluded_avx2`), which inline it.
#[cfg(target_arch = "x86_64")]
impl BoxTest for Node<8> {
    type Near = [f32; 8];
    #[inline(always)]
    fn boxes(&self, ray: &Prepared, tmax: f32) -> ([f32; 8], i32) {
        use std::arch::x86_64::*;
        // SAFETY: reached only through the `#[target_feature(enable =
        // "avx2")]` entry points, which are called only after
        // `is_x86_feature_detected!("avx2")`; `Node` is 64-byte aligned, so
        // each 32-byte row load is aligned.
        unsafe {
            let mut near = _mm256_setzero_ps();
            let mut far = _mm256_set1_ps(tmax);
            for a in 0..3 {
                let inv = _mm256_set1_ps(ray.inv_s[a]);
                let noi = _mm256_set1_ps(ray.neg_org_inv_s[a]);
                let bn = _mm256_load_ps(self.b[ray.near[a]].as_ptr());
                let bf = _mm256_load_ps(self.b[ray.far[a]].as_ptr());
                let tn = _mm256_add_ps(_mm256_mul_ps(bn, inv), noi);
                let tf = _mm256_add_ps(_mm256_mul_ps(bf, inv), noi);
                near = _mm256_max_ps(near, tn);
                far = _mm256_min_ps(far, tf);
            }
            let far = _mm256_mul_ps(far, _mm256_set1_ps(1.000_000_4));
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far));
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), near);
            (out, mask)
        }
    }
}

/// The 8-wide BVH's queries compiled for AVX2.
#[cfg(target_arch = "x86_64")]
impl Bvh8 {
    /// [`Bvh::closest_hit`] with AVX2.
    #[target_feature(enable = "avx2")]
    pub(crate) fn closest_hit_avx2(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<LaneHit> {
        self.closest_hit(origin, dir, tmax, accept)
    }

    /// [`Bvh::unoccluded`] with AVX2.
    #[target_feature(enable = "avx2")]
    pub(crate) fn unoccluded_avx2(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        self.unoccluded(origin, dir, tmax, accept)
    }
}

/// Bounding box of triangles.
fn bounds(tris: &[[Vec3; 3]], ids: &[u32]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for &i in ids {
        for p in tris[i as usize] {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    (lo, hi)
}

/// Relative cost of intersecting one [`Tri4`] packet, against 1 for one
/// [`Node`]'s W box tests (surface-area heuristic of the collapse).
const PACKET_COST: f32 = 1.0;
/// Most packets in one leaf.
const LEAF_PACKETS: u32 = 2;

/// The triangles being built over, in BVH order, and which are masked.
type Tris<'a> = (&'a [[Vec3; 3]], &'a [bool]);

/// What the collapse reads: the binary tree, its subtrees' plans and the
/// triangles.
struct Build<'a, const W: usize> {
    bvh2: &'a obvhs::bvh2::Bvh2,
    plans: &'a [Plan<W>],
    tris: Tris<'a>,
}

/// How a BVH2 subtree is best laid out in k child slots of a W-wide node
/// (k = 1..=W), with its surface-area cost.
#[derive(Clone, Copy, Debug)]
struct Plan<const W: usize> {
    /// `cost[k − 1]`: the cost of the subtree in at most k slots.
    cost: [f32; W],
    /// `split[k − 1]`: slots given to the left child when the subtree is
    /// split over k slots (0 for k = 1: one leaf or one inner node).
    split: [u8; W],
    /// With one slot: a leaf (else an inner node).
    leaf: bool,
}

impl<const W: usize> Bvh<W>
where
    Node<W>: BoxTest,
{
    /// Collapses `bvh2` (whose leaves index `bvh2.primitive_indices`) over
    /// triangles `tris` given in BVH order, i.e. `tris[k]` is the triangle of
    /// `primitive_indices[k]`; packet lane ids are those BVH-order indices.
    /// `masked[k]`: triangle k is alpha-masked (its hits go through the
    /// caller's `accept`; other hits are taken as they are).
    ///
    /// The collapse minimises the surface-area cost (MacDonald & Booth
    /// 1990) over every way of laying the binary tree into 4-wide nodes and
    /// leaves of up to [`LEAF_PACKETS`] packets, by dynamic programming
    /// over the BVH2 bottom-up (as Ylitie, Karras & Laine 2017 do for 8-wide
    /// nodes): a subtree in k slots is one leaf, one inner node (its own
    /// box test plus its best split over 4 slots) or a split of its two
    /// children over j and k − j slots. Siblings' inner nodes are stored
    /// next to each other, depth first.
    pub(crate) fn new(bvh2: &obvhs::bvh2::Bvh2, tris: &[[Vec3; 3]], masked: &[bool]) -> Self {
        assert!(tris.len() < MASKED as usize && masked.len() == tris.len());
        let mut b = Bvh {
            nodes: Vec::new(),
            packets: Vec::new(),
            root: EMPTY,
            stack_needed: 0,
        };
        if tris.is_empty() || bvh2.nodes.is_empty() {
            return b;
        }
        let plans = Self::plan(bvh2);
        let mut todo: Vec<(u32, u32)> = Vec::new();
        let cx = Build {
            bvh2,
            plans: &plans,
            tris: (tris, masked),
        };
        b.root = b.reference(&cx, 0, &mut todo);
        while let Some((index, n)) = todo.pop() {
            let mut children = Vec::with_capacity(W);
            Self::slots(bvh2, &plans, n, W, &mut children);
            b.fill(&cx, index, &children, &mut todo);
        }
        b.stack_needed = (W - 1) * b.depth() + 1;
        b
    }

    /// Triangles under BVH2 node `n`, per node.
    fn counts(bvh2: &obvhs::bvh2::Bvh2, order: &[u32]) -> Vec<u32> {
        let mut count = vec![0u32; bvh2.nodes.len()];
        for &n in order.iter().rev() {
            let node = &bvh2.nodes[n as usize];
            count[n as usize] = if node.prim_count > 0 {
                node.prim_count
            } else {
                let f = node.first_index as usize;
                count[f] + count[f + 1]
            };
        }
        count
    }

    /// The BVH2's nodes, parents before children.
    fn preorder(bvh2: &obvhs::bvh2::Bvh2) -> Vec<u32> {
        let mut order = Vec::with_capacity(bvh2.nodes.len());
        let mut todo = vec![0u32];
        while let Some(n) = todo.pop() {
            order.push(n);
            let node = &bvh2.nodes[n as usize];
            if node.prim_count == 0 {
                todo.push(node.first_index);
                todo.push(node.first_index + 1);
            }
        }
        order
    }

    /// The cost-minimal layout of every BVH2 subtree ([`Plan`]).
    fn plan(bvh2: &obvhs::bvh2::Bvh2) -> Vec<Plan<W>> {
        let order = Self::preorder(bvh2);
        let count = Self::counts(bvh2, &order);
        let mut plans = vec![
            Plan {
                cost: [f32::INFINITY; W],
                split: [0; W],
                leaf: true,
            };
            bvh2.nodes.len()
        ];
        for &n in order.iter().rev() {
            let node = &bvh2.nodes[n as usize];
            let area = node.aabb.half_area().max(0.0);
            let packets = count[n as usize].div_ceil(4);
            let leaf_cost = if packets <= LEAF_PACKETS {
                area * PACKET_COST * packets as f32
            } else {
                f32::INFINITY
            };
            let mut plan = Plan {
                cost: [leaf_cost; W],
                split: [0; W],
                leaf: true,
            };
            if node.prim_count == 0 {
                let (l, r) = (
                    plans[node.first_index as usize],
                    plans[node.first_index as usize + 1],
                );
                // Best split of the two children over k slots.
                let mut split = [(f32::INFINITY, 0u8); W];
                for (k, best) in split.iter_mut().enumerate().skip(1) {
                    for j in 1..=k {
                        let c = l.cost[j - 1] + r.cost[k - j];
                        if c < best.0 {
                            *best = (c, j as u8);
                        }
                    }
                }
                let inner = area + split[W - 1].0;
                if inner < leaf_cost {
                    plan.cost[0] = inner;
                    plan.leaf = false;
                }
                for (k, &(cost, j)) in split.iter().enumerate().skip(1) {
                    plan.cost[k] = plan.cost[k - 1];
                    if cost < plan.cost[k] {
                        plan.cost[k] = cost;
                        plan.split[k] = j;
                    }
                }
            }
            plans[n as usize] = plan;
        }
        plans
    }

    /// The BVH2 nodes that fill `k` slots for subtree `n` (each then a leaf
    /// or an inner node, as its plan for one slot says).
    fn slots(bvh2: &obvhs::bvh2::Bvh2, plans: &[Plan<W>], n: u32, k: usize, out: &mut Vec<u32>) {
        // The split of k slots may be "as for k − 1".
        let mut k = k;
        while k > 1 && plans[n as usize].split[k - 1] == 0 {
            k -= 1;
        }
        if k == 1 {
            out.push(n);
            return;
        }
        let j = plans[n as usize].split[k - 1] as usize;
        let f = bvh2.nodes[n as usize].first_index;
        Self::slots(bvh2, plans, f, j, out);
        Self::slots(bvh2, plans, f + 1, k - j, out);
    }

    /// The BVH-order triangles under BVH2 node `n`.
    fn triangles(bvh2: &obvhs::bvh2::Bvh2, n: u32) -> Vec<u32> {
        let mut ids = Vec::new();
        let mut todo = vec![n];
        while let Some(n) = todo.pop() {
            let node = &bvh2.nodes[n as usize];
            if node.prim_count > 0 {
                ids.extend(node.first_index..node.first_index + node.prim_count);
            } else {
                todo.push(node.first_index + 1);
                todo.push(node.first_index);
            }
        }
        ids
    }

    /// The reference for BVH2 subtree `n` in one slot: its leaf packets, or
    /// a new inner node queued in `todo` to be filled.
    fn reference(&mut self, cx: &Build<W>, n: u32, todo: &mut Vec<(u32, u32)>) -> u32 {
        if cx.plans[n as usize].leaf {
            let ids = Self::triangles(cx.bvh2, n);
            self.leaf(&ids, cx.tris)
        } else {
            let index = self.nodes.len() as u32;
            self.nodes.push(Node {
                b: [
                    [f32::INFINITY; W],
                    [f32::INFINITY; W],
                    [f32::INFINITY; W],
                    [f32::NEG_INFINITY; W],
                    [f32::NEG_INFINITY; W],
                    [f32::NEG_INFINITY; W],
                ],
                child: [EMPTY; W],
            });
            todo.push((index, n));
            index
        }
    }

    /// Fills inner node `index` with the BVH2 subtrees `children`.
    fn fill(&mut self, cx: &Build<W>, index: u32, children: &[u32], todo: &mut Vec<(u32, u32)>) {
        for (slot, &c) in children.iter().enumerate() {
            let reference = self.reference(cx, c, todo);
            // Inner boxes from obvhs; a leaf's is its triangles' box, clipped
            // to obvhs's, which bounds only the pieces of triangles split
            // before the build (pre_split) that the leaf stands for.
            let n = &cx.bvh2.nodes[c as usize];
            let (mut lo, mut hi) = (Vec3::from(n.aabb.min), Vec3::from(n.aabb.max));
            if reference & LEAF != 0 {
                let (tlo, thi) = bounds(cx.tris.0, &Self::triangles(cx.bvh2, c));
                (lo, hi) = (lo.max(tlo), hi.min(thi));
            }
            let node = &mut self.nodes[index as usize];
            node.child[slot] = reference;
            for axis in 0..3 {
                node.b[axis][slot] = lo[axis];
                node.b[axis + 3][slot] = hi[axis];
            }
        }
    }

    /// The tree's shape and surface-area cost.
    pub(crate) fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            depth: self.depth(),
            ..Default::default()
        };
        if self.root == EMPTY {
            return s;
        }
        let half_area = |lo: Vec3, hi: Vec3| {
            let d = (hi - lo).max(Vec3::ZERO);
            (d.x * d.y + d.y * d.z + d.z * d.x) as f64
        };
        // (reference, its box's half area)
        let mut todo = vec![(self.root, f64::NAN)];
        let mut root_area = f64::NAN;
        while let Some((r, area)) = todo.pop() {
            if r & LEAF != 0 {
                let start = (r & ((1 << COUNT_SHIFT) - 1)) as usize;
                let count = ((r & !LEAF) >> COUNT_SHIFT) as usize + 1;
                s.leaves += 1;
                s.packets += count;
                for p in &self.packets[start..start + count] {
                    s.triangles += p.id.iter().filter(|&&i| i != u32::MAX).count();
                }
                s.sah_packets += count as f64 * area;
                continue;
            }
            let node = &self.nodes[r as usize];
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for k in 0..W {
                if node.child[k] == EMPTY {
                    continue;
                }
                let clo = Vec3::new(node.b[0][k], node.b[1][k], node.b[2][k]);
                let chi = Vec3::new(node.b[3][k], node.b[4][k], node.b[5][k]);
                lo = lo.min(clo);
                hi = hi.max(chi);
                s.used_slots += 1;
                todo.push((node.child[k], half_area(clo, chi)));
            }
            let area = if area.is_nan() {
                root_area = half_area(lo, hi);
                root_area
            } else {
                area
            };
            s.nodes += 1;
            s.sah_nodes += area;
        }
        if root_area > 0.0 {
            s.sah_nodes /= root_area;
            s.sah_packets /= root_area;
        }
        s
    }

    /// Inner-node levels on the deepest path.
    fn depth(&self) -> usize {
        let mut deepest = 0;
        let mut todo = vec![(self.root, 0usize)];
        while let Some((r, d)) = todo.pop() {
            if r == EMPTY || r & LEAF != 0 {
                deepest = deepest.max(d);
                continue;
            }
            for &c in &self.nodes[r as usize].child {
                todo.push((c, d + 1));
            }
        }
        deepest
    }

    /// Packs the BVH-order triangles `ids` into packets.
    fn leaf(&mut self, ids: &[u32], (tris, masked): Tris) -> u32 {
        let start = self.packets.len() as u32;
        for chunk in ids.chunks(4) {
            let mut p = Tri4 {
                v0: [[0.0; 4]; 3],
                e1: [[0.0; 4]; 3],
                e2: [[0.0; 4]; 3],
                n: [[0.0; 4]; 3],
                id: [u32::MAX; 4],
            };
            for (lane, &k) in chunk.iter().enumerate() {
                let [a, b, c] = tris[k as usize];
                let e1 = a - b;
                let e2 = c - a;
                let n = e1.cross(e2);
                for axis in 0..3 {
                    p.v0[axis][lane] = a[axis];
                    p.e1[axis][lane] = e1[axis];
                    p.e2[axis][lane] = e2[axis];
                    p.n[axis][lane] = n[axis];
                }
                p.id[lane] = if masked[k as usize] { k | MASKED } else { k };
            }
            self.packets.push(p);
        }
        let packets = self.packets.len() as u32 - start;
        // The plan keeps leaves within LEAF_PACKETS ≤ 8 packets.
        assert!((1..=8).contains(&packets) && start < 1 << COUNT_SHIFT);
        LEAF | (packets - 1) << COUNT_SHIFT | start
    }

    /// Visits the leaves that the segment `origin + t·dir`, t ∈ [0, tmax],
    /// may hit, nearest first when `V::ORDERED`: the visitor returns the new
    /// `tmax` (smaller after a hit) or `None` to stop the traversal.
    #[inline(always)]
    fn traverse<V: Visitor>(&self, origin: Vec3, dir: Vec3, tmax: f32, visitor: &mut V) {
        if self.root == EMPTY {
            return;
        }
        if self.stack_needed <= STACK {
            // Not zero-filled: every entry is written before it is read.
            let mut stack = [const { MaybeUninit::<(u32, f32)>::uninit() }; STACK];
            self.traverse_with(&mut stack, origin, dir, tmax, visitor);
        } else {
            let mut stack = vec![MaybeUninit::uninit(); self.stack_needed];
            self.traverse_with(&mut stack, origin, dir, tmax, visitor);
        }
    }

    /// Asks for the cache lines of the node or leaf packets `r` refers to,
    /// so that the loads of the children a node's test found overlap.
    #[inline(always)]
    fn prefetch(&self, r: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let (ptr, bytes) = if r & LEAF == 0 {
                (
                    self.nodes.as_ptr().wrapping_add(r as usize) as *const i8,
                    std::mem::size_of::<Node<W>>(),
                )
            } else {
                let start = (r & ((1 << COUNT_SHIFT) - 1)) as usize;
                (
                    self.packets.as_ptr().wrapping_add(start) as *const i8,
                    std::mem::size_of::<Tri4>(),
                )
            };
            for line in (0..bytes).step_by(64) {
                // SAFETY: prefetching is a hint; it never faults, whatever
                // the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(ptr.wrapping_add(line)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = r;
    }

    #[inline(always)]
    fn traverse_with<V: Visitor>(
        &self,
        stack: &mut [MaybeUninit<(u32, f32)>],
        origin: Vec3,
        dir: Vec3,
        mut tmax: f32,
        visitor: &mut V,
    ) {
        let ray = Prepared::new(origin, dir);
        let mut top = 1usize;
        stack[0] = MaybeUninit::new((self.root, 0.0));
        // Pushes stay within `stack_needed`: at most 3 per level.
        macro_rules! push {
            ($entry:expr) => {{
                stack[top] = MaybeUninit::new($entry);
                top += 1;
            }};
        }
        'pop: loop {
            if top == 0 {
                return;
            }
            top -= 1;
            // SAFETY: entries below `top` were all written (pushes write
            // `stack[top]` before incrementing it).
            let (mut r, t_entry) = unsafe { stack[top].assume_init() };
            if t_entry > tmax {
                continue;
            }
            // Descend through inner nodes (nearest child first when ordered),
            // pushing the other children that the ray meets.
            while r & LEAF == 0 {
                let node = &self.nodes[r as usize];
                let (near, mut mask) = node.boxes(&ray, tmax);
                if mask == 0 {
                    continue 'pop;
                }
                let a = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                self.prefetch(node.child[a]);
                if mask == 0 {
                    // One child (the common case): no stack traffic.
                    r = node.child[a];
                    continue;
                }
                let b = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                self.prefetch(node.child[b]);
                if !V::ORDERED {
                    push!((node.child[a], 0.0));
                    while mask != 0 {
                        let k = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        self.prefetch(node.child[k]);
                        push!((node.child[k], 0.0));
                    }
                    r = node.child[b];
                    continue;
                }
                let (a, b) = if near[a] <= near[b] { (a, b) } else { (b, a) };
                if mask == 0 {
                    push!((node.child[b], near[b]));
                    r = node.child[a];
                    continue;
                }
                // Three or four children: insertion sort, far to near.
                let mut hits = [(0u32, 0.0f32); W];
                hits[0] = (node.child[b], near[b]);
                hits[1] = (node.child[a], near[a]);
                let mut n = 2;
                while mask != 0 {
                    let k = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    self.prefetch(node.child[k]);
                    let mut j = n;
                    while j > 0 && hits[j - 1].1 < near[k] {
                        hits[j] = hits[j - 1];
                        j -= 1;
                    }
                    hits[j] = (node.child[k], near[k]);
                    n += 1;
                }
                for h in &hits[..n - 1] {
                    push!(*h);
                }
                r = hits[n - 1].0;
            }
            let start = (r & ((1 << COUNT_SHIFT) - 1)) as usize;
            let count = ((r & !LEAF) >> COUNT_SHIFT) as usize + 1;
            for p in &self.packets[start..start + count] {
                match visitor.visit(p, &ray, tmax) {
                    Some(t) => tmax = t,
                    None => return,
                }
            }
        }
    }

    /// The hits of the ray with the four triangles of `p` within [0, tmax]:
    /// a lane mask, and what [`Self::hit_params`] turns into (t, u, v).
    ///
    /// Möller–Trumbore with the division left to the hits (as Embree's
    /// `MoellerTrumboreIntersector1` does): u·det, v·det and t·det, their
    /// signs flipped by det's, are compared with |det| and |det|·tmax.
    #[inline(always)]
    fn intersect(p: &Tri4, ray: &Prepared, tmax: f32) -> (i32, [f32x4; 4]) {
        let v = |a: &[[f32; 4]; 3]| a.map(f32x4::new);
        let (v0, e1, e2, n) = (v(&p.v0), v(&p.e1), v(&p.e2), v(&p.n));
        let o = &ray.origin;
        let d = &ray.dir;
        let c = [v0[0] - o[0], v0[1] - o[1], v0[2] - o[2]];
        // r = d × c
        let r = [
            d[1] * c[2] - d[2] * c[1],
            d[2] * c[0] - d[0] * c[2],
            d[0] * c[1] - d[1] * c[0],
        ];
        let dot = |a: &[f32x4; 3], b: &[f32x4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let det = dot(&n, d);
        let u = dot(&r, &e2);
        let w = dot(&r, &e1);
        let t = dot(&n, &c);
        let sign = det & f32x4::splat(-0.0);
        let abs = det ^ sign;
        let (us, ws, ts) = (u ^ sign, w ^ sign, t ^ sign);
        let zero = f32x4::splat(0.0);
        // det = 0 fails abs > 0; a NaN fails every comparison.
        let ok = us.cmp_ge(zero)
            & ws.cmp_ge(zero)
            & (us + ws).cmp_le(abs)
            & ts.cmp_ge(zero)
            & ts.cmp_le(abs * f32x4::splat(tmax))
            & abs.cmp_gt(zero);
        (ok.move_mask(), [t, u, w, det])
    }

    /// (t, u, v) per lane of a packet's hits from [`Self::intersect`].
    #[inline(always)]
    fn hit_params([t, u, w, det]: [f32x4; 4]) -> ([f32; 4], [f32; 4], [f32; 4]) {
        let inv = f32x4::splat(1.0) / det;
        (
            (t * inv).to_array(),
            (u * inv).to_array(),
            (w * inv).to_array(),
        )
    }

    /// The closest hit along `origin + t·dir`, t ∈ [0, tmax], among the
    /// lanes `accept` keeps (alpha cut-outs): (lane id, t, u, v).
    #[inline(always)]
    pub(crate) fn closest_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<LaneHit> {
        let mut v = Closest { accept, best: None };
        self.traverse(origin, dir, tmax, &mut v);
        v.best
    }

    /// True when no lane `accept` keeps lies along `origin + t·dir`,
    /// t ∈ [0, tmax].
    #[inline(always)]
    pub(crate) fn unoccluded(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        accept: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        let mut v = AnyHit {
            accept,
            clear: true,
        };
        self.traverse(origin, dir, tmax, &mut v);
        v.clear
    }
}

impl<const W: usize> Bvh<W> {
    /// The triangle nearest to `p` within distance √`max_d2`: (lane id,
    /// squared distance, nearest point). Best-first over the children's
    /// boxes (squared distance from `p` to each box), nearest pushed last
    /// so it is taken first; a subtree whose box lies beyond the best
    /// distance so far is skipped. Per triangle, the closest point of
    /// Ericson, *Real-Time Collision Detection* §5.1.5. Of triangles at
    /// one distance the lowest id wins, so the answer does not depend on
    /// the visit order. Alpha cut-outs are not consulted: a masked
    /// triangle counts whole.
    ///
    /// Also the runner-up: the least squared distance of any other
    /// triangle, exact where it is within a factor 1 + `tie` of the best
    /// (subtrees are kept to that slack), else some larger value. A
    /// coincident face (two coplanar faces back to back: an object resting
    /// on a floor) shows as a runner-up at the best distance.
    pub(crate) fn closest_point(
        &self,
        p: Vec3,
        max_d2: f32,
        tie: f32,
    ) -> Option<(u32, f32, Vec3, f32)> {
        if self.root == EMPTY {
            return None;
        }
        let mut best: Option<(u32, f32, Vec3)> = None;
        let mut second = f32::INFINITY;
        let mut limit = max_d2;
        let slack = 1.0 + tie;
        let mut stack: Vec<(u32, f32)> = Vec::with_capacity(self.stack_needed.max(8));
        stack.push((self.root, 0.0));
        while let Some((r, d2)) = stack.pop() {
            if d2 > limit * slack {
                continue;
            }
            if r & LEAF != 0 {
                let first = (r & ((1 << COUNT_SHIFT) - 1)) as usize;
                let count = (((r & !LEAF) >> COUNT_SHIFT) + 1) as usize;
                for packet in &self.packets[first..first + count] {
                    for k in 0..4 {
                        if packet.id[k] == u32::MAX {
                            continue;
                        }
                        let id = packet.id[k] & !MASKED;
                        let v0 = Vec3::new(packet.v0[0][k], packet.v0[1][k], packet.v0[2][k]);
                        let e1 = Vec3::new(packet.e1[0][k], packet.e1[1][k], packet.e1[2][k]);
                        let e2 = Vec3::new(packet.e2[0][k], packet.e2[1][k], packet.e2[2][k]);
                        let q = closest_on_triangle(p, v0, v0 - e1, v0 + e2);
                        let dq = (q - p).length_squared();
                        let better = dq < limit || (dq == limit && best.is_some_and(|b| id < b.0));
                        if better {
                            if let Some(b) = best {
                                second = second.min(b.1);
                            }
                            limit = dq;
                            best = Some((id, dq, q));
                        } else {
                            second = second.min(dq);
                        }
                    }
                }
                continue;
            }
            let node = &self.nodes[r as usize];
            let mut children: [(u32, f32); W] = [(EMPTY, 0.0); W];
            let mut n = 0;
            for c in 0..W {
                if node.child[c] == EMPTY {
                    continue;
                }
                let mut dc = 0.0f32;
                for axis in 0..3 {
                    let (lo, hi) = (node.b[axis][c], node.b[axis + 3][c]);
                    let x = p[axis];
                    let d = if x < lo {
                        lo - x
                    } else if x > hi {
                        x - hi
                    } else {
                        0.0
                    };
                    dc += d * d;
                }
                if dc <= limit * slack {
                    children[n] = (node.child[c], dc);
                    n += 1;
                }
            }
            // Farthest first onto the stack, so the nearest is popped next.
            children[..n].sort_by(|a, b| b.1.total_cmp(&a.1));
            stack.extend_from_slice(&children[..n]);
        }
        best.map(|(id, d2, q)| (id, d2, q, second))
    }
}

/// The point of triangle (a, b, c) nearest to `p` (Ericson 2005, §5.1.5:
/// the Voronoi regions of the vertices, then of the edges, then the face).
pub(crate) fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// What a traversal does at a leaf packet (a trait rather than a closure,
/// so that the packet test is always inlined into the traversal loop).
trait Visitor {
    /// Children visited nearest first (closest hit), or in slot order
    /// (any hit: sorting costs more than it saves).
    const ORDERED: bool;
    /// Tests packet `p`: the new `tmax`, or `None` to stop.
    fn visit(&mut self, p: &Tri4, ray: &Prepared, tmax: f32) -> Option<f32>;
}

/// The closest-hit visitor.
struct Closest<F> {
    accept: F,
    best: Option<LaneHit>,
}

impl<F: Fn(u32, f32, f32) -> bool> Visitor for Closest<F> {
    const ORDERED: bool = true;
    #[inline(always)]
    fn visit(&mut self, p: &Tri4, ray: &Prepared, tmax: f32) -> Option<f32> {
        // A little beyond tmax, so that a hit at the very distance of the
        // best so far (a coplanar twin) is not lost to rounding in the
        // packet test; the exact rule is applied below.
        let (mut mask, raw) = Bvh4::intersect(p, ray, tmax * (1.0 + 1e-6));
        if mask == 0 {
            return Some(tmax);
        }
        let (t, u, v) = Bvh4::hit_params(raw);
        let mut limit = tmax;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let id = p.id[k] & !MASKED;
            // Nearest first, and of hits at the same distance the lowest
            // id: the answer does not depend on the order of the visit, so
            // the 4- and 8-wide BVHs give the same hits.
            let better = t[k] < limit || (t[k] == limit && self.best.is_some_and(|b| id < b.0));
            if better && (p.id[k] & MASKED == 0 || (self.accept)(id, u[k], v[k])) {
                limit = t[k];
                self.best = Some((id, t[k], u[k], v[k]));
            }
        }
        Some(limit)
    }
}

/// The occlusion (any-hit) visitor.
struct AnyHit<F> {
    accept: F,
    clear: bool,
}

impl<F: Fn(u32, f32, f32) -> bool> Visitor for AnyHit<F> {
    const ORDERED: bool = false;
    #[inline(always)]
    fn visit(&mut self, p: &Tri4, ray: &Prepared, tmax: f32) -> Option<f32> {
        let (mut mask, raw) = Bvh4::intersect(p, ray, tmax);
        if mask == 0 {
            return Some(tmax);
        }
        // An opaque lane's hit ends the ray: no barycentrics needed.
        let opaque = (0..4).any(|k| mask & 1 << k != 0 && p.id[k] & MASKED == 0);
        if opaque {
            self.clear = false;
            return None;
        }
        let (_, u, v) = Bvh4::hit_params(raw);
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if (self.accept)(p.id[k] & !MASKED, u[k], v[k]) {
                self.clear = false;
                return None;
            }
        }
        Some(tmax)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::sampling::Stream;

    /// obvhs's BVH2 over `n` random triangles, as `RayCaster` builds it,
    /// and the triangles.
    fn random_bvh2(n: usize, seed: u64) -> (obvhs::bvh2::Bvh2, Vec<[Vec3; 3]>) {
        let mut s = Stream::new(seed, 0, 0);
        let mut v = || Vec3::new(s.next_f32(), s.next_f32(), s.next_f32());
        let tris: Vec<[Vec3; 3]> = (0..n)
            .map(|_| {
                let c = v() * 20.0;
                [c + v() - 0.5, c + v() - 0.5, c + v() - 0.5]
            })
            .collect();
        let obvhs_tris: Vec<obvhs::triangle::Triangle> = tris
            .iter()
            .map(|p| obvhs::triangle::Triangle {
                v0: p[0].into(),
                v1: p[1].into(),
                v2: p[2].into(),
            })
            .collect();
        let params = obvhs::BvhBuildParams {
            max_prims_per_leaf: 4,
            ..obvhs::BvhBuildParams::medium_build()
        };
        let bvh2 = obvhs::bvh2::builder::build_bvh2_from_tris(
            &obvhs_tris,
            params,
            &mut std::time::Duration::default(),
        );
        (bvh2, tris)
    }

    /// A W-wide BVH over `n` random triangles, and the triangles in BVH
    /// order.
    fn random_bvh<const W: usize>(n: usize, seed: u64) -> (Bvh<W>, Vec<[Vec3; 3]>)
    where
        Node<W>: BoxTest,
    {
        let (bvh2, tris) = random_bvh2(n, seed);
        let ordered: Vec<[Vec3; 3]> = bvh2
            .primitive_indices
            .iter()
            .map(|&g| tris[g as usize])
            .collect();
        let masked = vec![false; ordered.len()];
        (Bvh::new(&bvh2, &ordered, &masked), ordered)
    }

    /// Every triangle sits in exactly one lane, every box holds what is
    /// under it, leaves keep to LEAF_PACKETS, and the tree's surface-area
    /// cost is the one the dynamic programme minimised.
    #[test]
    fn collapse_keeps_every_triangle_once_inside_its_boxes() {
        check_collapse::<4>();
        check_collapse::<8>();
    }

    fn check_collapse<const W: usize>()
    where
        Node<W>: BoxTest,
    {
        let (bvh, tris) = random_bvh::<W>(5000, 11);
        let mut seen = vec![0u32; tris.len()];
        // (reference, box it must lie in)
        let mut todo = vec![(
            bvh.root,
            Vec3::splat(f32::NEG_INFINITY),
            Vec3::splat(f32::INFINITY),
        )];
        while let Some((r, lo, hi)) = todo.pop() {
            if r & LEAF != 0 {
                let start = (r & ((1 << COUNT_SHIFT) - 1)) as usize;
                let count = ((r & !LEAF) >> COUNT_SHIFT) as usize + 1;
                assert!(count as u32 <= LEAF_PACKETS);
                for p in &bvh.packets[start..start + count] {
                    for &id in p.id.iter().filter(|&&i| i != u32::MAX) {
                        assert_eq!(id & MASKED, 0);
                        seen[id as usize] += 1;
                        for c in tris[id as usize] {
                            assert!(
                                c.cmpge(lo).all() && c.cmple(hi).all(),
                                "{c} outside {lo}..{hi}"
                            );
                        }
                    }
                }
                continue;
            }
            let node = &bvh.nodes[r as usize];
            for k in 0..W {
                if node.child[k] == EMPTY {
                    continue;
                }
                let clo = Vec3::new(node.b[0][k], node.b[1][k], node.b[2][k]);
                let chi = Vec3::new(node.b[3][k], node.b[4][k], node.b[5][k]);
                // Inner boxes nest (obvhs's boxes are exact unions).
                assert!(clo.cmpge(lo).all() && chi.cmple(hi).all());
                todo.push((node.child[k], clo, chi));
            }
        }
        assert!(
            seen.iter().all(|&c| c == 1),
            "a triangle is missing or repeated"
        );
        let st = bvh.stats();
        assert_eq!(st.triangles, tris.len());
        let fill = st.used_slots as f64 / st.nodes as f64;
        eprintln!("{W}-wide: {fill:.2} children per node");
        assert!(fill > 0.7 * W as f64, "{st:?}");
    }

    /// The collapse's cost is no worse than the greedy collapse that opens
    /// the largest child until a node has four, on the same binary tree.
    #[test]
    fn collapse_costs_no_more_than_the_greedy_one() {
        let (bvh, _) = random_bvh::<4>(20_000, 5);
        let st = bvh.stats();
        let dp = st.sah_nodes + PACKET_COST as f64 * st.sah_packets;
        // Greedy, on the same cost terms and the same BVH2.
        let greedy = greedy_cost(20_000, 5);
        eprintln!("surface-area cost: dynamic programme {dp:.3}, greedy {greedy:.3}");
        assert!(dp <= greedy * 1.000_1, "dp {dp} greedy {greedy}");
    }

    /// Surface-area cost (relative to the root's box) of the greedy BVH2 →
    /// BVH4 collapse over the tree `random_bvh` builds: inner nodes open
    /// their largest inner child until they have four; BVH2 leaves are
    /// leaves.
    fn greedy_cost(n: usize, seed: u64) -> f64 {
        let (bvh2, _) = random_bvh2(n, seed);
        let area = |c: u32| bvh2.nodes[c as usize].aabb.half_area() as f64;
        let root = area(0);
        let mut cost = 0.0;
        let mut todo = vec![0u32];
        while let Some(i) = todo.pop() {
            let node = &bvh2.nodes[i as usize];
            if node.prim_count > 0 {
                cost += PACKET_COST as f64 * node.prim_count.div_ceil(4) as f64 * area(i);
                continue;
            }
            cost += area(i);
            let mut open = vec![node.first_index, node.first_index + 1];
            while open.len() < 4 {
                let best = open
                    .iter()
                    .enumerate()
                    .filter(|(_, &c)| bvh2.nodes[c as usize].prim_count == 0)
                    .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
                    .map(|(k, _)| k);
                let Some(k) = best else { break };
                let c = open.swap_remove(k);
                let f = bvh2.nodes[c as usize].first_index;
                open.extend([f, f + 1]);
            }
            todo.extend(open);
        }
        cost / root
    }
}
