//! The signed distance field (issue #24): `radbake::sdf` against analytic
//! fields, an open box against the closed one, sphere tracing against the
//! BVH's rays, determinism across thread counts, and `radbake sdf`'s
//! files.

mod common;

use common::{quad, scene_path, sphere, temp_dir, GltfBuilder};
use glam::Vec3;
use radbake::sdf::{self, Sdf, Settings};

/// Bakes the field of the scene at `path` with voxels of `voxel` metres.
fn bake(path: &std::path::Path, voxel: f32) -> Sdf {
    let scene = radbake::scene::load(path, &Default::default()).unwrap();
    let g = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &g);
    sdf::bake(&scene, &g, &rays, Settings { voxel, band: None })
}

/// `radbake bake <path> --out <out>` at 4 texels/m without probes, with
/// the field options `sdf`.
fn bake_with_field(path: &std::path::Path, out: &std::path::Path, sdf: &[&str]) {
    let mut args: Vec<std::ffi::OsString> = ["bake", "-q", "--force", "--texels-per-meter", "4"]
        .iter()
        .chain(&["--probes", "off"])
        .chain(sdf)
        .map(Into::into)
        .collect();
    args.extend([path.into(), "--out".into(), out.into()]);
    common::run_ok(args);
}

/// One mesh of `p`, `i` written as a glTF scene `name`.
fn mesh_scene(name: &str, p: &[[f32; 3]], i: &[u32]) -> std::path::PathBuf {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let m = b.mesh(p, i, Some(grey));
    b.node("shape", m);
    let path = temp_dir(name).join("shape.gltf");
    b.write(&path);
    path
}

/// The faces of the box |x|, |y|, |z| ≤ `h`, outward, without the top
/// (+Y) one where `open`.
fn cube(h: f32, open: bool) -> (Vec<[f32; 3]>, Vec<u32>) {
    let s = 2.0 * h;
    let mut faces = vec![
        quad([-h, -h, -h], [s, 0.0, 0.0], [0.0, 0.0, s]),
        quad([h, -h, -h], [0.0, s, 0.0], [0.0, 0.0, s]),
        quad([-h, -h, -h], [0.0, 0.0, s], [0.0, s, 0.0]),
        quad([-h, -h, h], [s, 0.0, 0.0], [0.0, s, 0.0]),
        quad([-h, -h, -h], [0.0, s, 0.0], [s, 0.0, 0.0]),
    ];
    if !open {
        faces.push(quad([-h, h, -h], [0.0, 0.0, s], [s, 0.0, 0.0]));
    }
    let (mut p, mut i) = (Vec::new(), Vec::new());
    for (fp, fi) in faces {
        let base = p.len() as u32;
        p.extend(fp);
        i.extend(fi.iter().map(|k| k + base));
    }
    (p, i)
}

/// A torus about +Y (radii `big`, `small`), `nu` × `nv` quads, outward.
fn torus(big: f32, small: f32, nu: u32, nv: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut p = Vec::new();
    for a in 0..nu {
        let u = a as f32 / nu as f32 * std::f32::consts::TAU;
        for b in 0..nv {
            let v = b as f32 / nv as f32 * std::f32::consts::TAU;
            let r = big + small * v.cos();
            p.push([r * u.cos(), small * v.sin(), r * u.sin()]);
        }
    }
    let mut idx = Vec::new();
    for a in 0..nu {
        for b in 0..nv {
            let k = |a: u32, b: u32| (a % nu) * nv + (b % nv);
            let (p00, p10, p01, p11) = (k(a, b), k(a + 1, b), k(a, b + 1), k(a + 1, b + 1));
            idx.extend([p00, p01, p10, p10, p01, p11]);
        }
    }
    (p, idx)
}

/// Every voxel of `sdf` within `tess` (+ float error) of the analytic
/// field `f` at its centre, and of the sign of `f` wherever |f| > `tess`.
/// Returns the worst error and the voxels whose sign was checked.
fn check_field(sdf: &Sdf, f: impl Fn(Vec3) -> f32, tess: f32) -> (f32, usize) {
    let (mut worst, mut signed) = (0.0f32, 0);
    for i in 0..sdf.grid.len() {
        let c = sdf.grid.centre(i);
        let (want, got) = (f(c), sdf.distance[i]);
        worst = worst.max((got.abs() - want.abs()).abs());
        if want.abs() > tess + 1e-4 {
            assert_eq!(
                got < 0.0,
                want < 0.0,
                "sign at {c}: {got} vs analytic {want}"
            );
            signed += 1;
        }
    }
    assert!(
        worst <= tess + 1e-4,
        "worst distance error {worst} (tessellation {tess})"
    );
    (worst, signed)
}

