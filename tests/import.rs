//! Import features exercised through whole bakes with known answers:
//! transforms (TRS, matrix, mirroring), instancing, strips and fans, textures
//! with `KHR_texture_transform`, emissive strength, `--uv existing`.

mod common;

use base64::Engine as _;
use common::*;
use radbake::radiosity::form_factors::analytic;
use radbake::{BakeConfig, Silent};
use serde_json::json;

fn config() -> BakeConfig {
    BakeConfig {
        texels_per_meter: 48.0,
        patch_texels: 2,
        rays_per_patch: 1024,
        ..BakeConfig::default()
    }
}

fn bake_means(
    path: &std::path::Path,
    config: &BakeConfig,
) -> Vec<(String, [f32; 3], u64, [f32; 4])> {
    let scene = radbake::scene::load(path, &Default::default()).unwrap();
    let bake = radbake::bake(&scene, config, &Silent).unwrap();
    bake.instance_reports()
        .into_iter()
        .map(|r| (r.node, r.mean, r.texels, r.uv_rect))
        .collect()
}

/// The parallel plates built from one unit quad mesh placed twice: once by a
/// TRS node, once by a mirroring matrix node (negative determinant, so the
/// winding must flip to keep the emitter facing down). Receiver mean = C-11.
#[test]
fn instancing_trs_and_mirrored_matrix() {
    let dir = temp_dir("import-instancing");
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    // Unit quad in the xz plane facing +y, centred on the origin.
    let (p, i) = quad([-0.5, 0.0, -0.5], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(emit));
    let mut doc = b.json();
    // Receiver: same mesh, black via a second mesh entry sharing accessors.
    let mut receiver_mesh = doc["meshes"][0].clone();
    receiver_mesh["primitives"][0]["material"] = json!(1);
    doc["materials"]
        .as_array_mut()
        .unwrap()
        .push(json!({"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}}));
    doc["meshes"].as_array_mut().unwrap().push(receiver_mesh);
    doc["nodes"] = json!([
        // Receiver scaled ×2 by its parent and ×0.5 by itself: a TRS chain.
        {"name": "parent", "scale": [2.0, 2.0, 2.0], "children": [1]},
        {"name": "receiver", "mesh": 1, "scale": [0.5, 0.5, 0.5], "rotation": [0.0, std::f32::consts::FRAC_1_SQRT_2, 0.0, std::f32::consts::FRAC_1_SQRT_2]},
        // Emitter: mirrored in y (det < 0) and lifted to y = 1: faces down.
        {"name": "emitter", "mesh": m, "matrix": [1,0,0,0, 0,-1,0,0, 0,0,1,0, 0,1,0,1]},
    ]);
    doc["scenes"] = json!([{"nodes": [0, 2]}]);
    let path = dir.join("instanced.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let means = bake_means(&path, &config());
    let recv = means.iter().find(|m| m.0 == "receiver").unwrap();
    let want = analytic::parallel_rectangles(1.0, 1.0, 1.0);
    assert!(
        ((recv.1[0] as f64) - want).abs() / want < 0.02,
        "receiver {:?} vs {want}",
        recv.1
    );
    assert!(recv.2 > 0);
}

/// One mesh drawn by three nodes: three instances with their own texels and
/// disjoint rectangles, each lit by its own emitter above it.
#[test]
fn shared_mesh_gets_one_rect_per_instance() {
    let dir = temp_dir("import-shared");
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let emit = b.material([0.0; 3], [1.0; 3]);
    let (p, i) = quad([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    let floor = b.mesh(&p, &i, Some(grey));
    let (p, i) = quad([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let lamp = b.mesh(&p, &i, Some(emit));
    let mut doc = b.json();
    doc["nodes"] = json!([
        {"name": "a", "mesh": floor},
        {"name": "b", "mesh": floor, "translation": [5.0, 0.0, 0.0]},
        {"name": "c", "mesh": floor, "translation": [10.0, 0.0, 0.0]},
        {"name": "lamp_a", "mesh": lamp},
        {"name": "lamp_b", "mesh": lamp, "translation": [5.0, 0.0, 0.0]},
        {"name": "lamp_c", "mesh": lamp, "translation": [10.0, 0.0, 0.0]},
    ]);
    doc["scenes"] = json!([{"nodes": [0, 1, 2, 3, 4, 5]}]);
    let path = dir.join("shared.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let means = bake_means(&path, &config());
    let floors: Vec<_> = means.iter().filter(|m| m.0.len() == 1).collect();
    assert_eq!(floors.len(), 3);
    let want = analytic::parallel_rectangles(1.0, 1.0, 1.0);
    for f in &floors {
        assert!(f.2 > 0);
        assert!(
            ((f.1[0] as f64) - want).abs() / want < 0.03,
            "{} {:?}",
            f.0,
            f.1
        );
    }
    for (k, a) in floors.iter().enumerate() {
        for b in floors.iter().skip(k + 1) {
            let (ra, rb) = (a.3, b.3);
            let disjoint = ra[2] <= rb[0] || rb[2] <= ra[0] || ra[3] <= rb[1] || rb[3] <= ra[1];
            assert!(disjoint, "{ra:?} and {rb:?} overlap");
        }
    }
}

/// The receiver written as a TRIANGLE_STRIP and the emitter as a
/// TRIANGLE_FAN, non-indexed: same answer as the plain lists.
#[test]
fn strips_and_fans() {
    let dir = temp_dir("import-strips");
    let mut b = GltfBuilder::default();
    let emit = b.material([0.0; 3], [1.0; 3]);
    let black = b.material([0.0; 3], [0.0; 3]);
    // Strip 0,1,3,2 of the receiver quad (facing +y); fan of the emitter (facing −y).
    let recv = b.vec3(&[
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 1.0],
    ]);
    let lamp = b.vec3(&[
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ]);
    let mut doc = b.json();
    doc["meshes"] = json!([
        {"primitives": [{"attributes": {"POSITION": recv}, "mode": 5, "material": black}]},
        {"primitives": [{"attributes": {"POSITION": lamp}, "mode": 6, "material": emit}]},
    ]);
    doc["nodes"] = json!([{"name": "receiver", "mesh": 0}, {"name": "emitter", "mesh": 1}]);
    doc["scenes"] = json!([{"nodes": [0, 1]}]);
    let path = dir.join("strips.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let means = bake_means(&path, &config());
    let recv = means.iter().find(|m| m.0 == "receiver").unwrap();
    let want = analytic::parallel_rectangles(1.0, 1.0, 1.0);
    assert!(
        ((recv.1[0] as f64) - want).abs() / want < 0.02,
        "{:?}",
        recv.1
    );
}

/// A uniform texture as a data-URI PNG.
fn png_data_uri(rgba: [u8; 4]) -> String {
    let img = image::RgbaImage::from_pixel(4, 4, image::Rgba(rgba));
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// The furnace box with its albedo from an sRGB base colour texture (through
/// a `KHR_texture_transform`) times a factor, and its emission from an
/// emissive texture × strength: B = E/(1 − ρ) with ρ and E decoded from sRGB.
#[test]
fn textured_furnace() {
    let dir = temp_dir("import-texture");
    let text = std::fs::read_to_string(scene_path("furnace_box.gltf")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["images"] = json!([{"uri": png_data_uri([200, 200, 200, 255])}, {"uri": png_data_uri([128, 128, 128, 255])}]);
    doc["textures"] = json!([{"source": 0}, {"source": 1}]);
    doc["extensionsUsed"] = json!(["KHR_texture_transform", "KHR_materials_emissive_strength"]);
    let m = &mut doc["materials"][0];
    m["pbrMetallicRoughness"]["baseColorFactor"] = json!([0.8, 0.8, 0.8, 1.0]);
    m["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.3, 0.1], "scale": [3.0, 2.0], "rotation": 0.5}}});
    m["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    m["emissiveTexture"] = json!({"index": 1});
    m["extensions"] = json!({"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}});
    let path = dir.join("textured.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let rho = 0.8 * radbake::scene::texture::srgb_to_linear(200.0 / 255.0);
    let e = 2.0 * radbake::scene::texture::srgb_to_linear(128.0 / 255.0);
    let want = e / (1.0 - rho);
    let cfg = BakeConfig {
        texels_per_meter: 16.0,
        ..config()
    };
    for (node, mean, texels, _) in bake_means(&path, &cfg) {
        assert!(texels > 0);
        assert!(
            (mean[0] - want).abs() / want < 0.005,
            "{node}: {mean:?} vs {want}"
        );
    }
}

/// The furnace box with an albedo texture far finer than the lightmap: a
/// one-pixel checker of two sRGB greys, about 18 pixels to a texel side and
/// not aligned with the texels. Seen from anywhere, the walls reflect with
/// their mean albedo ρ̄, so B = E/(1 − ρ̄) at every texel. Tolerances: the
/// mean within 0.5 %, texel RMS within 0.5 %, every texel that is not a
/// sliver within 2.5 % (measured: 0.08 %, 0.16 %, 1.5 %; texels beside an
/// edge gather from few texels of the next wall, each with its own 16-point
/// estimate of ρ̄).
#[test]
fn fine_checker_furnace() {
    let dir = temp_dir("import-checker");
    let path = dir.join("checker.gltf");
    let text = std::fs::read_to_string(scene_path("furnace_box.gltf")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (dark, light) = (100u8, 210u8);
    let img = image::RgbaImage::from_fn(64, 64, |x, y| {
        let g = if (x + y) % 2 == 0 { dark } else { light };
        image::Rgba([g, g, g, 255])
    });
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let uri = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&png)
    );
    doc["images"] = json!([{ "uri": uri }]);
    doc["samplers"] =
        json!([{"magFilter": 9729, "minFilter": 9729, "wrapS": 10497, "wrapT": 10497}]);
    doc["textures"] = json!([{"source": 0, "sampler": 0}]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = json!([1.0, 1.0, 1.0, 1.0]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    // TEXCOORD_0: each face's two in-plane coordinates × 4 (8 repeats of
    // the 64-pixel checker over the 2 m face: 3.9 mm pixels).
    let scene = radbake::scene::load(&scene_path("furnace_box.gltf"), &Default::default()).unwrap();
    let mesh = &scene.meshes[0];
    let uvs: Vec<[f32; 2]> = mesh
        .positions
        .chunks(4)
        .flat_map(|face| {
            let span = (face[0] - face[2]).abs();
            let axis = if span.x < 1e-6 {
                0
            } else if span.y < 1e-6 {
                1
            } else {
                2
            };
            let (a, b) = [(1, 2), (0, 2), (0, 1)][axis];
            face.iter()
                .map(move |p| [p[a] * 4.37, p[b] * 4.37])
                .collect::<Vec<_>>()
        })
        .collect();
    let acc = append_vec2_accessor(&mut doc, &uvs);
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(acc);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();

    let srgb = |g: u8| radbake::scene::texture::srgb_to_linear(g as f32 / 255.0);
    let rho = 0.5 * (srgb(dark) + srgb(light));
    let e = 1.0; // the furnace's emission
    let want = e / (1.0 - rho);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let cfg = BakeConfig {
        texels_per_meter: 16.0,
        ..BakeConfig::default()
    };
    let bake = radbake::bake(&scene, &cfg, &Silent).unwrap();
    let values = &bake.maps.lightmaps.texel_values;
    let mean = values.iter().map(|v| v[0]).sum::<f32>() / values.len() as f32;
    // Slivers (texels a face's edge barely enters) are left out of the worst.
    let full = 1.0 / (cfg.texels_per_meter * cfg.texels_per_meter);
    let worst = values
        .iter()
        .zip(&bake.texels.area)
        .filter(|(_, &a)| a > 0.25 * full)
        .map(|(v, _)| (v[0] - want).abs() / want)
        .fold(0.0f32, f32::max);
    let rms = (values
        .iter()
        .map(|v| ((v[0] - want) / want).powi(2))
        .sum::<f32>()
        / values.len() as f32)
        .sqrt();
    eprintln!(
        "checker furnace: want {want}, mean {mean}, worst texel {:.3} %, RMS {:.3} %",
        worst * 100.0,
        rms * 100.0
    );
    assert!((mean - want).abs() / want < 0.005, "mean {mean} vs {want}");
    // The footprint samples read the mipmap level as coarse as they are
    // apart, so each texel's ρ̄ is the box mean itself (16 bilinear samples
    // of the full-size checker gave 0.16 % RMS and 1.2 % at worst).
    assert!(rms < 0.001, "texel RMS {:.3} %", rms * 100.0);
    assert!(worst < 0.005, "worst texel off by {:.3} %", worst * 100.0);
}

/// `--uv existing`: the plates with their own TEXCOORD_1 give the same answer.
#[test]
fn existing_uvs_are_repacked() {
    let dir = temp_dir("import-uv1");
    let text = std::fs::read_to_string(scene_path("parallel_plates.gltf")).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let path = dir.join("plates.gltf");
    // Give every primitive a TEXCOORD_1 equal to its positions' xz (a valid chart).
    let scene =
        radbake::scene::load(&scene_path("parallel_plates.gltf"), &Default::default()).unwrap();
    let mut doc = doc;
    for mesh in &scene.meshes {
        let uvs: Vec<[f32; 2]> = mesh.positions.iter().map(|p| [p.x, p.z]).collect();
        let acc = append_vec2_accessor(&mut doc, &uvs);
        for prim in doc["meshes"][mesh.gltf_index]["primitives"]
            .as_array_mut()
            .unwrap()
        {
            prim["attributes"]["TEXCOORD_1"] = json!(acc);
        }
    }
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let cfg = BakeConfig {
        uv: radbake::config::UvSource::Existing,
        ..config()
    };
    let means = bake_means(&path, &cfg);
    let recv = means.iter().find(|m| m.0 == "receiver").unwrap();
    let want = analytic::parallel_rectangles(1.0, 1.0, 1.0);
    assert!(
        ((recv.1[0] as f64) - want).abs() / want < 0.02,
        "{:?}",
        recv.1
    );
    // Without TEXCOORD_1, `existing` is refused naming the key.
    let scene =
        radbake::scene::load(&scene_path("parallel_plates.gltf"), &Default::default()).unwrap();
    let err = radbake::bake(&scene, &cfg, &Silent).err().expect("refused");
    assert!(err.to_string().contains("uv"), "{err}");
}

/// A TRIANGLES primitive whose index count is not a multiple of 3 is baked
/// without its trailing indices, never silently: a warning names the mesh
/// and primitive, and `report.json` counts it.
#[test]
fn malformed_index_counts_are_warned_and_counted() {
    let mut g = GltfBuilder::default();
    let m = g.material([0.5; 3], [1.0; 3]);
    let (p, mut idx) = quad([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    idx.push(1); // 7 indices
    let mesh = g.mesh(&p, &idx, Some(m));
    g.meshes[mesh]["name"] = serde_json::json!("panel");
    g.node("panel", mesh);
    let path = temp_dir("malformed_indices").join("scene.gltf");
    g.write(&path);
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let bake = radbake::bake(&scene, &BakeConfig::default(), &Silent).unwrap();
    let report = bake.report("scene.gltf");
    assert_eq!(report.counts.malformed_primitives, 1);
    assert_eq!(report.counts.triangles, 2, "the whole triangles are kept");
    let w: Vec<_> = report
        .warnings
        .iter()
        .filter(|w| w.contains("not a multiple of 3"))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", report.warnings);
    assert!(
        w[0].contains("meshes[0].primitives[0]") && w[0].contains("panel"),
        "{}",
        w[0]
    );
}

/// Attributes of one primitive whose counts disagree (a NORMAL accessor
/// shorter than POSITION) are refused with one line naming the file and
/// the primitive, never baked with a guess.
#[test]
fn disagreeing_attribute_counts_are_refused() {
    let mut g = GltfBuilder::default();
    let m = g.material([0.5; 3], [1.0; 3]);
    let (p, idx) = quad([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let mesh = g.mesh(&p, &idx, Some(m));
    let normals = g.vec3(&[[0.0, 0.0, 1.0]; 3]);
    g.meshes[mesh]["primitives"][0]["attributes"]["NORMAL"] = json!(normals);
    g.node("panel", mesh);
    let path = temp_dir("attribute_counts").join("scene.gltf");
    g.write(&path);
    let err = radbake::scene::load(&path, &Default::default())
        .expect_err("refused")
        .to_string();
    assert!(err.contains("scene.gltf"), "{err}");
    assert!(err.contains("meshes[0].primitives[0]"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}
