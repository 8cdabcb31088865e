//! The imported scene: meshes in their local space, the node
//! instances that place them in the world, materials, textures, lights and
//! cameras. `gltf.rs` is the only file that reads glTF.
//!
//! Units: metres; emission is emitted radiance (W·sr⁻¹·m⁻²); point and spot
//! light intensity is W/sr (≙ cd); directional light intensity is W/m² (≙ lux).

mod gltf;
pub mod layers;
pub mod light_modes;
pub mod probe_volume;
pub mod sun_path;
pub mod texture;

pub use self::gltf::{load, LoadOptions};
pub use crate::config::LightMode;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
pub use texture::{Filter, Filters, Mips, Texture, TextureRef, Wrap};

/// A mesh in its local space: the triangles of all its (triangle) primitives
/// concatenated. Degenerate triangles have already been removed.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// `meshes[i].name`, or `mesh<i>`.
    pub name: String,
    /// Index in the glTF `meshes` array.
    pub gltf_index: usize,
    /// The mesh's `extras.radbake.texel_scale`, for nodes that set none.
    pub texel_scale: Option<f32>,
    /// Vertex positions (local space).
    pub positions: Vec<Vec3>,
    /// Vertex normals (local space, unit length).
    pub normals: Vec<Vec3>,
    /// `TEXCOORD_0`, or zeros.
    pub uv0: Vec<Vec2>,
    /// `TEXCOORD_1` when every primitive has one (used by `--uv existing`).
    pub uv1: Option<Vec<Vec2>>,
    /// `COLOR_0` (linear RGBA; an RGB set gets alpha 1) when some primitive
    /// has one, white for the vertices of those that do not. The bake
    /// ignores it; the preview multiplies the base colour by it, as
    /// three.js does (`color_fragment.glsl.js`).
    pub colors: Option<Vec<Vec4>>,
    /// Triangles, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Material index (into [`Scene::materials`]) per triangle.
    pub triangle_material: Vec<u32>,
    /// glTF primitive index (within the mesh) of each triangle.
    pub triangle_primitive: Vec<u32>,
    /// Index of each vertex in its primitive's own attribute arrays.
    pub vertex_source: Vec<u32>,
}

/// The density of a node with `extras.radbake.lightmap: false` over its
/// `texel_scale`: its texels only carry its light for the bounces.
pub const LIGHTMAPLESS_SCALE: f32 = 0.25;

/// One placement of a mesh by a node: each instance gets its own lightmap
/// rectangle.
#[derive(Clone, Debug)]
pub struct Instance {
    /// The node's name, or `node<i>`.
    pub node: String,
    /// Index in the glTF `nodes` array.
    pub node_index: usize,
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Local to world transform (the product of the node path's transforms).
    pub world_from_local: Mat4,
    /// The node's `extras.radbake.texel_scale`: its lightmap density is the
    /// bake's times this (1: the bake's).
    pub texel_scale: f32,
    /// The node's `extras.radbake.cast_shadows` (default true): false
    /// leaves it out of the ray caster, so it neither blocks nor reflects
    /// light for anything else, and receives light in its own texels.
    pub cast_shadows: bool,
    /// The node's `extras.radbake.lightmap` (default true): false gives it
    /// no lightmap an engine reads (no `MOZ_lightmap`, `lightmap: false`
    /// in the manifest; engines light it by the probes). It still casts
    /// shadows and bounces light: its texels, at
    /// [`LIGHTMAPLESS_SCALE`] × its density (folded into `texel_scale`),
    /// carry its light for the bounces only.
    pub lightmap: bool,
}

impl Instance {
    /// True when the transform mirrors (negative determinant): the triangle
    /// winding must then be flipped to keep front faces in front.
    pub fn mirrors(&self) -> bool {
        self.world_from_local.determinant() < 0.0
    }

    /// Matrix that takes local normals to world normals (inverse transpose).
    pub fn normal_matrix(&self) -> Mat3 {
        Mat3::from_mat4(self.world_from_local).inverse().transpose()
    }

    /// Uniform scale that best describes the transform: the cube root of
    /// |det|, used to keep one texel density across scaled instances.
    pub fn uniform_scale(&self) -> f32 {
        self.world_from_local.determinant().abs().cbrt()
    }
}

/// How alpha is used (glTF `alphaMode`); MASK and BLEND are both cut out at
/// `cutoff` (0.5 for BLEND), for rays and for texels alike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Alpha {
    /// Fully opaque.
    Opaque,
    /// Cut out where base colour alpha < cutoff.
    Mask {
        /// glTF `alphaCutoff`.
        cutoff: f32,
    },
}

