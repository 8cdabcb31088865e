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