/// A unit sphere (32 × 64 quads), a box and a torus: every voxel's
/// distance within the tessellation's deviation from the analytic surface
/// (the field is exact at voxel centres), and every sign right where the
/// tessellation leaves no doubt.
#[test]
fn analytic_fields() {
    let voxel = 0.1;
    let (p, i) = sphere(1.0, 32, 64, false);
    let s = bake(&mesh_scene("sdf-sphere", &p, &i), voxel);
    // A facet spans π/32 in θ and in φ: its points lie within
    // 1 − cos(π/32) of the sphere.
    let tess = 1.0 - (std::f32::consts::PI / 32.0).cos();
    let (w, n) = check_field(&s, |c| c.length() - 1.0, tess);
    eprintln!(
        "sphere: {} voxels, worst {w:.5} m (tessellation {tess:.5}), {n} signs",
        s.grid.len()
    );

    let (p, i) = cube(0.75, false);
    let s = bake(&mesh_scene("sdf-box", &p, &i), voxel);
    let boxf = |c: Vec3| {
        let q = c.abs() - Vec3::splat(0.75);
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    };
    let (w, n) = check_field(&s, boxf, 0.0);
    eprintln!("box: {} voxels, worst {w:.6} m, {n} signs", s.grid.len());

    let (big, small) = (1.0, 0.35);
    let (p, i) = torus(big, small, 96, 32);
    let s = bake(&mesh_scene("sdf-torus", &p, &i), voxel);
    // The sagittas of the outer ring (radius big + small) and of the tube.
    let tess = (big + small) * (1.0 - (std::f32::consts::PI / 96.0).cos())
        + small * (1.0 - (std::f32::consts::PI / 32.0).cos());
    let torusf = |c: Vec3| (Vec3::new(c.x, 0.0, c.z).length() - big).hypot(c.y) - small;
    let (w, n) = check_field(&s, torusf, tess);
    eprintln!(
        "torus: {} voxels, worst {w:.5} m (tessellation {tess:.5}), {n} signs",
        s.grid.len()
    );
}

/// A closed box resting on a one-sided floor, its bottom face lying on
/// the floor's (coincident faces back to back, as every object placed on
/// a level's floor): every voxel inside the box or below the floor is
/// negative and every other one positive, farther than half a voxel from
/// the faces. The
/// nearest face is tied there between the floor (seen from above: outside)
/// and the box's bottom (seen from inside: inside), so the voxel votes.
#[test]
fn box_resting_on_a_floor_is_solid() {
    let (wrong, checked) = resting_box_signs("sdf-resting", true);
    eprintln!("resting box: {wrong} wrong signs of {checked}");
    assert!(checked > 10_000);
    assert_eq!(wrong, 0);
}

/// The same box without its bottom face (as the Cornell box's blocks are
/// modelled): inside it, near the floor, the nearest face is the floor
/// seen from its front, and it used to decide alone (outside: 1,050 wrong
/// signs of 139,624). A voxel in front of its nearest face now also casts
/// a ray along that face's normal, and where the ray meets the back of a
/// one-sided face (the box's top, from inside) the voxel votes.
#[test]
fn bottomless_box_standing_on_a_floor_is_solid() {
    let (wrong, checked) = resting_box_signs("sdf-bottomless", false);
    eprintln!("bottomless box: {wrong} wrong signs of {checked}");
    assert!(checked > 10_000);
    assert_eq!(wrong, 0);
}

