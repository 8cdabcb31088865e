//! Files written atomically: each to a temporary file in the same folder,
//! then renamed over the target, so a killed process never leaves a
//! half-written file where a good one was; and the two image formats every
//! layer writes (linear float EXR, PNG).

use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// Writes `img` to `path` as a PNG, atomically ([`write_atomic`]).
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_png<P>(path: &Path, img: &image::ImageBuffer<P, Vec<P::Subpixel>>) -> Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
{
    write_atomic(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| Error::Encode {
                path: path.to_path_buf(),
                message: e.to_string(),
            })
    })
}

/// Writes `path` atomically: `write` fills a temporary sibling, which is
/// synced and renamed over `path` only if `write` succeeds.
///
/// # Errors
/// [`Error::Io`] on any file-system failure; whatever `write` returns.
pub fn write_atomic(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    // Keep the extension last: some encoders pick the format from it.
    let tmp = dir.join(format!(".{name}.{}.tmp.{ext}", std::process::id()));
    let io = |source| Error::Io {
        path: tmp.clone(),
        source,
    };
    let result = write(&tmp).and_then(|_| {
        std::fs::File::open(&tmp)
            .and_then(|f| f.sync_all())
            .map_err(io)?;
        std::fs::rename(&tmp, path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Removes temporary files left in `out_dir` by [`write_atomic`] (names
/// `.<file>.<pid>.tmp.<ext>`): those of process `pid`, or all of them
/// (stale ones from a killed bake) when `pid` is `None`.
pub fn remove_temporaries(out_dir: &Path, pid: Option<u32>) {
    let Ok(entries) = std::fs::read_dir(out_dir) else {
        return;
    };
    for e in entries.flatten() {
        let Some(file_pid) = temporary_pid(&e.file_name().to_string_lossy()) else {
            continue;
        };
        if pid.is_none_or(|p| p == file_pid) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Removes the temporary files that other processes left in `out_dir`
/// ([`remove_temporaries`] of every pid but this one's).
pub fn remove_stale_temporaries(out_dir: &Path) {
    let own = std::process::id();
    let Ok(entries) = std::fs::read_dir(out_dir) else {
        return;
    };
    let pids: std::collections::BTreeSet<u32> = entries
        .flatten()
        .filter_map(|e| temporary_pid(&e.file_name().to_string_lossy()))
        .filter(|&p| p != own)
        .collect();
    for pid in pids {
        remove_temporaries(out_dir, Some(pid));
    }
}

/// The pid in a temporary's name (`.<file>.<pid>.tmp.<ext>`), if it is one.
fn temporary_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    let before = &rest[..rest.rfind(".tmp.")?];
    before[before.rfind('.')? + 1..].parse().ok()
}

/// Writes bytes atomically.
///
/// # Errors
/// [`Error::Io`].
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|source| Error::Io {
            path: tmp.to_path_buf(),
            source,
        })
    })
}

/// Writes a row-major `width × height` linear RGB image as float OpenEXR,
/// atomically.
///
/// # Errors
/// [`Error::Encode`] or [`Error::Io`].
pub fn write_exr_rgb(path: &Path, width: u32, height: u32, values: &[Vec3]) -> Result<()> {
    let (w, h) = (width as usize, height as usize);
    write_atomic(path, |tmp| {
        use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage as _};
        // Compressed serially: exr's parallel writer stores blocks in the
        // order they finish, which varies from run to run.
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let v = values[y * w + x];
            (v.x, v.y, v.z)
        });
        Image::from_channels((w, h), channels)
            .write()
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| Error::Encode {
                path: path.to_path_buf(),
                message: e.to_string(),
            })
    })
}

/// Reads an OpenEXR image: the first layer with R, G and B channels
/// (alpha ignored) as linear f32, row-major. The header's size is checked
/// (not empty, at most `max_width` wide and `max_pixels` in all) before
/// the pixels are decoded; `what` names the image in errors.
///
/// # Errors
/// [`Error::Io`]; [`Error::Invalid`] for a file that is not a readable
/// OpenEXR image or is empty; [`Error::Limit`] above the limits.
pub fn read_exr_rgb(
    path: &Path,
    what: &str,
    max_width: u64,
    max_pixels: u64,
) -> Result<(u32, u32, Vec<Vec3>)> {
    use exr::prelude::traits::*;
    let invalid = |message: String| Error::Invalid {
        path: path.to_path_buf(),
        location: what.into(),
        message: message.replace(['\n', '\r'], " "),
    };
    let check = |w: u64, h: u64| {
        if w == 0 || h == 0 {
            return Err(invalid(format!("empty {what} ({w} × {h} pixels)")));
        }
        if w > max_width || w.saturating_mul(h) > max_pixels {
            return Err(Error::Limit(format!(
                "{}: {what} is {w} × {h}, above the limit of {max_width} pixels wide and \
                 {max_pixels} pixels in all",
                path.display()
            )));
        }
        Ok(())
    };
    let open = || {
        std::fs::File::open(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    };
    let meta = exr::meta::MetaData::read_from_unbuffered(open()?, false)
        .map_err(|e| invalid(format!("not a readable OpenEXR file: {e}")))?;
    let has =
        |h: &exr::meta::header::Header, name: &str| h.channels.list.iter().any(|c| c.name.eq(name));
    let header = meta
        .headers
        .iter()
        .find(|h| has(h, "R") && has(h, "G") && has(h, "B"));
    let Some(header) = header.or(meta.headers.first()) else {
        return Err(invalid("no image layer".into()));
    };
    let size = header.layer_size;
    check(size.width() as u64, size.height() as u64)?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            // Another layer than the one checked could be read: then no
            // more than the limit is allocated, and the size checked below.
            |size, _| {
                let fits = size.area() as u64 <= max_pixels;
                (
                    size.width(),
                    vec![Vec3::ZERO; if fits { size.area() } else { 0 }],
                )
            },
            |(w, pixels): &mut (usize, Vec<Vec3>), at, (r, g, b, _): (f32, f32, f32, f32)| {
                if let Some(p) = pixels.get_mut(at.y() * *w + at.x()) {
                    *p = Vec3::new(r, g, b);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_unbuffered(open()?)
        .map_err(|e| invalid(format!("could not decode OpenEXR: {e}")))?;
    let size = image.layer_data.size;
    let (w, h) = (size.width() as u64, size.height() as u64);
    check(w, h)?;
    Ok((w as u32, h as u32, image.layer_data.channel_data.pixels.1))
}
