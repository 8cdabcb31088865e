// Closest-hit ray casting over a binary BVH (obvhs's PLOC-built Bvh2,
// flattened by src/gpu.rs), one ray per invocation: the GPU half of
// `--device gpu`. Rays are generated on the CPU by the same sampling code as
// the CPU path, so both paths cast identical rays; hits come back as
// (t, u, v, triangle) and are turned into patches on the CPU.

struct Node {
    // Bounds.
    min: vec3<f32>,
    // 0: inner node (children at first_index and first_index + 1);
    // n > 0: a leaf of n triangles starting at first_index (BVH order).
    prim_count: u32,
    max: vec3<f32>,
    first_index: u32,
}

// Möller–Trumbore in the layout of src/raycast.rs: e1 = v0 − v1,
// e2 = v2 − v0, n = e1 × e2 (xyz of each; w unused).
struct Tri {
    v0: vec4<f32>,
    e1: vec4<f32>,
    e2: vec4<f32>,
    n: vec4<f32>,
}

// origin.xyz, tmin; dir.xyz, tmax.
struct Ray {
    origin: vec4<f32>,
    dir: vec4<f32>,
}

// t (3.4e38 on a miss), u, v, triangle index in BVH order (0xffffffff on a miss).
struct Hit {
    t: f32,
    u: f32,
    v: f32,
    tri: u32,
}

struct Params {
    count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> tris: array<Tri>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> hits: array<Hit>;
@group(0) @binding(4) var<uniform> params: Params;

const STACK: u32 = 64u;

// Slab test: the entry distance, or 3.4e38 when the box is missed within [tmin, tmax].
fn box_entry(lo: vec3<f32>, hi: vec3<f32>, o: vec3<f32>, inv: vec3<f32>, tmin: f32, tmax: f32) -> f32 {
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let near = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), max(min(t0.z, t1.z), tmin));
    let far = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), min(max(t0.z, t1.z), tmax));
    if near <= far {
        return near;
    }
    return 3.4e38;
}

@compute @workgroup_size(64)
fn cast_rays(@builtin(global_invocation_id) gid: vec3<u32>) {
    let id = gid.x + gid.y * 65535u * 64u;
    if id >= params.count {
        return;
    }
    let ray = rays[id];
    let o = ray.origin.xyz;
    let d = ray.dir.xyz;
    let inv = 1.0 / d;
    var tmax = ray.dir.w;
    let tmin = ray.origin.w;
    var best = Hit(3.4e38, 0.0, 0.0, 0xffffffffu);

    var stack: array<u32, STACK>;
    var sp = 0u;
    var node = 0u;
    if box_entry(nodes[0].min, nodes[0].max, o, inv, tmin, tmax) > tmax {
        hits[id] = best;
        return;
    }
    loop {
        let n = nodes[node];
        if n.prim_count > 0u {
            for (var k = 0u; k < n.prim_count; k++) {
                let i = n.first_index + k;
                let tri = tris[i];
                let c = tri.v0.xyz - o;
                let r = cross(d, c);
                let det = dot(tri.n.xyz, d);
                if det != 0.0 {
                    let inv_det = 1.0 / det;
                    let u = dot(r, tri.e2.xyz) * inv_det;
                    let v = dot(r, tri.e1.xyz) * inv_det;
                    let t = dot(tri.n.xyz, c) * inv_det;
                    if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= tmin && t <= tmax && t < best.t {
                        best = Hit(t, u, v, i);
                        tmax = t;
                    }
                }
            }
        } else {
            let a = n.first_index;
            let b = a + 1u;
            let ta = box_entry(nodes[a].min, nodes[a].max, o, inv, tmin, tmax);
            let tb = box_entry(nodes[b].min, nodes[b].max, o, inv, tmin, tmax);
            let hit_a = ta <= tmax;
            let hit_b = tb <= tmax;
            if hit_a && hit_b {
                // Nearer child first; the other waits on the stack.
                if ta <= tb {
                    node = a;
                    if sp < STACK {
                        stack[sp] = b;
                        sp++;
                    }
                } else {
                    node = b;
                    if sp < STACK {
                        stack[sp] = a;
                        sp++;
                    }
                }
                continue;
            } else if hit_a {
                node = a;
                continue;
            } else if hit_b {
                node = b;
                continue;
            }
        }
        // Pop the next node still in reach.
        var found = false;
        loop {
            if sp == 0u {
                break;
            }
            sp--;
            let next = stack[sp];
            if box_entry(nodes[next].min, nodes[next].max, o, inv, tmin, tmax) <= tmax {
                node = next;
                found = true;
                break;
            }
        }
        if !found {
            break;
        }
    }
    hits[id] = best;
}