/// A 1 m box standing on a 4 m one-sided floor (with or without its
/// bottom face), baked at 5 cm voxels: (voxels whose sign is wrong,
/// voxels checked), over the voxels farther than half a voxel from the
/// box's faces and the floor's plane.
fn resting_box_signs(name: &str, bottom: bool) -> (usize, usize) {
    let voxel = 0.05;
    let (mut p, mut i) = cube(0.5, false);
    if !bottom {
        // The first face is the bottom (y = −h).
        i.drain(..6);
    }
    for v in &mut p {
        v[1] += 0.5;
    }
    let (fp, fi) = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]);
    let base = p.len() as u32;
    p.extend(fp);
    i.extend(fi.iter().map(|k| k + base));
    let s = bake(&mesh_scene(name, &p, &i), voxel);
    let (mut wrong, mut checked) = (0, 0);
    for k in 0..s.grid.len() {
        let c = s.grid.centre(k);
        let q = (c - Vec3::new(0.0, 0.5, 0.0)).abs() - Vec3::splat(0.5);
        let boxf = q.max(Vec3::ZERO).length() + q.max_element().min(0.0);
        // Solid: the box, and below the floor (behind its one-sided face).
        let solid = boxf < 0.0 || c.y < 0.0;
        if boxf.abs() > 0.5 * voxel && c.y.abs() > 0.5 * voxel {
            checked += 1;
            wrong += ((s.distance[k] < 0.0) != solid) as usize;
        }
    }
    (wrong, checked)
}

/// A box without its top face: its signs agree with the closed box's
/// everywhere farther than one voxel from the missing face.
#[test]
fn open_box_agrees_with_the_closed_one_away_from_the_hole() {
    let (h, voxel) = (1.0f32, 0.1f32);
    let (closed, open) = closed_and_open_boxes("sdf", h, voxel, |m| m);
    assert_eq!(closed.grid, open.grid);
    let (mut compared, mut near) = (0, 0);
    for k in 0..closed.grid.len() {
        let c = closed.grid.centre(k);
        if near_the_hole(c, h, voxel) {
            near += 1;
            continue;
        }
        compared += 1;
        assert_eq!(
            open.distance[k] < 0.0,
            closed.distance[k] < 0.0,
            "sign at {c}: open {} closed {}",
            open.distance[k],
            closed.distance[k]
        );
    }
    eprintln!("{compared} voxels agree; {near} within a voxel of the hole not compared");
    assert!(compared > 5 * near);
}

/// The box of half-size `h` closed and open (no top face), each passed
/// through `place` (into a room, or as it is), baked at `voxel`.
fn closed_and_open_boxes(
    name: &str,
    h: f32,
    voxel: f32,
    place: impl Fn((Vec<[f32; 3]>, Vec<u32>)) -> (Vec<[f32; 3]>, Vec<u32>),
) -> (Sdf, Sdf) {
    let [closed, open] = [false, true].map(|hole| {
        let (p, i) = place(cube(h, hole));
        let which = if hole { "open" } else { "closed" };
        bake(&mesh_scene(&format!("{name}-{which}"), &p, &i), voxel)
    });
    (closed, open)
}

/// Whether voxel centre `c` lies within a voxel of the open box's missing
/// face (y = h, |x|, |z| ≤ h).
fn near_the_hole(c: Vec3, h: f32, voxel: f32) -> bool {
    let q = Vec3::new(c.x.clamp(-h, h), h, c.z.clamp(-h, h));
    (c - q).length() <= voxel
}

/// The open box of [`open_box_agrees_with_the_closed_one_away_from_the_hole`],
/// hung in a room (a floor 2 m below it,
/// a ceiling 3 m above, 8 m across), where the air above its opening is
/// open air far from any surface: its inside is still solid, as the
/// closed box's, everywhere farther than a voxel from the opening. (A
/// rule that gave each region of open air, joined through the opening,
/// one sign by majority made 4,352 of these voxels free space.)
#[test]
fn open_box_in_a_room_agrees_with_the_closed_one() {
    let (h, voxel) = (1.0f32, 0.1f32);
    let floor = quad([-4.0, -3.0, -4.0], [0.0, 0.0, 8.0], [8.0, 0.0, 0.0]);
    let ceiling = quad([-4.0, 4.0, -4.0], [8.0, 0.0, 0.0], [0.0, 0.0, 8.0]);
    let in_room = |(mut p, mut i): (Vec<[f32; 3]>, Vec<u32>)| {
        for f in [&floor, &ceiling] {
            let base = p.len() as u32;
            p.extend(f.0.clone());
            i.extend(f.1.iter().map(|k| k + base));
        }
        (p, i)
    };
    let (closed, open) = closed_and_open_boxes("sdf-room", h, voxel, in_room);
    let (mut compared, mut differ) = (0, 0);
    for k in 0..closed.grid.len() {
        let c = closed.grid.centre(k);
        if near_the_hole(c, h, voxel) {
            continue;
        }
        compared += 1;
        differ += ((open.distance[k] < 0.0) != (closed.distance[k] < 0.0)) as u32;
    }
    let inside = closed.distance.iter().filter(|d| **d < 0.0).count();
    eprintln!("{compared} voxels compared, {differ} differ; {inside} inside the closed box");
    assert!(inside > 10_000, "{inside} voxels inside");
    assert_eq!(differ, 0);
}

