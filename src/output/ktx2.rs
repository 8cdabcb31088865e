//! KTX 2.0 files (Khronos, "KTX File Format Specification 2.0"):
//! uncompressed `E5B9G9R9_UFLOAT_PACK32` images (Bevy's irradiance volumes,
//! [`super::probes`], and the HDR lightmap pages) and `BC6H_UFLOAT_BLOCK`
//! lightmap pages, encoded by Intel's ISPC Texture Compressor
//! (`intel_tex_2`). The container is small enough to write by hand (the
//! `ktx2` crate only reads); the tests read it back with that crate.

use glam::Vec3;
use rayon::prelude::*;

/// `VK_FORMAT_E5B9G9R9_UFLOAT_PACK32`.
const VK_FORMAT_E5B9G9R9_UFLOAT_PACK32: u32 = 123;
/// `VK_FORMAT_R16G16B16A16_SFLOAT`.
const VK_FORMAT_R16G16B16A16_SFLOAT: u32 = 97;
/// `VK_FORMAT_BC6H_UFLOAT_BLOCK`.
const VK_FORMAT_BC6H_UFLOAT_BLOCK: u32 = 143;
/// `VK_FORMAT_R32_SFLOAT`.
const VK_FORMAT_R32_SFLOAT: u32 = 100;
/// `VK_FORMAT_R16_SFLOAT`.
const VK_FORMAT_R16_SFLOAT: u32 = 76;
/// `VK_FORMAT_R8G8B8A8_UNORM`.
const VK_FORMAT_R8G8B8A8_UNORM: u32 = 37;

/// Packs linear RGB into RGB9E5 as the Vulkan specification's
/// "Shared Exponent" section (from `EXT_texture_shared_exponent`) defines:
/// N = 9 mantissa bits, bias B = 15, E_max = 31; negative and NaN values
/// become 0, values above the largest representable clamp to it.
pub fn rgb9e5(c: Vec3) -> u32 {
    const N: i32 = 9;
    const B: i32 = 15;
    let max = ((1 << N) - 1) as f32 / (1 << N) as f32 * 2f32.powi(31 - B);
    let clamp = |v: f32| if v > 0.0 { v.min(max) } else { 0.0 };
    let (r, g, b) = (clamp(c.x), clamp(c.y), clamp(c.z));
    let maxc = r.max(g).max(b);
    let mut exp = (-B - 1).max(maxc.log2().floor() as i32) + 1 + B;
    if maxc == 0.0 {
        exp = 0;
    }
    let scale = |e: i32| 2f32.powi(e - B - N);
    let maxs = (maxc / scale(exp) + 0.5).floor() as i32;
    if maxs == 1 << N {
        exp += 1;
    }
    let q = |v: f32| ((v / scale(exp) + 0.5).floor() as u32).min((1 << N) - 1);
    q(r) | q(g) << 9 | q(b) << 18 | (exp as u32) << 27
}

/// A KTX2 file of one uncompressed image in RGB9E5 (`texels` x fastest,
/// then y, then z): 2D when `size[2]` is 0 (KTX2's `pixelDepth` for a 2D
/// image), 3D otherwise. The container follows the KTX 2.0 specification; its
/// data format descriptor is the Khronos basic descriptor for this format
/// (six samples: a 9-bit mantissa and the shared 5-bit exponent per
/// channel), word for word as in Bevy's own `Example.vxgi.ktx2`.
pub fn ktx2_rgb9e5(size: [u32; 3], texels: &[u32]) -> Vec<u8> {
    container(size, texels, None)
}

/// The Zstandard level of every KTX2 file a bake writes. Sponza's RGB9E5
/// page (8.6 MB raw, `zstd` 1.5 on the EPYC VM): level 3 4.49 MB in
/// 0.07 s, level 9 4.41 MB in 0.18 s; the level only trades size for time,
/// the decoded texels are the same.
pub const ZSTD_LEVEL: i32 = 3;

