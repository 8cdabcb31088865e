// Hemicube faces rasterised by the GPU (Cohen & Greenberg 1985, as
// lightmapper.h renders them): an item buffer of triangle ids and the
// perspective-correct barycentric weights of corners 1 and 2 at each
// pixel centre, nearest surface kept by the depth test. The CPU lands
// each pixel on its texel's patch (src/form_factors/hemicube.rs, Resolve).
//
// Depth is reversed and unbounded: clip = (x, y', NEAR, z) with z the
// distance along the face's forward axis, so NDC depth = NEAR / z, larger
// is nearer, and the GPU's clip at depth ≤ w is the near plane z ≥ NEAR.

struct Face {
    // xyz: the face's right axis; w: 1 for a half side face (up ∈ [0, 1]).
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
    eye: vec4<f32>,
};

@group(0) @binding(0) var<storage, read> faces: array<Face>;
// Three corners per triangle, in the bake's triangle order.
@group(0) @binding(1) var<storage, read> corners: array<vec4<f32>>;

const NEAR: f32 = 1e-5;

struct Varyings {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) item: u32,
    @location(1) bary: vec2<f32>,
};

@vertex
fn vs_face(@builtin(vertex_index) v: u32, @builtin(instance_index) f: u32) -> Varyings {
    let face = faces[f];
    let d = corners[v].xyz - face.eye.xyz;
    let c = vec3<f32>(dot(d, face.right.xyz), dot(d, face.up.xyz), dot(d, face.forward.xyz));
    // A half side face maps up/forward ∈ [0, 1] onto the viewport's height.
    var y = c.y;
    if face.right.w > 0.5 {
        y = 2.0 * c.y - c.z;
    }
    var out: Varyings;
    out.clip = vec4<f32>(c.x, y, NEAR, c.z);
    out.item = v / 3u + 1u;
    let k = v % 3u;
    out.bary = vec2<f32>(select(0.0, 1.0, k == 1u), select(0.0, 1.0, k == 2u));
    return out;
}

struct Item {
    @location(0) item: u32,
    @location(1) bary: vec2<f32>,
};

@fragment
fn fs_item(in: Varyings) -> Item {
    return Item(in.item, in.bary);
}
