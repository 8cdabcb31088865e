//! The lightmap atlas (the only file that uses `uvunwrap`).
//!
//! Each scene mesh is unwrapped once (charts never span two materials) and
//! every instance of it gets its own rectangle at a fixed texel density,
//! scaled by the instance's uniform scale: a vertex's atlas coordinate is
//! `rect.min + uv · (rect.max − rect.min)`, Bevy's `Lightmap::uv_rect`
//! convention. `--uv existing` repacks the input `TEXCOORD_1` islands instead.

use crate::config::{BakeConfig, Packing, UvSource};
use crate::error::{Error, Result};
use crate::scene::Scene;
use glam::Vec2;

/// One mesh's unwrap: its triangles re-indexed onto new vertices (split at
/// chart seams), each with its input vertex (`xref`), its UV in `[0, 1]` of
/// each instance rectangle, and its chart.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct MeshUnwrap {
    /// Input vertex of each output vertex.
    pub xref: Vec<u32>,
    /// UV in `[0, 1]` of the instance rectangle.
    pub uv: Vec<Vec2>,
    /// Chart of each output vertex (`u32::MAX`: none).
    pub chart: Vec<u32>,
    /// Same triangles as the mesh, indexing the output vertices.
    pub triangles: Vec<[u32; 3]>,
}

/// Where one instance lives in the atlas.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InstanceRect {
    /// Atlas page.
    pub page: u32,
    /// Corner with the smallest coordinates, in `[0, 1]` page coordinates.
    pub min: [f32; 2],
    /// Opposite corner.
    pub max: [f32; 2],
}

impl InstanceRect {
    /// Atlas texel coordinate (not normalised) of a UV in this rectangle.
    pub fn to_texels(self, uv: Vec2, width: u32, height: u32) -> Vec2 {
        let min = Vec2::from(self.min);
        let max = Vec2::from(self.max);
        (min + uv * (max - min)) * Vec2::new(width as f32, height as f32)
    }
}

/// The lightmap atlas.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Atlas {
    /// Page width (texels).
    pub width: u32,
    /// Page height (texels).
    pub height: u32,
    /// Number of pages.
    pub page_count: u32,
    /// Texel density used (texels per metre).
    pub texels_per_meter: f32,
    /// Number of charts (per mesh layout, not counting instances).
    pub chart_count: u32,
    /// Fraction of the atlas covered by charts.
    pub utilization: f32,
    /// Per scene mesh.
    pub meshes: Vec<MeshUnwrap>,
    /// Per scene instance.
    pub instances: Vec<InstanceRect>,
    /// Density lowered to respect `max_texels`, and why.
    pub warnings: Vec<String>,
}

/// Longest lightmap side any engine loads (and past which `uvunwrap`'s packer
/// misbehaves): a triangle longer than this in texels cannot be packed.
pub const MAX_CHART_TEXELS: f32 = 16384.0;

/// Refuses a triangle whose longest edge, at its instance's scale and the
/// texel density, is longer than [`MAX_CHART_TEXELS`] (a 2000 km sliver
/// from a broken export, say), naming the mesh and triangle.
fn check_chart_extent(scene: &Scene, scales: &[Vec<f32>], density: f32) -> Result<()> {
    for (m, mesh) in scene.meshes.iter().enumerate() {
        let Some(scale) = scales[m].iter().copied().reduce(f32::max) else {
            continue;
        };
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let p = tri.map(|i| mesh.positions[i as usize]);
            let edge = [p[1] - p[0], p[2] - p[1], p[0] - p[2]]
                .iter()
                .map(|e| e.length())
                .fold(0.0f32, f32::max);
            let texels = edge * scale * density;
            if texels.is_nan() || texels > MAX_CHART_TEXELS {
                return Err(Error::Limit(format!(
                    "meshes[{}].primitives[{}] (`{}`): a triangle with a {:.3e} m edge is {:.3e} texels long at {density} texels/m, over the {MAX_CHART_TEXELS}-texel lightmap limit",
                    mesh.gltf_index,
                    mesh.triangle_primitive.get(t).copied().unwrap_or(0),
                    mesh.name,
                    edge * scale,
                    texels
                )));
            }
        }
    }
    Ok(())
}