/// [`ktx2_rgb9e5`] with the level supercompressed by Zstandard at `level`
/// (KTX2 scheme 2, as Bevy's own sample lightmaps are; Bevy reads it with
/// its `zstd_rust` feature, on by default).
pub fn ktx2_rgb9e5_zstd(size: [u32; 3], texels: &[u32], level: i32) -> Vec<u8> {
    container(size, texels, Some(level))
}

fn container(size: [u32; 3], texels: &[u32], zstd: Option<i32>) -> Vec<u8> {
    assert_eq!(texels.len(), (size[0] * size[1] * size[2].max(1)) as usize);
    let mut dfd: Vec<u32> = vec![
        1 | 1 << 8 | 1 << 16, // model RGBSDA, primaries BT.709, linear
        0,                    // texel block dimensions 1×1×1×1
        4,                    // bytes per plane 0
        0,
    ];
    for ch in 0..3u32 {
        // Mantissa: 9 bits at 9·ch; lower 0, upper 8448 (0x2100), as
        // Khronos's dfdutils write it.
        dfd.extend([(9 * ch) | 8 << 16 | ch << 24, 0, 0, 0x2100]);
        // Shared exponent: 5 bits at 27, qualifier EXPONENT (0x20).
        dfd.extend([27 | 4 << 16 | (ch | 0x20) << 24, 0, 15, 31]);
    }
    let raw: Vec<u8> = texels.iter().flat_map(|t| t.to_le_bytes()).collect();
    file(VK_FORMAT_E5B9G9R9_UFLOAT_PACK32, 4, size, &dfd, &raw, zstd)
}

/// A 2D KTX2 file of `width` × `height` linear RGB (`texels` row by row) in
/// `BC6H_UFLOAT_BLOCK`, Zstandard supercompressed at `level`. Negative
/// values and NaN become 0 and values clamp to half's largest, 65504 (BC6H
/// unsigned holds half floats without sign). Encoded with
/// `intel_tex_2::bc6h::basic_settings` (ISPC, deterministic), one band of
/// 4 rows of blocks per task; the image is padded to whole 4 × 4 blocks by
/// repeating its last row and column (the KTX2 size stays the image's).
/// The data format descriptor is Khronos's for this format: colour model
/// BC6H (133), 4 × 4 blocks of 16 bytes, one 128-bit FLOAT sample with
/// lower 0 and upper 1.0.
pub fn ktx2_bc6h_zstd(width: u32, height: u32, texels: &[Vec3], level: i32) -> Vec<u8> {
    assert_eq!(texels.len(), (width * height) as usize);
    let blocks = bc6h_blocks(width, height, texels);
    let dfd = [
        133 | 1 << 8 | 1 << 16, // model BC6H, primaries BT.709, linear
        3 | 3 << 8,             // texel block dimensions 4×4×1×1
        16,                     // bytes per plane 0
        0,
        127 << 16 | 0x80 << 24, // bits 0..127, channel colour, FLOAT
        0,
        0,
        0x3F80_0000,
    ];
    file(
        VK_FORMAT_BC6H_UFLOAT_BLOCK,
        1,
        [width, height, 0],
        &dfd,
        &blocks,
        Some(level),
    )
}