/// Sphere tracing against the BVH on the Cornell box (voxels of 1/128 of
/// its size): 100,000 rays from random points in its open air, in random
/// directions ([`sdf::agreement::random_rays`]); the march hits within one
/// voxel of the BVH's hit (or misses with it) for ≥ 99 % of them, as the
/// issue asks. Measured: 99.793 % with the current march, which does not
/// stop at a steep dip (Merged 22, NoCrossing 32 of the 207 others); before
/// it 99.795 % (97.74 % with the march that stopped
/// within 0.6 voxel of any surface, which stopped 1,825 rays at edges and
/// walls they pass and 408 at sign flips; 99.785 % while the blocks, which
/// have no bottom face, were negative only in a shell inside). The other
/// 205, by [`sdf::agreement::Class`]: 145 stop at a surface they pass
/// within about a quarter voxel of (taken for a sheet); 26 hit about a
/// voxel late; 26 go through a surface with no zero crossing there (most
/// within half a voxel of a wall's or a block's edge); 5 meet their
/// surface at under 11.5°; 3 hit within a voxel of the grid's border.
/// (Sponza at 256 voxels: 97.89 %, see `tools/sdf_agreement.rs`.)
#[test]
fn sphere_tracing_agrees_with_the_bvh() {
    use sdf::agreement::{compare, random_rays, Class};
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let g = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &g);
    let bounds = g.bounds().unwrap();
    let voxel = sdf::voxel_for_resolution(bounds, 128);
    let field = sdf::bake(&scene, &g, &rays, Settings { voxel, band: None });
    let list = random_rays(&field, bounds, 7, 100_000);
    let mut classes = std::collections::BTreeMap::<Class, u32>::new();
    let (mut agree, mut misses) = (0u32, 0u32);
    for &(o, d) in &list {
        let out = compare(&scene, &g, &rays, &field, o, d);
        match out.class {
            None => agree += 1,
            Some(c) => *classes.entry(c).or_default() += 1,
        }
        misses += out.cast.is_none() as u32;
    }
    let share = agree as f64 / list.len() as f64;
    eprintln!(
        "{agree} of {} rays agree ({:.3} %); {misses} BVH misses; the rest: {classes:?}",
        list.len(),
        100.0 * share
    );
    assert!(share >= 0.99);
    // Rays that miss with the BVH, through the box's open front, are
    // counted: the march must find no surface there either.
    assert!(misses > 10_000);
    // A ray in open air is stopped by a sign flip only where the flip
    // looks like a surface (its gradient a unit vector).
    assert!(classes.get(&Class::OpenAir).copied().unwrap_or(0) < 50);
}

/// The same field with 1 and 2 threads, bit for bit; `radbake sdf` writes
/// a KTX2 3D `R32_SFLOAT` texture holding it and the sidecar JSON with
/// its grid; a bad voxel size is a one-line error.
#[test]
fn deterministic_and_written() {
    let (p, i) = sphere(1.0, 16, 32, false);
    let path = mesh_scene("sdf-files", &p, &i);
    let in_pool = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| bake(&path, 0.125))
    };
    let (one, two) = (in_pool(1), in_pool(2));
    assert!(one
        .distance
        .iter()
        .zip(&two.distance)
        .all(|(a, b)| a.to_bits() == b.to_bits()));

    let out = temp_dir("sdf-files-out").join("field.ktx2");
    common::run_ok::<_, std::ffi::OsString>([
        "sdf".into(),
        "-q".into(),
        "--voxel-size".into(),
        "0.125".into(),
        "--out".into(),
        std::ffi::OsString::from(&out),
        std::ffi::OsString::from(&path),
    ]);
    let (h, raw) = common::ktx2_level(&out);
    assert_eq!(h.format, Some(ktx2::Format::R32_SFLOAT));
    assert_eq!(
        [h.pixel_width, h.pixel_height, h.pixel_depth],
        one.grid.dims
    );
    let values = floats(&raw);
    assert_eq!(values, one.distance);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap();
    assert_eq!(json["sdf"]["dims"], serde_json::json!(one.grid.dims));
    assert_eq!(json["sdf"]["voxel_size"], 0.125);

    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(["sdf", "-q", "--voxel-size", "0", "--out"])
        .arg(&out)
        .arg(&path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && stderr.trim().lines().count() == 1,
        "{stderr}"
    );
    assert!(stderr.contains("--voxel-size"), "{stderr}");
}