/// Unwraps every mesh of `scene` and packs every instance.
///
/// # Errors
/// [`Error::Unwrap`] when `uvunwrap` fails; [`Error::Config`] when
/// `--uv existing` is asked for and a mesh has no `TEXCOORD_1`.
pub fn unwrap(scene: &Scene, config: &BakeConfig) -> Result<Atlas> {
    let mut warnings = Vec::new();
    let (mesh_instances, scales) = instances_by_mesh(scene);
    let density = fit_density(scene, &scales, config, &mut warnings);
    check_chart_extent(scene, &scales, density)?;
    let out = run_unwrapper(scene, &scales, density, config)?;
    Ok(to_atlas(scene, &mesh_instances, out, warnings))
}

/// Each mesh's instances and their scales in the atlas: the transform's
/// uniform scale times the node's `texel_scale` (its charts are that much
/// larger in texels; the texel budget counts them so).
fn instances_by_mesh(scene: &Scene) -> (Vec<Vec<usize>>, Vec<Vec<f32>>) {
    let mut mesh_instances: Vec<Vec<usize>> = vec![Vec::new(); scene.meshes.len()];
    for (i, inst) in scene.instances.iter().enumerate() {
        mesh_instances[inst.mesh as usize].push(i);
    }
    let scales = mesh_instances
        .iter()
        .map(|list| {
            list.iter()
                .map(|&i| scene.instances[i].uniform_scale() * scene.instances[i].texel_scale)
                .collect()
        })
        .collect();
    (mesh_instances, scales)
}

/// The texel density: `texels_per_meter`, lowered (with a warning) when the
/// surface would need more than `max_texels`.
fn fit_density(
    scene: &Scene,
    scales: &[Vec<f32>],
    config: &BakeConfig,
    warnings: &mut Vec<String>,
) -> f32 {
    let mut area = 0.0f64;
    for (m, mesh) in scene.meshes.iter().enumerate() {
        let local: f64 = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| mesh.positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64
            })
            .sum();
        area += scales[m]
            .iter()
            .map(|s| local * (*s as f64).powi(2))
            .sum::<f64>();
    }
    let density = config.texels_per_meter;
    // Packing leaves about a third of the atlas empty.
    let estimate = area * (density as f64).powi(2) / 0.6;
    if estimate <= config.max_texels as f64 {
        return density;
    }
    let lowered = (config.max_texels as f64 * 0.6 / area).sqrt() as f32;
    warnings.push(format!(
        "texels_per_meter {density} would need ~{:.1} M texels for {area:.0} m² of surface; lowered to {lowered:.2} to stay within max_texels = {} (set either to choose)",
        estimate / 1e6,
        config.max_texels
    ));
    lowered
}