/// A 2D KTX2 file of `width` × `height` signed linear RGB (`texels` row by
/// row) in `R16G16B16A16_SFLOAT` (alpha 1), Zstandard supercompressed at
/// `level`: for pages with negative values (the SH pages' linear
/// coefficients), which RGB9E5 and unsigned BC6H cannot hold. Values clamp
/// to ±65504. The data format descriptor is Khronos's basic one: RGBSDA,
/// four 16-bit samples qualified FLOAT | SIGNED, lower −1.0, upper 1.0.
pub fn ktx2_rgba16f_zstd(width: u32, height: u32, texels: &[Vec3], level: i32) -> Vec<u8> {
    assert_eq!(texels.len(), (width * height) as usize);
    let mut raw = Vec::with_capacity(texels.len() * 8);
    for c in texels {
        for v in [c.x, c.y, c.z, 1.0] {
            raw.extend(half_le(v, -65504.0));
        }
    }
    let mut dfd = vec![
        1 | 1 << 8 | 1 << 16, // model RGBSDA, primaries BT.709, linear
        0,                    // texel block dimensions 1×1×1×1
        8,                    // bytes per plane 0
        0,
    ];
    // R, G, B, A (channel 15): 16 bits each, FLOAT | SIGNED (0xC0).
    for (k, ch) in [0u32, 1, 2, 15].into_iter().enumerate() {
        dfd.extend([
            (16 * k as u32) | 15 << 16 | (ch | 0xC0) << 24,
            0,
            0xBF80_0000,
            0x3F80_0000,
        ]);
    }
    file(
        VK_FORMAT_R16G16B16A16_SFLOAT,
        2,
        [width, height, 0],
        &dfd,
        &raw,
        Some(level),
    )
}

/// A KTX2 file of `size` (width, height, depth; depth 0 for 2D) single
/// float texels (x fastest) in `R32_SFLOAT`, Zstandard supercompressed at
/// `level`: the signed distance field. The data format descriptor is
/// Khronos's basic one: RGBSDA, BT.709, linear, one 32-bit sample, FLOAT |
/// SIGNED, lower −1.0, upper 1.0.
pub fn ktx2_r32f_zstd(size: [u32; 3], texels: &[f32], level: i32) -> Vec<u8> {
    let n: usize = size.iter().map(|&d| d.max(1) as usize).product();
    assert_eq!(texels.len(), n);
    let raw: Vec<u8> = texels.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut dfd = vec![1 | 1 << 8 | 1 << 16, 0, 4, 0];
    dfd.extend([31 << 16 | 0xC0 << 24, 0, 0xBF80_0000, 0x3F80_0000]);
    file(VK_FORMAT_R32_SFLOAT, 4, size, &dfd, &raw, Some(level))
}

/// [`ktx2_r32f_zstd`] in `R16_SFLOAT`: half floats (IEEE 754 binary16,
/// rounded to nearest; 11 significant bits, so within 2⁻¹¹ of each value,
/// clamped to ±65504; NaN becomes 0), half the size. The data format
/// descriptor is the same but for its one 16-bit sample and 2 bytes per
/// plane.
pub fn ktx2_r16f_zstd(size: [u32; 3], texels: &[f32], level: i32) -> Vec<u8> {
    let n: usize = size.iter().map(|&d| d.max(1) as usize).product();
    assert_eq!(texels.len(), n);
    let raw: Vec<u8> = texels.iter().flat_map(|&v| half_le(v, -65504.0)).collect();
    let mut dfd = vec![1 | 1 << 8 | 1 << 16, 0, 2, 0];
    dfd.extend([15 << 16 | 0xC0 << 24, 0, 0xBF80_0000, 0x3F80_0000]);
    file(VK_FORMAT_R16_SFLOAT, 2, size, &dfd, &raw, Some(level))
}

/// A 2D KTX2 file of `width` × `height` linear RGBA8 texels (row by row)
/// in `R8G8B8A8_UNORM`, Zstandard supercompressed at `level`: for the
/// shadowmask pages (visibility, where 8 bits are enough). The data format
/// descriptor is Khronos's basic one: RGBSDA, BT.709, linear, straight
/// alpha, four 8-bit samples of range 0–255.
pub fn ktx2_rgba8_zstd(width: u32, height: u32, texels: &[[u8; 4]], level: i32) -> Vec<u8> {
    assert_eq!(texels.len(), (width * height) as usize);
    let raw: Vec<u8> = texels.iter().flatten().copied().collect();
    let mut dfd = vec![
        1 | 1 << 8 | 1 << 16, // model RGBSDA, primaries BT.709, linear
        0,                    // texel block dimensions 1×1×1×1
        4,                    // bytes per plane 0
        0,
    ];
    // R, G, B, A (channel 15): 8 bits each, no qualifiers, 0–255.
    for (k, ch) in [0u32, 1, 2, 15].into_iter().enumerate() {
        dfd.extend([(8 * k as u32) | 7 << 16 | ch << 24, 0, 0, 255]);
    }
    file(
        VK_FORMAT_R8G8B8A8_UNORM,
        1,
        [width, height, 0],
        &dfd,
        &raw,
        Some(level),
    )
}