/// `radbake sdf --format r16f` writes the field as `R16_SFLOAT`: every
/// texel the R32F file's value rounded to a half float (within 2⁻¹¹ of
/// it, 2⁻²⁵ near 0), in a smaller file; the sidecar says which format.
/// `bake --sdf-format r16f` writes the same in `sdf.ktx2` and says so in
/// the manifest; a bad format is an error naming the values.
#[test]
fn r16f_is_the_field_in_half_floats() {
    let (p, i) = sphere(1.0, 16, 32, false);
    let path = mesh_scene("sdf-r16f", &p, &i);
    let dir = temp_dir("sdf-r16f-out");
    let write = |format: &str| {
        let out = dir.join(format!("{format}.ktx2"));
        common::run_ok::<_, std::ffi::OsString>([
            "sdf".into(),
            "-q".into(),
            "--resolution".into(),
            "40".into(),
            "--format".into(),
            format.into(),
            "--out".into(),
            std::ffi::OsString::from(&out),
            std::ffi::OsString::from(&path),
        ]);
        out
    };
    let (full, half) = (write("r32f"), write("r16f"));
    let (h32, raw32) = common::ktx2_level(&full);
    let (h16, raw16) = common::ktx2_level(&half);
    assert_eq!(h16.format, Some(ktx2::Format::R16_SFLOAT));
    assert_eq!(h32.format, Some(ktx2::Format::R32_SFLOAT));
    assert_eq!(
        [h16.pixel_width, h16.pixel_height, h16.pixel_depth],
        [h32.pixel_width, h32.pixel_height, h32.pixel_depth]
    );
    let (f32s, f16s) = (floats(&raw32), halves(&raw16));
    assert_eq!(f32s.len(), f16s.len());
    let mut worst = 0.0f32;
    for (a, b) in f32s.iter().zip(&f16s) {
        let bound = a.abs() / 2048.0 + 2f32.powi(-25);
        assert!((a - b).abs() <= bound, "{a} -> {b}");
        assert_eq!(*a < 0.0, *b < 0.0, "sign of {a} -> {b}");
        worst = worst.max((a - b).abs());
    }
    eprintln!(
        "{} texels; worst half-float error {worst:.2e} m",
        f32s.len()
    );
    assert!(std::fs::metadata(&half).unwrap().len() < std::fs::metadata(&full).unwrap().len());
    let sidecar = |p: &std::path::Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p.with_extension("json")).unwrap()).unwrap()
    };
    assert_eq!(sidecar(&half)["sdf"]["format"], "R16_SFLOAT");
    assert_eq!(sidecar(&full)["sdf"]["format"], "R32_SFLOAT");

    let out = dir.join("bake");
    bake_with_field(&path, &out, &["--sdf", "40", "--sdf-format", "r16f"]);
    let (hb, rawb) = common::ktx2_level(&out.join("sdf.ktx2"));
    assert_eq!(hb.format, Some(ktx2::Format::R16_SFLOAT));
    assert_eq!(halves(&rawb).len(), f16s.len());
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["sdf"]["format"], "R16_SFLOAT");

    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_radbake"))
        .args(["sdf", "-q", "--format", "r8", "--out"])
        .arg(dir.join("bad.ktx2"))
        .arg(&path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success(), "{stderr}");
    assert!(
        stderr.contains("r16f") && stderr.contains("r32f"),
        "{stderr}"
    );
}