/// `uvunwrap` over every mesh (existing `TEXCOORD_1` repacked with `uv =
/// existing`), at `density`.
///
/// # Errors
/// A mesh without `TEXCOORD_1` under `uv = existing`; the unwrapper's
/// failure (or panic, which is caught).
fn run_unwrapper(
    scene: &Scene,
    scales: &[Vec<f32>],
    density: f32,
    config: &BakeConfig,
) -> Result<uvunwrap::Atlas> {
    let positions: Vec<Vec<[f32; 3]>> = scene
        .meshes
        .iter()
        .map(|m| m.positions.iter().map(|p| p.to_array()).collect())
        .collect();
    let indices: Vec<Vec<u32>> = scene
        .meshes
        .iter()
        .map(|m| m.triangles.iter().flatten().copied().collect())
        .collect();
    let uv1: Vec<Option<Vec<[f32; 2]>>> = scene
        .meshes
        .iter()
        .map(|m| {
            m.uv1
                .as_ref()
                .map(|u| u.iter().map(|v| v.to_array()).collect())
        })
        .collect();
    let mut inputs = Vec::with_capacity(scene.meshes.len());
    for (m, mesh) in scene.meshes.iter().enumerate() {
        let existing_uvs = match config.uv {
            UvSource::Unwrap => None,
            UvSource::Existing => Some(uv1[m].as_deref().ok_or_else(|| Error::Config {
                key: "uv".into(),
                message: format!(
                    "`existing` needs TEXCOORD_1, but mesh `{}` has none",
                    mesh.name
                ),
            })?),
        };
        inputs.push(uvunwrap::MeshInput {
            face_materials: Some(&mesh.triangle_material),
            instance_scales: &scales[m],
            existing_uvs,
            ..uvunwrap::MeshInput::new(&positions[m], &indices[m])
        });
    }
    let options = uvunwrap::Options {
        density: uvunwrap::Density::Fixed {
            texels_per_unit: density,
            page_size: None,
        },
        padding: config.padding,
        // BC6H pages (`--ktx2 bc6h`): charts on whole 4 × 4 blocks, no
        // block shared by two charts, page sizes multiples of 4 (as block
        // compression and WebGPU's texture sizes need).
        block_align: config.ktx2 == crate::config::Ktx2Mode::Bc6h,
        packing: match config.packing {
            Packing::Fast => uvunwrap::Packing::Fast,
            Packing::Shape => uvunwrap::Packing::Shape,
        },
        ..uvunwrap::Options::default()
    };
    // A safety net: `uvunwrap` has been seen to panic on geometry the checks
    // above do not catch (found by fuzzing); turn that into an error.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        uvunwrap::generate(&inputs, &options)
    }))
    .map_err(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Error::Unwrap(format!("the unwrapper failed on this geometry ({why})"))
    })?
    .map_err(|e| Error::Unwrap(e.to_string()))
}