/// `v` as a little-endian half float, clamped to [`min`, 65504] (half's
/// largest); NaN becomes 0.
fn half_le(v: f32, min: f32) -> [u8; 2] {
    let v = if v.is_nan() {
        0.0
    } else {
        v.clamp(min, 65504.0)
    };
    half::f16::from_f32(v).to_le_bytes()
}

/// BC6H blocks of an image, row of blocks by row of blocks.
fn bc6h_blocks(width: u32, height: u32, texels: &[Vec3]) -> Vec<u8> {
    use intel_tex_2::{bc6h, RgbaSurface};
    let (bw, bh) = (width.div_ceil(4), height.div_ceil(4));
    let settings = bc6h::basic_settings();
    let bands: Vec<Vec<u8>> = (0..bh)
        .into_par_iter()
        .map(|by| {
            // One row of blocks: 4 rows of texels, RGBA half, padded.
            let mut data = Vec::with_capacity((bw * 4 * 4 * 8) as usize);
            for y in by * 4..by * 4 + 4 {
                let row = y.min(height - 1) * width;
                for x in 0..bw * 4 {
                    let c = texels[(row + x.min(width - 1)) as usize];
                    for v in [c.x, c.y, c.z, 1.0] {
                        data.extend(half_le(v, 0.0));
                    }
                }
            }
            let surface = RgbaSurface {
                data: &data,
                width: bw * 4,
                height: 4,
                stride: bw * 4 * 8,
            };
            bc6h::compress_blocks(&settings, &surface)
        })
        .collect();
    bands.concat()
}