/// A closed box (|x|, |y|, |z| ≤ 1), a floor under it and a one-sided wall
/// at x = 1.6 facing it, with one probe volume over [−0.3, 1.3] ×
/// [−0.6, 0.4] × [−1.3, 0.7] (through the box's +x side, short of the
/// wall), written as a glTF scene `name`.
fn volume_scene(name: &str) -> std::path::PathBuf {
    let mut b = GltfBuilder::default();
    let grey = b.material([0.5; 3], [0.0; 3]);
    let (p, i) = cube(1.0, false);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("box", m);
    let (p, i) = quad([-3.0, -1.5, -3.0], [0.0, 0.0, 6.0], [6.0, 0.0, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("floor", m);
    let (p, i) = quad([1.6, -1.5, -3.0], [0.0, 0.0, 6.0], [0.0, 2.5, 0.0]);
    let m = b.mesh(&p, &i, Some(grey));
    b.node("wall", m);
    let mut doc = b.json();
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({
            "name": "volume", "translation": [0.5, -0.1, -0.3], "scale": [1.6, 1.0, 2.0],
            "extras": {"radbake": {"probe_volume": {"spacing": 0.5}}}
        }));
    let n = doc["nodes"].as_array().unwrap().len();
    doc["scenes"][0]["nodes"] = serde_json::json!((0..n).collect::<Vec<_>>());
    let path = temp_dir(name).join("volume.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

/// A field over the probe volume (`--bounds probe-volumes`): its grid is
/// the volume's box with [`sdf::Grid::over`]'s voxel of margin, and its
/// values are the whole scene's field's at the same points (the two grids
/// line up here: the box's corner is whole voxels from the scene's), to
/// 10⁻⁴ m, voxel by voxel and trilinear at random points; distances
/// measure to triangles outside the box (the wall). `radbake sdf
/// --bounds probe-volumes` writes that field; without a probe volume,
/// `--bounds probe-volumes` and `bake --sdf-bounds probe-volumes` are
/// errors naming the option.
#[test]
fn field_over_the_probe_volumes() {
    use radbake::config::SdfBounds;
    let path = volume_scene("sdf-volume");
    let scene = radbake::scene::load(&path, &Default::default()).unwrap();
    let g = radbake::layout::geometry::Geometry::unmapped(&scene);
    let rays = radbake::raycast::RayCaster::new(&scene, &g);
    let voxel = 0.1;
    let settings = Settings { voxel, band: None };
    let whole = sdf::bake(&scene, &g, &rays, settings);
    let (lo, hi) = sdf::bounds(&scene, &g, SdfBounds::ProbeVolumes).unwrap();
    assert!(
        (lo - Vec3::new(-0.3, -0.6, -1.3)).abs().max_element() < 1e-5,
        "{lo}"
    );
    assert!(
        (hi - Vec3::new(1.3, 0.4, 0.7)).abs().max_element() < 1e-5,
        "{hi}"
    );
    let part = sdf::bake_over(&scene, &g, &rays, (lo, hi), settings);
    let gr = part.grid;
    let top = gr.origin + Vec3::from(gr.dims.map(|d| d as f32)) * voxel;
    assert!((gr.origin - (lo - Vec3::splat(voxel))).abs().max_element() < 1e-5);
    assert!(top.cmpge(hi + Vec3::splat(voxel - 1e-5)).all(), "{top}");
    assert!(top.cmplt(hi + Vec3::splat(2.0 * voxel)).all(), "{top}");
    assert!(part.grid.len() * 10 < whole.grid.len());

    let (worst, inside, to_wall) = against_the_whole(&part, &whole, (lo, hi));
    eprintln!(
        "{:?} voxels over the volume ({} over the scene); worst difference {worst:.2e} m; {inside} inside the box, {to_wall} nearest the wall",
        gr.dims,
        whole.grid.len()
    );
    assert!(worst < 1e-4, "worst difference {worst}");
    assert!(inside > 100 && to_wall > 100);

    // `radbake sdf --bounds probe-volumes`.
    let out = temp_dir("sdf-volume-out").join("field.ktx2");
    common::run_ok::<_, std::ffi::OsString>([
        "sdf".into(),
        "-q".into(),
        "--bounds".into(),
        "probe-volumes".into(),
        "--voxel-size".into(),
        "0.1".into(),
        "--out".into(),
        std::ffi::OsString::from(&out),
        std::ffi::OsString::from(&path),
    ]);
    let (h, raw) = common::ktx2_level(&out);
    assert_eq!([h.pixel_width, h.pixel_height, h.pixel_depth], gr.dims);
    assert_eq!(floats(&raw), part.distance);
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap();
    assert_eq!(
        json["sdf"]["origin"],
        serde_json::json!(gr.origin.to_array())
    );
}

/// `part`, a field over `bounds`, against `whole`, the scene's, voxel by
/// voxel (the same centres) and at 1,000 random points (trilinear): the
/// largest difference, the voxels inside the box, and those nearest the
/// wall (outside the box, nearer the wall than the box or the floor).
fn against_the_whole(part: &sdf::Sdf, whole: &sdf::Sdf, (lo, hi): (Vec3, Vec3)) -> (f32, u32, u32) {
    let (gr, voxel) = (&part.grid, part.grid.voxel);
    let shift = (gr.origin - whole.grid.origin) / voxel;
    assert!(
        (shift - shift.round()).abs().max_element() < 1e-3,
        "{shift}"
    );
    let [sx, sy, sz] = shift.round().to_array().map(|v| v as usize);
    let [wx, wy, _] = whole.grid.dims.map(|d| d as usize);
    let (mut worst, mut inside, mut to_wall) = (0.0f32, 0, 0);
    for i in 0..gr.len() {
        let [x, y, z] = gr.xyz(i).map(|v| v as usize);
        let j = (x + sx) + wx * ((y + sy) + wy * (z + sz));
        assert!((gr.centre(i) - whole.grid.centre(j)).length() < 1e-4);
        let (a, b) = (part.distance[i], whole.distance[j]);
        worst = worst.max((a - b).abs());
        inside += (a < 0.0) as u32;
        // Nearer the wall (outside the box) than the box or the floor.
        let c = gr.centre(i);
        to_wall += ((a - (1.6 - c.x)).abs() < 1e-4 && 1.6 - c.x < c.x - 1.0) as u32;
    }
    // At random points, trilinear.
    let mut rng = radbake::util::sampling::Stream::new(3, 5, 0);
    for _ in 0..1000 {
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let p = lo + (hi - lo) * u;
        worst = worst.max((part.sample(p) - whole.sample(p)).abs());
    }
    (worst, inside, to_wall)
}

/// `--bounds probe-volumes` (and the bake's `--sdf-bounds`) on a scene
/// without a probe volume: a one-line error naming the option.
#[test]
fn sdf_bounds_without_probe_volumes_is_an_error() {
    let out = temp_dir("sdf-volume-none-out").join("field.ktx2");
    let (p, i) = sphere(1.0, 8, 16, false);
    let bare = mesh_scene("sdf-volume-none", &p, &i);
    let run = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_radbake"))
            .args(args)
            .arg(&bare)
            .output()
            .unwrap();
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let none = out.with_file_name("none.ktx2");
    let e = run(&[
        "sdf",
        "-q",
        "--bounds",
        "probe-volumes",
        "--out",
        none.to_str().unwrap(),
    ]);
    assert!(
        e.trim().lines().count() == 1 && e.contains("--bounds"),
        "{e}"
    );
    assert!(e.contains("no probe volume"), "{e}");
    let bake_out = out.with_file_name("bake");
    let e = run(&[
        "bake",
        "-q",
        "--force",
        "--sdf",
        "8",
        "--sdf-bounds",
        "probe-volumes",
        "--out",
        bake_out.to_str().unwrap(),
    ]);
    assert!(
        e.contains("sdf_bounds") && e.contains("no probe volume"),
        "{e}"
    );
}

/// `radbake bake --sdf 24` writes `sdf.ktx2` and the manifest's `sdf`
/// entry: the same field as `radbake sdf --resolution 24` (within float
/// rounding: the bake's triangles come through its atlas).
#[test]
fn bake_option_writes_the_field() {
    let (p, i) = sphere(1.0, 16, 32, false);
    let path = mesh_scene("sdf-bake", &p, &i);
    let out = temp_dir("sdf-bake-out");
    bake_with_field(&path, &out, &["--sdf", "24"]);
    let alone = out.join("alone.ktx2");
    common::run_ok::<_, std::ffi::OsString>([
        "sdf".into(),
        "-q".into(),
        "--resolution".into(),
        "24".into(),
        "--out".into(),
        std::ffi::OsString::from(&alone),
        std::ffi::OsString::from(&path),
    ]);
    let read = |p: &std::path::Path| floats(&common::ktx2_level(p).1);
    let (a, b) = (read(&out.join("sdf.ktx2")), read(&alone));
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "worst difference {worst}");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(alone.with_extension("json")).unwrap()).unwrap();
    assert_eq!(manifest["sdf"]["ktx2"], "sdf.ktx2");
    assert_eq!(manifest["sdf"]["dims"], sidecar["sdf"]["dims"]);
    assert_eq!(manifest["sdf"]["bounds_min"], sidecar["sdf"]["bounds_min"]);
}

/// `--integrator sphere-trace` on the Cornell box's bake (a field of 256
/// voxels along its longest side): each pixel's centre ray marched, the
/// surface shaded from the lightmap, against the same shading at the
/// BVH's primary hit: the means within 1 % and ≥ 95 % of pixels within
/// 2 % (the rest lie on silhouettes and edges); the rendered image
/// (16 jittered rays per pixel) against the path-traced final pass: means
/// within 5 % (+2.3 %: the lamp's edge).
#[test]
fn sphere_traced_render_matches_the_bvh() {
    use radbake::trace::render::{render, Integrator, View};
    use radbake::trace::{LightmapLookup, Tracer};
    let scene = radbake::scene::load(&scene_path("cornell_box.gltf"), &Default::default()).unwrap();
    let cfg = radbake::BakeConfig {
        probes: false,
        ..Default::default()
    };
    let bake = radbake::bake(&scene, &cfg, &radbake::Silent).unwrap();
    let g = &bake.geometry;
    let rays = radbake::raycast::RayCaster::new(&scene, g);
    let mut tracer = Tracer::new(&scene, g, &rays, Vec3::ZERO);
    let lm = LightmapLookup {
        width: bake.maps.lightmaps.width,
        height: bake.maps.lightmaps.height,
        pages: &bake.maps.lightmaps.pages,
    };
    tracer.lightmaps = Some(lm);
    let view = View::from_camera(&scene.cameras[0]);
    let field = sdf::bake(
        &scene,
        g,
        &rays,
        Settings {
            voxel: sdf::voxel_for_resolution(g.bounds().unwrap(), 256),
            band: None,
        },
    );
    let size = (64, 64);
    let marched = radbake::trace::sphere::render(&tracer, &field, &view, size, 16, 3, &|_| {});
    // The same shading at the BVH's hits, through each pixel's centre.
    let mut agree = 0;
    let (mut bvh_sum, mut sdf_sum) = (Vec3::ZERO, Vec3::ZERO);
    for y in 0..size.1 {
        for x in 0..size.0 {
            let ndc = glam::Vec2::new(
                2.0 * (x as f32 + 0.5) / size.0 as f32 - 1.0,
                1.0 - 2.0 * (y as f32 + 0.5) / size.1 as f32,
            );
            let d = view.ray(ndc, 1.0);
            let l = match rays.closest_hit(view.eye, d, f32::INFINITY) {
                None => Vec3::ZERO,
                Some(h) => {
                    let m = g.material[h.tri as usize];
                    let uv0 = g.uv0_at(h.tri, h.u, h.v);
                    let front = g.ng_ws[h.tri as usize].dot(d) < 0.0;
                    let e = if front {
                        scene.emission_at(m, uv0)
                    } else {
                        Vec3::ZERO
                    };
                    e + scene.albedo_at(m, uv0).0
                        * lm.at(g.page[h.tri as usize], g.uv_lm_at(h.tri, h.u, h.v))
                }
            };
            bvh_sum += l;
            let got = radbake::trace::sphere::radiance(&tracer, &field, view.eye, d);
            sdf_sum += got;
            let scale = l.max_element().max(1e-3);
            agree += ((got - l).abs().max_element() <= 0.02 * scale) as u32;
        }
    }
    let n = (size.0 * size.1) as f32;
    let (mean_bvh, mean_sdf) = (bvh_sum / n, sdf_sum / n);
    let share = agree as f32 / n;
    let fin = render(&tracer, &view, size, 16, Integrator::Path, 7, &|_| {});
    eprintln!(
        "centre rays: sphere-traced mean {mean_sdf}, BVH {mean_bvh}; rendered {}, path-traced final pass {}; {:.1} % of pixels within 2 %",
        marched.mean(),
        fin.mean(),
        100.0 * share
    );
    let rel = |a: Vec3, b: Vec3| ((a - b).element_sum() / b.element_sum()).abs();
    assert!(rel(mean_sdf, mean_bvh) < 0.01);
    assert!(share >= 0.95);
    // The lamp's edge: a ray that passes within a voxel of it takes its
    // emission (the nearest triangle short of the hit), a bright halo of
    // a voxel; so a looser bound for the whole image.
    assert!(rel(marched.mean(), fin.mean()) < 0.05);
}

/// Little-endian half floats, widened.
fn halves(raw: &[u8]) -> Vec<f32> {
    raw.chunks_exact(2)
        .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
        .collect()
}

/// Little-endian f32s.
fn floats(raw: &[u8]) -> Vec<f32> {
    raw.chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}
