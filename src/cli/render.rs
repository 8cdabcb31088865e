//! `radbake render`: path-trace an image of a scene, the reference, or the
//! final pass over a bake's lightmaps.

use super::{lib_err, parse_rgb, parse_size, Outcome, ViewArgs};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    /// The scene (.gltf or .glb), as given to `radbake bake`.
    pub scene: PathBuf,
    /// Output image: `.exr` (linear; a tone-mapped `.png` is written beside it) or `.png`.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Final pass: read this bake folder's lightmaps at the hits of the indirect rays.
    #[arg(long, value_name = "BAKE_DIR")]
    pub lightmaps: Option<PathBuf>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Estimator of the reference (the final pass always traces paths).
    #[arg(long, value_enum, default_value = "path")]
    pub integrator: radbake::trace::render::Integrator,
    /// Voxels along the scene's longest side of the distance field that
    /// `--integrator sphere-trace` marches.
    #[arg(long, default_value_t = 256)]
    pub sdf_resolution: u32,
    #[command(flatten)]
    pub at: ViewArgs,
    /// Vertical field of view in degrees for --look-from and the framing.
    #[arg(long, default_value_t = 50.0)]
    pub fov: f32,
    /// Sky radiance `r,g,b` [default: the bake's with --lightmaps, else 0].
    #[arg(long, value_parser = parse_rgb)]
    pub sky: Option<[f32; 3]>,
    /// Exposure of the PNG in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Seed of the random sequences (images are deterministic for a seed).
    #[arg(long, default_value_t = 0x5eed)]
    pub seed: u64,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Renders `args.scene` (over `args.lightmaps` for the final pass) into `args.out`.
pub fn run(args: &RenderArgs) -> Outcome {
    use radbake::trace::render::{self, Integrator};
    let start = Instant::now();
    let scene = radbake::scene::load(&args.scene, &Default::default()).map_err(lib_err)?;
    let baked = match &args.lightmaps {
        Some(dir) => Some(render::load_bake(&scene, dir).map_err(lib_err)?),
        None => None,
    };
    let unmapped;
    let geometry = match &baked {
        Some(b) => &b.geometry,
        None => {
            unmapped = radbake::layout::geometry::Geometry::unmapped(&scene);
            &unmapped
        }
    };
    // `--sky`, else the bake's sky (its map, if it had one), else black.
    let sky = match (args.sky, &baked) {
        (Some(c), _) => radbake::light::sky::Sky::Uniform(c.into()),
        (None, Some(b)) => b.config.load_sky().map_err(lib_err)?,
        (None, None) => radbake::light::sky::Sky::default(),
    };
    let rays = radbake::raycast::RayCaster::new(&scene, geometry);
    let mut tracer = radbake::trace::Tracer::new(&scene, geometry, &rays, sky);
    if let Some(b) = &baked {
        tracer.lightmaps = Some(radbake::trace::LightmapLookup {
            width: b.width,
            height: b.height,
            pages: &b.pages,
        });
    }
    let mut integrator = args.integrator;
    if integrator == Integrator::SphereTrace && baked.is_none() {
        return Err((
            1,
            "--integrator sphere-trace shades from a bake's lightmaps: give --lightmaps BAKE_DIR"
                .into(),
        ));
    }
    if integrator == Integrator::Bdpt
        && (baked.is_some() || !radbake::trace::bdpt::supports(&tracer))
    {
        if !args.quiet {
            eprintln!("warning: BDPT covers Lambertian scenes without lightmaps; rendering with the path tracer");
        }
        integrator = Integrator::Path;
    }
    let view = choose_view(args, &scene, geometry)?;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        let passes = match integrator {
            Integrator::Bdpt => render::BDPT_PASSES as u64,
            Integrator::Path | Integrator::SphereTrace => 1,
        };
        ProgressBar::new(args.size.1 as u64 * passes).with_style(
            ProgressStyle::with_template(
                "{msg:>13} [{bar:30}] {pos}/{len} rows {elapsed} (eta {eta})",
            )
            .expect("static template")
            .progress_chars("=> "),
        )
    };
    bar.set_message(if baked.is_some() {
        "final pass"
    } else {
        "reference"
    });
    let image = if integrator == Integrator::SphereTrace {
        let bounds = geometry
            .bounds()
            .unwrap_or((glam::Vec3::ZERO, glam::Vec3::ONE));
        let settings = radbake::sdf::Settings {
            voxel: radbake::sdf::voxel_for_resolution(bounds, args.sdf_resolution.max(1)),
            band: None,
        };
        let field = radbake::sdf::bake(&scene, geometry, &rays, settings);
        let size = args.size;
        radbake::trace::sphere::render(&tracer, &field, &view, size, args.spp, args.seed, &|n| {
            bar.inc(n)
        })
    } else {
        render::render(
            &tracer,
            &view,
            args.size,
            args.spp,
            integrator,
            args.seed,
            &|n| bar.inc(n),
        )
    };
    bar.finish_and_clear();
    write_image(args, &image)?;
    if !args.quiet {
        let m = image.mean();
        eprintln!(
            "rendered {}x{} at {} spp ({:?}) in {:.2} s, mean radiance {:.4} {:.4} {:.4} → {}",
            args.size.0,
            args.size.1,
            args.spp,
            integrator,
            start.elapsed().as_secs_f64(),
            m.x,
            m.y,
            m.z,
            args.out.display()
        );
    }
    Ok(())
}

/// Writes the image: `.exr` (linear, with a tone-mapped `.png` beside it)
/// or `.png`, creating the folder.
fn write_image(args: &RenderArgs, image: &radbake::trace::render::Image) -> Outcome {
    let io = |e: radbake::Error| (3u8, e.to_string());
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| (3u8, format!("{}: {e}", dir.display())))?;
    }
    let is_exr = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        image.write_exr(&args.out).map_err(io)?;
        image
            .write_png(&args.out.with_extension("png"), args.exposure)
            .map_err(io)?;
    } else {
        image.write_png(&args.out, args.exposure).map_err(io)?;
    }
    Ok(())
}

/// The view of `--camera`, `--look-from` (towards `--look-at` or the
/// scene's centre), the scene's first camera, or a framing of the scene.
fn choose_view(
    args: &RenderArgs,
    scene: &radbake::scene::Scene,
    geometry: &radbake::layout::geometry::Geometry,
) -> Result<radbake::trace::render::View, (u8, String)> {
    use radbake::trace::render::View;
    let yfov = args.fov.to_radians();
    Ok(match (&args.at.camera, args.at.look_from) {
        (Some(name), _) => {
            let cam = scene
                .cameras
                .iter()
                .find(|c| &c.name == name)
                .ok_or_else(|| {
                    (
                        1,
                        format!("{}: no camera named `{name}`", args.scene.display()),
                    )
                })?;
            View::from_camera(cam)
        }
        (None, Some(from)) => {
            let at = args
                .at
                .look_at
                .map(Into::into)
                .unwrap_or_else(|| centre(geometry));
            View::look_at(from.into(), at, yfov)
        }
        (None, None) => match scene.cameras.first() {
            Some(cam) => View::from_camera(cam),
            None => View::framing(geometry, yfov),
        },
    })
}

/// Centre of the scene's bounding box.
fn centre(geometry: &radbake::layout::geometry::Geometry) -> glam::Vec3 {
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
    for p in geometry.p_ws.iter().flatten() {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if lo.x > hi.x {
        glam::Vec3::ZERO
    } else {
        (lo + hi) * 0.5
    }
}