/// The KTX2 container of one level: `dfd` is the basic descriptor after its
/// two header words (total size, vendor/type) and its version/size word.
fn file(
    vk_format: u32,
    type_size: u32,
    size: [u32; 3],
    dfd: &[u32],
    raw: &[u8],
    zstd: Option<i32>,
) -> Vec<u8> {
    let samples = (dfd.len() - 4) / 4;
    let mut words = vec![0, 0, 2 | ((24 + 16 * samples) as u32) << 16];
    words.extend_from_slice(dfd);
    words[0] = (words.len() * 4) as u32;
    let header_len = 80 + 24; // header + index, one level
    let dfd_off = header_len as u32;
    let dfd_len = words[0];
    let data_off = (dfd_off + dfd_len) as u64;
    let data = match zstd {
        Some(level) => zstd::bulk::compress(raw, level).expect("zstd compression in memory"),
        None => raw.to_vec(),
    };
    let data_len = data.len() as u64;
    let mut out = Vec::with_capacity(data_off as usize + data_len as usize);
    out.extend([
        0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
    ]);
    for w in [
        vk_format,
        type_size,
        size[0],
        size[1],
        size[2],
        0,                                  // layers
        1,                                  // faces
        1,                                  // levels
        if zstd.is_some() { 2 } else { 0 }, // supercompression: none or Zstandard
        dfd_off,
        dfd_len,
        0, // no key/value data
        0,
    ] {
        out.extend(w.to_le_bytes());
    }
    out.extend(0u64.to_le_bytes()); // no supercompression global data
    out.extend(0u64.to_le_bytes());
    for v in [data_off, data_len, raw.len() as u64] {
        out.extend(v.to_le_bytes());
    }
    for w in words {
        out.extend(w.to_le_bytes());
    }
    out.extend(data);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The specification's decode, value = mantissa × 2^(e − B − N).
    fn decode(p: u32) -> Vec3 {
        let e = (p >> 27) as i32;
        let s = 2f32.powi(e - 15 - 9);
        Vec3::new(
            (p & 511) as f32 * s,
            ((p >> 9) & 511) as f32 * s,
            ((p >> 18) & 511) as f32 * s,
        )
    }

    #[test]
    fn rgb9e5_round_trips_within_its_quantisation() {
        for c in [
            Vec3::new(2.0, 2.0, 2.0),
            Vec3::new(0.013, 0.5, 7.25),
            Vec3::new(1e-6, 0.0, 3e-3),
            Vec3::new(60000.0, 1.0, 0.0),
        ] {
            let d = decode(rgb9e5(c));
            // Half a step of the shared exponent: ≤ max channel / 2⁹.
            let bound = c.max_element() / 512.0 + 1e-9;
            assert!((d - c).abs().max_element() <= bound, "{c} -> {d}");
        }
        assert_eq!(decode(rgb9e5(Vec3::splat(-1.0))), Vec3::ZERO);
        assert_eq!(decode(rgb9e5(Vec3::splat(2.0))), Vec3::splat(2.0));
    }

    #[test]
    fn r16f_holds_half_floats() {
        let texels = [0.0, -1.5, 7.123_456, 1e-3, -70000.0, f32::NAN];
        let bytes = ktx2_r16f_zstd([3, 2, 1], &texels, 3);
        let word = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        assert_eq!((word(12), word(16)), (76, 2)); // R16_SFLOAT, 2-byte type
        assert_eq!((word(20), word(24), word(28)), (3, 2, 1));
        assert_eq!(word(44), 2); // Zstandard
                                 // The DFD: 2 bytes per plane, one 16-bit FLOAT | SIGNED sample.
        assert_eq!((word(104 + 20), word(104 + 28)), (2, 15 << 16 | 0xC0 << 24));
        let at = u64::from_le_bytes(bytes[80..88].try_into().unwrap()) as usize;
        let len = u64::from_le_bytes(bytes[88..96].try_into().unwrap()) as usize;
        let raw = zstd::bulk::decompress(&bytes[at..at + len], 12).unwrap();
        let back: Vec<f32> = raw
            .chunks_exact(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect();
        for (v, b) in texels[..4].iter().zip(&back) {
            assert!((v - b).abs() <= v.abs() / 2048.0, "{v} -> {b}");
        }
        assert_eq!(back[4..], [-65504.0, 0.0]);
    }

    #[test]
    fn ktx2_header_is_as_bevy_ships_it() {
        let bytes = ktx2_rgb9e5([2, 4, 3], &[0; 24]);
        assert_eq!(&bytes[..12], b"\xabKTX 20\xbb\r\n\x1a\n");
        let word = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        assert_eq!(word(12), 123);
        assert_eq!((word(20), word(24), word(28)), (2, 4, 3));
        assert_eq!(word(48), 104); // DFD right after the level index
        assert_eq!(word(52), 124);
        assert_eq!(bytes.len(), 104 + 124 + 24 * 4);
        // The DFD of Bevy 0.19's assets/irradiance_volumes/Example.vxgi.ktx2.
        let bevy: [u32; 31] = [
            0x7c, 0x0, 0x780002, 0x10101, 0x0, 0x4, 0x0, 0x80000, 0x0, 0x0, 0x2100, 0x2004001b,
            0x0, 0xf, 0x1f, 0x1080009, 0x0, 0x0, 0x2100, 0x2104001b, 0x0, 0xf, 0x1f, 0x2080012,
            0x0, 0x0, 0x2100, 0x2204001b, 0x0, 0xf, 0x1f,
        ];
        let dfd: Vec<u32> = (0..31).map(|k| word(104 + 4 * k)).collect();
        assert_eq!(dfd, bevy);
    }
}