/// The unwrapper's output as radbake's [`Atlas`]: per mesh its vertices'
/// UVs, charts and source vertices; per instance its page rectangle.
fn to_atlas(
    scene: &Scene,
    mesh_instances: &[Vec<usize>],
    out: uvunwrap::Atlas,
    warnings: Vec<String>,
) -> Atlas {
    let mut instances = vec![
        InstanceRect {
            page: 0,
            min: [0.0; 2],
            max: [0.0; 2]
        };
        scene.instances.len()
    ];
    let mut meshes = Vec::with_capacity(out.meshes.len());
    for (m, om) in out.meshes.iter().enumerate() {
        for (k, &inst) in mesh_instances[m].iter().enumerate() {
            let r = om.instances[k];
            instances[inst] = InstanceRect {
                page: r.page,
                min: r.min,
                max: r.max,
            };
        }
        meshes.push(MeshUnwrap {
            xref: om.vertices.iter().map(|v| v.xref).collect(),
            uv: om.vertices.iter().map(|v| Vec2::from(v.uv)).collect(),
            chart: om
                .vertices
                .iter()
                .map(|v| v.chart.unwrap_or(u32::MAX))
                .collect(),
            triangles: om
                .indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        });
    }
    Atlas {
        width: out.width,
        height: out.height,
        page_count: out.page_count,
        texels_per_meter: out.texels_per_unit,
        chart_count: out.chart_count,
        utilization: out.utilization,
        meshes,
        instances,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Instance, Material, Mesh};
    use glam::{Mat4, Vec3};

    fn cube_mesh() -> Mesh {
        // 6 faces × 2 triangles, split per face (flat normals).
        let mut m = Mesh {
            name: "cube".into(),
            ..Default::default()
        };
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n =
                    Vec3::from_array(std::array::from_fn(|i| if i == axis { sign } else { 0.0 }));
                let (t, b) = crate::util::sampling::frame(n);
                let base = m.positions.len() as u32;
                for (u, v) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    m.positions.push(n + t * u + b * v);
                    m.normals.push(n);
                    m.uv0.push(Vec2::ZERO);
                }
                m.triangles.push([base, base + 1, base + 2]);
                m.triangles.push([base, base + 2, base + 3]);
                m.triangle_material.extend([0, 0]);
            }
        }
        m
    }

    /// Every instance's UVs stay inside its own rectangle, and rectangles
    /// (hence charts of different instances) do not overlap.
    #[test]
    fn instances_get_disjoint_rects() {
        let scene = Scene {
            meshes: vec![cube_mesh()],
            instances: (0..3)
                .map(|i| Instance {
                    node: format!("n{i}"),
                    texel_scale: 1.0,
                    cast_shadows: true,
                    lightmap: true,
                    node_index: i,
                    mesh: 0,
                    world_from_local: Mat4::from_translation(Vec3::X * 3.0 * i as f32),
                })
                .collect(),
            materials: vec![Material::fallback()],
            ..Default::default()
        };
        let config = BakeConfig {
            texels_per_meter: 8.0,
            ..BakeConfig::default()
        };
        let atlas = unwrap(&scene, &config).unwrap();
        let mu = &atlas.meshes[0];
        assert!(mu
            .uv
            .iter()
            .all(|uv| (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y)));
        for (a, ra) in atlas.instances.iter().enumerate() {
            assert!(ra.max[0] > ra.min[0] && ra.max[1] > ra.min[1]);
            for rb in atlas.instances.iter().skip(a + 1) {
                let disjoint = ra.max[0] <= rb.min[0]
                    || rb.max[0] <= ra.min[0]
                    || ra.max[1] <= rb.min[1]
                    || rb.max[1] <= ra.min[1]
                    || ra.page != rb.page;
                assert!(disjoint, "{ra:?} overlaps {rb:?}");
            }
        }
        // Each cube face is 2×2 m at 8 texels/m: about 16 texels across.
        let r = atlas.instances[0];
        let w = (r.max[0] - r.min[0]) * atlas.width as f32;
        assert!(w >= 16.0, "instance rect only {w} texels wide");
    }

    /// The presets are level-scale as well as room-scale: a small scene
    /// keeps `texels_per_meter`, a large one gets the density that fits the
    /// preset's texel budget (and the atlas then holds about that many
    /// texels), ordered preview < medium < production.
    #[test]
    fn presets_fit_large_scenes_to_their_texel_budget() {
        let scene = |scale: f32, count: u32| Scene {
            meshes: vec![cube_mesh()],
            instances: (0..count)
                .map(|i| Instance {
                    node: format!("n{i}"),
                    texel_scale: 1.0,
                    cast_shadows: true,
                    lightmap: true,
                    node_index: i as usize,
                    mesh: 0,
                    world_from_local: Mat4::from_scale_rotation_translation(
                        Vec3::splat(scale),
                        Default::default(),
                        Vec3::X * 3.0 * scale * i as f32,
                    ),
                })
                .collect(),
            materials: vec![Material::fallback()],
            ..Default::default()
        };
        // A room: 2 cubes of 0.5 m, 3 m² in all.
        let room = unwrap(&scene(0.25, 2), &BakeConfig::medium()).unwrap();
        assert_eq!(room.texels_per_meter, BakeConfig::medium().texels_per_meter);
        assert!(room.warnings.is_empty(), "{:?}", room.warnings);
        // A level: 12 cubes of 30 m, 64,800 m² (7.5e8 texels at 116 texels/m).
        let level = scene(15.0, 12);
        let mut densities = Vec::new();
        for config in [
            BakeConfig::preview(),
            BakeConfig::medium(),
            BakeConfig::production(),
        ] {
            let atlas = unwrap(&level, &config).unwrap();
            let texels = atlas.width as f64 * atlas.height as f64 * atlas.page_count as f64;
            let budget = config.max_texels as f64;
            assert!(
                texels <= 1.5 * budget && texels >= 0.4 * budget,
                "{texels} atlas texels for a budget of {budget}"
            );
            assert!(atlas.texels_per_meter < config.texels_per_meter);
            assert_eq!(atlas.warnings.len(), 1, "the lowered density is reported");
            densities.push(atlas.texels_per_meter);
        }
        assert!(densities[0] < densities[1] && densities[1] < densities[2]);
    }
}