/// A Lambertian material.
#[derive(Clone, Debug)]
pub struct Material {
    /// `materials[i].name`, or `material<i>`, or `default`.
    pub name: String,
    /// Linear RGB albedo factor ρ (glTF `baseColorFactor`; metallic is ignored).
    pub albedo: Vec3,
    /// `baseColorFactor` alpha.
    pub alpha_factor: f32,
    /// Base colour texture (sRGB), multiplied into `albedo`.
    pub albedo_texture: Option<TextureRef>,
    /// Emitted radiance factor: `emissiveFactor × KHR_materials_emissive_strength`.
    pub emission: Vec3,
    /// Emissive texture (sRGB), multiplied into `emission`.
    pub emission_texture: Option<TextureRef>,
    /// glTF `doubleSided`.
    pub double_sided: bool,
    /// Cut-out mode.
    pub alpha: Alpha,
    /// glTF `alphaMode` `BLEND`. The bake cuts such a material out at 0.5
    /// (`alpha`); viewers, the preview included, blend it.
    pub blend: bool,
    /// Perfectly specular response, traced by the path tracer's Whitted-style
    /// paths (the radiosity bake treats every surface as Lambertian).
    pub specular: Specular,
    /// The light layer of its emission (`extras.radbake.layer`; `None`:
    /// the layer `static`). See [`crate::scene::layers`].
    pub layer: Option<String>,
}

/// Perfectly specular materials the path tracer follows recursively.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Specular {
    /// Lambertian only.
    #[default]
    None,
    /// A perfect mirror tinted by the base colour: glTF `metallicFactor` 1
    /// and `roughnessFactor` 0.
    Mirror,
    /// A smooth dielectric (Fresnel reflection and refraction, tinted by the
    /// base colour): `KHR_materials_transmission` factor ≥ 0.5, with
    /// `KHR_materials_ior` (default 1.5).
    Glass {
        /// Index of refraction.
        ior: f32,
    },
}

impl Material {
    /// The material used where glTF gives none: a white-ish diffuse (ρ = 0.8),
    /// since glTF's default (white, fully metallic) has no diffuse response.
    pub fn fallback() -> Self {
        Material {
            name: "default".into(),
            albedo: Vec3::splat(0.8),
            alpha_factor: 1.0,
            albedo_texture: None,
            emission: Vec3::ZERO,
            emission_texture: None,
            double_sided: false,
            alpha: Alpha::Opaque,
            blend: false,
            specular: Specular::None,
            layer: None,
        }
    }

    /// True when the material emits anything.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// `KHR_lights_punctual` light kinds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Directional: `intensity` is irradiance on a surface facing it (W/m²).
    Directional,
    /// Point: `intensity` is radiant intensity (W/sr).
    Point,
    /// Spot: a point light with the spec's smooth cone falloff.
    Spot {
        /// Inner cone angle (radians).
        inner_cone_angle: f32,
        /// Outer cone angle (radians).
        outer_cone_angle: f32,
    },
}

/// A punctual light placed in the world.
#[derive(Clone, Debug)]
pub struct Light {
    /// The light's name, or its node's where it has none.
    pub name: String,
    /// The node's name.
    pub node: String,
    /// The node's index in the glTF `nodes` array.
    pub node_index: usize,
    /// The mode the bake uses (see [`LightMode`]): the node's
    /// `extras.radbake.mode` as imported, changed by
    /// [`crate::config::LightModes::apply`].
    pub mode: LightMode,
    /// The node's own `extras.radbake.mode`, if it has one.
    pub node_mode: Option<LightMode>,
    /// Kind and cone.
    pub kind: LightKind,
    /// Linear RGB colour × intensity.
    pub intensity: Vec3,
    /// Position (world).
    pub position: Vec3,
    /// Direction the light points to (world, unit): the node's −Z.
    pub direction: Vec3,
    /// Range cut-off (metres), if any.
    pub range: Option<f32>,
    /// Radius of a point or spot light's sphere (metres; the node's
    /// `extras.radbake.radius`): soft shadows. 0: a delta light.
    pub radius: f32,
    /// Angular diameter of a directional light's disk (radians; the node's
    /// `extras.radbake.angle`, given in degrees: the real sun's is 0.53°):
    /// soft shadows. 0: a delta light.
    pub angle: f32,
    /// The light layer (the node's `extras.radbake.layer`; `None`: the
    /// layer `static`). See [`crate::scene::layers`].
    pub layer: Option<String>,
    /// A live sun's path (the node's `extras.radbake.sun_path`): the
    /// directions its sun table is made for (`None`: the hemisphere's grid).
    pub sun_path: Option<sun_path::SunPath>,
}

impl Light {
    /// A delta light (no size) in mode `baked`, of no node.
    pub fn delta(
        name: &str,
        kind: LightKind,
        intensity: Vec3,
        position: Vec3,
        direction: Vec3,
    ) -> Light {
        Light {
            name: name.to_owned(),
            node: name.to_owned(),
            node_index: 0,
            mode: LightMode::Baked,
            node_mode: None,
            kind,
            intensity,
            position,
            direction,
            range: None,
            radius: 0.0,
            angle: 0.0,
            sun_path: None,
            layer: None,
        }
    }

    /// True for a light with a size (a sphere or a sun disk), whose shadows
    /// are soft.
    pub fn has_extent(&self) -> bool {
        match self.kind {
            LightKind::Directional => self.angle > 0.0,
            LightKind::Point | LightKind::Spot { .. } => self.radius > 0.0,
        }
    }

    /// True for a point or spot light: a local light, whose irradiance
    /// varies as 1/r² near it (a directional light's only with shadows).
    pub fn is_local(&self) -> bool {
        !matches!(self.kind, LightKind::Directional)
    }
}

/// A perspective camera placed in the world.
#[derive(Clone, Debug)]
pub struct Camera {
    /// The node's name.
    pub name: String,
    /// Camera to world transform (looks down −Z).
    pub world_from_camera: Mat4,
    /// Vertical field of view (radians).
    pub yfov: f32,
    /// Aspect ratio, if the file gives one.
    pub aspect_ratio: Option<f32>,
}

/// Counts the importer reports.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ImportStats {
    /// Zero-area or repeated-index triangles dropped.
    pub degenerate_triangles: u64,
    /// Point and line primitives skipped.
    pub skipped_primitives: u64,
    /// Triangle primitives whose index count does not fit their mode
    /// (trailing indices dropped, with a warning).
    pub malformed_primitives: u64,
}

/// The file as written, kept for outputs that round-trip it (the baked glTF)
/// and for the bake's content hash.
#[derive(Clone, Debug, Default)]
pub struct SourceDocument {
    /// The glTF JSON document.
    pub json: serde_json::Value,
    /// Every buffer's bytes.
    pub buffers: Vec<Vec<u8>>,
    /// Every image's encoded bytes and MIME type.
    pub images: Vec<Option<(Vec<u8>, String)>>,
    /// External files read (buffers, images), resolved.
    pub files: Vec<std::path::PathBuf>,
}

/// The imported scene.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// The source document (None for scenes built in code).
    pub source: Option<SourceDocument>,
    /// Meshes in local space.
    pub meshes: Vec<Mesh>,
    /// Node instances of the meshes.
    pub instances: Vec<Instance>,
    /// Instances of nodes marked `extras.radbake.dynamic`: left out of the
    /// bake (no lightmap, no shadow), lit by the probes.
    pub dynamic: Vec<Instance>,
    /// Probe boxes placed as nodes with `extras.radbake.probe_volume`.
    pub probe_volumes: Vec<crate::scene::probe_volume::VolumeSpec>,
    /// Materials; the last one may be [`Material::fallback`].
    pub materials: Vec<Material>,
    /// Decoded textures.
    pub textures: Vec<Texture>,
    /// Punctual lights.
    pub lights: Vec<Light>,
    /// Cameras.
    pub cameras: Vec<Camera>,
    /// Non-fatal problems found on import.
    pub warnings: Vec<String>,
    /// Import counters.
    pub stats: ImportStats,
}

impl Scene {
    /// True when some material emits or some light shines.
    pub fn has_emitters(&self) -> bool {
        !self.lights.is_empty()
            || self.instances.iter().any(|inst| {
                let mesh = &self.meshes[inst.mesh as usize];
                mesh.triangle_material
                    .iter()
                    .any(|&m| self.materials[m as usize].is_emissive())
            })
    }

    /// Albedo of `material` at texture coordinate `uv0` (linear RGB), and its alpha.
    pub fn albedo_at(&self, material: u32, uv0: Vec2) -> (Vec3, f32) {
        self.albedo_level(material, uv0, &Mips::default(), 0)
    }

    /// [`Scene::albedo_at`] from mipmap `level` of the texture (`mips`:
    /// this scene's; [`Texture::sample_level`]).
    pub fn albedo_level(&self, material: u32, uv0: Vec2, mips: &Mips, level: u32) -> (Vec3, f32) {
        let m = &self.materials[material as usize];
        match &m.albedo_texture {
            Some(t) => {
                let texel = self.textures[t.texture as usize].sample_level(
                    mips,
                    t.texture,
                    t.transform_uv(uv0),
                    level,
                );
                (m.albedo * texel.truncate(), m.alpha_factor * texel.w)
            }
            None => (m.albedo, m.alpha_factor),
        }
    }

    /// Emitted radiance of `material` at `uv0` (linear RGB).
    pub fn emission_at(&self, material: u32, uv0: Vec2) -> Vec3 {
        self.emission_level(material, uv0, &Mips::default(), 0)
    }

    /// [`Scene::emission_at`] from mipmap `level` of the texture.
    pub fn emission_level(&self, material: u32, uv0: Vec2, mips: &Mips, level: u32) -> Vec3 {
        let m = &self.materials[material as usize];
        match &m.emission_texture {
            Some(t) if m.is_emissive() => {
                m.emission
                    * self.textures[t.texture as usize]
                        .sample_level(mips, t.texture, t.transform_uv(uv0), level)
                        .truncate()
            }
            _ => m.emission,
        }
    }

    /// True when the surface of `material` at `uv0` is cut out (transparent).
    pub fn is_cut_out(&self, material: u32, uv0: Vec2) -> bool {
        match self.materials[material as usize].alpha {
            Alpha::Opaque => false,
            Alpha::Mask { cutoff } => self.albedo_at(material, uv0).1 < cutoff,
        }
    }
}
