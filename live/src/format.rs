//! `live.bin`: what a live bake keeps for the runtime, one file.
//!
//! ```text
//! magic "RBLIVE\r\n" · u32 version · u32 header length · header (JSON, UTF-8)
//! · u32 CRC-32 of the body · body
//! ```
//!
//! The body's sections follow each other in this order, little-endian,
//! each's length given by the header's counts (P patches, T texels, R runs,
//! N entries of F, Q padding pixels, G = grid² directions, S live lights):
//!
//! | section | per | type |
//! |---|---|---|
//! | albedo ρ | patch | 3 × f32 |
//! | F's row starts (into its entries), and the end | patch + 1 | u32 |
//! | F's columns, rising within a row | entry | u32 |
//! | F's entries Fᵢⱼ | entry | f16 |
//! | each live light's sun table, direction-major: π × the patch's D for a unit sun (W/m²) | S × G × patch | u8 (/255) |
//! | the texel's patch | texel | u32 |
//! | its share of the patch's area aₜ / Aₚ | texel | f32 |
//! | the patches at its four bilinear corners (u32::MAX: none) | texel | 4 × u32 |
//! | its pixel: row-major index in its page | texel | u32 |
//! | its page | texel | u16 |
//! | padding pixels, page by page, ring by ring: the pixel and the 3 × 3 neighbour (0–8, row order) it copies | padding pixel | u32 + u8 |
//! | with `probes` (K probes, n rays): each probe's validity (1 valid, 0 inside a solid) | probe | u8 |
//! | the patch each probe ray meets, ray i along [`crate::probes::fibonacci`]`(i, n)` (u32::MAX: none, a back face, the sky) | probe × ray | u32 |
//! | the patches' outgoing radiance L at the baked suns (exact visibility), which the probes were baked with | patch | 3 × f32 |
//!
//! Read back with every count, offset and index checked, so a truncated
//! or corrupted file is an error naming the section, never a panic or a
//! wrong image.

use crate::{LiveError, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file's first bytes.
pub const MAGIC: [u8; 8] = *b"RBLIVE\r\n";
/// The format version this crate reads and writes.
pub const VERSION: u32 = 2;
/// Largest patch or texel count accepted (2²⁸): a count beyond it is a
/// corrupted header, not a scene.
const MAX_COUNT: u64 = 1 << 28;

/// A live light: a directional light whose direction and colour change
/// at run time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LiveLight {
    /// The light's name in the scene.
    pub name: String,
    /// As baked: the unit direction towards the light (y up).
    pub direction: [f32; 3],
    /// As baked: its irradiance on a surface facing it, W/m² (linear RGB,
    /// colour × intensity).
    pub irradiance: [f32; 3],
    /// Its sun path: the directions its table holds, in order along the
    /// path ([`crate::directions::path_weights`]); `None`: the header's
    /// hemisphere grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<Vec<[f32; 3]>>,
}

impl LiveLight {
    /// How many directions its sun table holds.
    pub fn directions(&self, grid: u32) -> u64 {
        self.path
            .as_ref()
            .map_or(grid as u64 * grid as u64, |p| p.len() as u64)
    }
}

/// The sky's light layer, where the sky is uniform and so may change
/// colour at run time (its layer's pages scale by the new colour over the
/// baked one, channel by channel).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkyLayer {
    /// The layer's name.
    pub layer: String,
    /// The baked sky radiance (W·sr⁻¹·m⁻², linear RGB).
    pub radiance: [f32; 3],
}

/// A lightmap page's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PageSize {
    pub width: u32,
    pub height: u32,
}

/// A probe grid: its first probe and resolution (probe (i, j, k) is
/// `first + i + Rx·(j + Ry·k)`), as `probes.json`'s volumes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeGrid {
    pub first: u64,
    pub resolution: [u32; 3],
}

/// The probes' view of the patches ([`crate::probes`]): what a probe ray
/// meets, for the live layer's probes to follow the sun.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeHeader {
    /// Probes K, in `probes.bin`'s order.
    pub count: u64,
    /// Rays per probe n (a spherical Fibonacci set, the same for every
    /// probe).
    pub rays: u32,
    /// The grids, in order, covering the K probes.
    pub grids: Vec<ProbeGrid>,
}

/// The header: counts, the live lights and where their light goes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// [`VERSION`].
    pub version: u32,
    /// Patches P.
    pub patches: u64,
    /// Texels T.
    pub texels: u64,
    /// Entries of F.
    pub entries: u64,
    /// The patches' size in texels (k × k blocks): the bilinear weights'
    /// spacing.
    pub block: u32,
    /// The sun directions: a `grid` × `grid` hemi-octahedral grid
    /// ([`crate::directions`]).
    pub grid: u32,
    /// The lightmap pages, and each one's padding pixels.
    pub pages: Vec<PageSize>,
    pub padding: Vec<u64>,
    /// The bake's solver tolerance (Σ|ΔL| / Σ|L|) and iteration limit.
    pub tolerance: f32,
    pub max_iterations: u32,
    /// The light layer whose pages the live solution replaces: the live
    /// lights' bounced light.
    pub layer: String,
    /// The live lights, in the order of their sun tables.
    pub lights: Vec<LiveLight>,
    /// The sky's layer, where its colour may change live.
    pub sky: Option<SkyLayer>,
    /// The probes' view of the patches (none: a bake without probes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probes: Option<ProbeHeader>,
}

/// F in compressed sparse rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Matrix {
    /// Row i's entries are `cols[rows[i]..rows[i + 1]]`, `vals[…]`.
    pub rows: Vec<u32>,
    /// Column of each entry, rising within a row.
    pub cols: Vec<u32>,
    /// Fᵢⱼ as f16 bits.
    pub vals: Vec<u16>,
}

/// A texel's reconstruction from the patches: the bake's first-pass
/// interpolation (bilinear between the centres of up to four patches of
/// its region, then shifted per patch so that the patch's mean is kept).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TexelMap {
    /// Its patch.
    pub patch: Vec<u32>,
    /// aₜ / Aₚ.
    pub share: Vec<f32>,
    /// The patch at each bilinear corner ((0,0), (1,0), (0,1), (1,1)) or
    /// u32::MAX.
    pub corners: Vec<[u32; 4]>,
    /// Row-major pixel index in its page.
    pub pixel: Vec<u32>,
    /// Its page.
    pub page: Vec<u16>,
    /// Per page: (pixel, 3 × 3 neighbour 0–8 in row order) per padding
    /// pixel, ring by ring (a pixel copies one filled before it).
    pub padding: Vec<Vec<(u32, u8)>>,
}

/// Per probe, what its rays meet ([`ProbeHeader`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProbeHits {
    /// False for a probe inside a solid (its light is filled from its
    /// neighbours', [`crate::probes::fill_plan`]).
    pub valid: Vec<bool>,
    /// Probe-major: the patch ray i meets (u32::MAX: none).
    pub hits: Vec<u32>,
    /// Per patch, its outgoing radiance L at the baked suns with their
    /// exact visibility (not the table's): the light the baked probes saw,
    /// from which [`crate::Live::probe_delta`] measures the change.
    pub baked: Vec<[f32; 3]>,
}

/// The whole file's content.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveData {
    pub header: Header,
    /// ρ per patch.
    pub albedo: Vec<[f32; 3]>,
    pub matrix: Matrix,
    /// Per live light: directions × P bytes, direction-major.
    pub suns: Vec<Vec<u8>>,
    pub texels: TexelMap,
    /// With [`Header::probes`].
    pub probes: Option<ProbeHits>,
}

impl LiveData {
    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let header = serde_json::to_vec(&self.header).expect("a header serialises");
        let mut body = Vec::with_capacity(body_len(&self.header).unwrap_or(0) as usize);
        for a in &self.albedo {
            put_f32s(&mut body, a);
        }
        put_u32s(&mut body, &self.matrix.rows);
        put_u32s(&mut body, &self.matrix.cols);
        for v in &self.matrix.vals {
            body.extend_from_slice(&v.to_le_bytes());
        }
        for s in &self.suns {
            body.extend_from_slice(s);
        }
        let t = &self.texels;
        put_u32s(&mut body, &t.patch);
        put_f32s(&mut body, &t.share);
        for c in &t.corners {
            put_u32s(&mut body, c);
        }
        put_u32s(&mut body, &t.pixel);
        for p in &t.page {
            body.extend_from_slice(&p.to_le_bytes());
        }
        for page in &t.padding {
            for (i, n) in page {
                body.extend_from_slice(&i.to_le_bytes());
                body.push(*n);
            }
        }
        if let Some(p) = &self.probes {
            body.extend(p.valid.iter().map(|&v| v as u8));
            put_u32s(&mut body, &p.hits);
            for l in &p.baked {
                put_f32s(&mut body, l);
            }
        }
        let mut out = Vec::with_capacity(20 + header.len() + body.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&crc32fast::hash(&body).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }

    /// Reads `path` ([`LiveData::from_bytes`]), naming it in any error.
    ///
    /// # Errors
    /// The file cannot be read, or is not a valid `live.bin`.
    pub fn read(path: &Path) -> Result<LiveData> {
        let bytes = std::fs::read(path).map_err(|e| LiveError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        LiveData::from_bytes(&bytes).map_err(|e| match e {
            LiveError::Malformed { message, .. } => LiveError::Malformed {
                path: path.display().to_string(),
                message,
            },
            e => e,
        })
    }

    /// Parses and checks a `live.bin`'s bytes.
    ///
    /// # Errors
    /// [`LiveError::Malformed`] naming what is wrong: magic, version,
    /// header, length, checksum, or an index out of its range.
    pub fn from_bytes(bytes: &[u8]) -> Result<LiveData> {
        let mut r = Reader { bytes, at: 0 };
        if r.take(8, "magic")? != MAGIC {
            return Err(bad("not a radbake live file (wrong magic bytes)"));
        }
        let version = r.u32("version")?;
        if version != VERSION {
            return Err(bad(format!(
                "format version {version}, this reader reads version {VERSION}: bake again"
            )));
        }
        let len = r.u32("header length")? as usize;
        let header: Header = serde_json::from_slice(r.take(len, "header")?)
            .map_err(|e| bad(format!("header: {e}")))?;
        check_header(&header)?;
        let crc = r.u32("checksum")?;
        let body = &bytes[r.at..];
        let want = body_len(&header).ok_or_else(|| bad("header counts overflow"))?;
        if body.len() as u64 != want {
            return Err(bad(format!(
                "body is {} bytes, the header's counts give {want} (truncated or padded)",
                body.len()
            )));
        }
        if crc32fast::hash(body) != crc {
            return Err(bad("checksum mismatch: the file is corrupted"));
        }
        let data = parse_body(header, body)?;
        check_body(&data)?;
        Ok(data)
    }
}

fn bad(message: impl Into<String>) -> LiveError {
    LiveError::Malformed {
        path: "live.bin".into(),
        message: message.into(),
    }
}

fn put_u32s(out: &mut Vec<u8>, v: &[u32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Bytes of the body for `h`'s counts.
fn body_len(h: &Header) -> Option<u64> {
    let (p, t) = (h.patches, h.texels);
    let dirs = h
        .lights
        .iter()
        .try_fold(0u64, |a, l| a.checked_add(l.directions(h.grid)))?;
    let padding = h.padding.iter().try_fold(0u64, |a, b| a.checked_add(*b))?;
    let parts = [
        p.checked_mul(12)?,
        (p + 1).checked_mul(4)?,
        h.entries.checked_mul(6)?,
        dirs.checked_mul(p)?,
        t.checked_mul(4 + 4 + 16 + 4 + 2)?,
        padding.checked_mul(5)?,
        h.probes.as_ref().map_or(Some(0), |q| {
            q.count
                .checked_mul(1 + 4 * q.rays as u64)?
                .checked_add(p * 12)
        })?,
    ];
    parts.iter().try_fold(0u64, |a, b| a.checked_add(*b))
}

fn check_header(h: &Header) -> Result<()> {
    if h.patches > MAX_COUNT || h.texels > MAX_COUNT || h.padding.iter().any(|&n| n > 1 << 30) {
        return Err(bad("patch, texel or padding count out of range"));
    }
    if h.entries > u32::MAX as u64 {
        return Err(bad("F's entry count out of range"));
    }
    if !(2..=64).contains(&h.grid) || !(1..=64).contains(&h.block) {
        return Err(bad(format!(
            "grid {} or block {} out of range",
            h.grid, h.block
        )));
    }
    if h.lights.is_empty() {
        return Err(bad("no live light"));
    }
    let finite = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
    if h.lights
        .iter()
        .any(|l| !finite(&l.direction) || !finite(&l.irradiance))
    {
        return Err(bad("a live light's direction or irradiance is not finite"));
    }
    if h.lights
        .iter()
        .any(|l| l.direction.iter().all(|&x| x == 0.0))
    {
        return Err(bad("a live light's direction is of zero length"));
    }
    let path_ok = |p: &Vec<[f32; 3]>| !p.is_empty() && p.len() <= 4096 && p.iter().all(finite);
    if h.lights
        .iter()
        .any(|l| l.path.as_ref().is_some_and(|p| !path_ok(p)))
    {
        return Err(bad(
            "a live light's sun path is empty, too long or not finite",
        ));
    }
    if !(h.tolerance.is_finite() && h.tolerance > 0.0) || h.max_iterations == 0 {
        return Err(bad("solver tolerance or iteration limit out of range"));
    }
    let page_ok =
        |p: &PageSize| (1..=1 << 15).contains(&p.width) && (1..=1 << 15).contains(&p.height);
    if h.pages.is_empty() || h.pages.len() > u16::MAX as usize || !h.pages.iter().all(page_ok) {
        return Err(bad("no pages, or a page size out of range"));
    }
    if h.padding.len() != h.pages.len() {
        return Err(bad("the padding counts do not match the pages"));
    }
    if let Some(q) = &h.probes {
        check_probe_header(q)?;
    }
    Ok(())
}

/// The probe grids cover the probes in order, the counts in range.
fn check_probe_header(q: &ProbeHeader) -> Result<()> {
    if q.count > MAX_COUNT || !(1..=4096).contains(&q.rays) {
        return Err(bad("probe count or rays per probe out of range"));
    }
    let mut next = 0u64;
    for g in &q.grids {
        let [x, y, z] = g.resolution.map(u64::from);
        let n = x.checked_mul(y).and_then(|n| n.checked_mul(z));
        if g.first != next || n.is_none_or(|n| n == 0 || n > MAX_COUNT) {
            return Err(bad("the probe grids do not cover the probes in order"));
        }
        next += n.unwrap_or(0);
    }
    if next != q.count {
        return Err(bad(format!(
            "the probe grids hold {next} probes, the header says {}",
            q.count
        )));
    }
    Ok(())
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| bad(format!("truncated in its {what}")))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }

    fn u32s(&mut self, n: u64, what: &str) -> Result<Vec<u32>> {
        let b = self.take(n as usize * 4, what)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn u16s(&mut self, n: u64, what: &str) -> Result<Vec<u16>> {
        let b = self.take(n as usize * 2, what)?;
        Ok(b.chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect())
    }

    fn f32s(&mut self, n: u64, what: &str) -> Result<Vec<f32>> {
        Ok(self
            .u32s(n, what)?
            .into_iter()
            .map(f32::from_bits)
            .collect())
    }
}

fn parse_body(header: Header, body: &[u8]) -> Result<LiveData> {
    let mut r = Reader { bytes: body, at: 0 };
    let (p, t) = (header.patches, header.texels);
    let albedo = r.f32s(p * 3, "albedo")?;
    let rows = r.u32s(p + 1, "F's rows")?;
    let cols = r.u32s(header.entries, "F's columns")?;
    let vals = r.u16s(header.entries, "F's entries")?;
    let suns = (header.lights.iter())
        .map(|l| {
            let n = l.directions(header.grid) as usize * p as usize;
            r.take(n, "sun table").map(<[u8]>::to_vec)
        })
        .collect::<Result<Vec<_>>>()?;
    let patch = r.u32s(t, "texels' patches")?;
    let share = r.f32s(t, "texels' shares")?;
    let corners = r.u32s(t * 4, "texels' corners")?;
    let pixel = r.u32s(t, "texels' pixels")?;
    let page = r.u16s(t, "texels' pages")?;
    let padding = (header.padding.iter())
        .map(|&n| {
            let b = r.take(n as usize * 5, "padding")?;
            Ok(b.chunks_exact(5)
                .map(|c| (u32::from_le_bytes([c[0], c[1], c[2], c[3]]), c[4]))
                .collect())
        })
        .collect::<Result<Vec<_>>>()?;
    let probes = match &header.probes {
        Some(q) => Some(ProbeHits {
            valid: (r.take(q.count as usize, "probes' validity")?.iter())
                .map(|&v| v != 0)
                .collect(),
            hits: r.u32s(q.count * q.rays as u64, "probes' ray hits")?,
            baked: (r.f32s(p * 3, "patches' baked radiance")?.chunks_exact(3))
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        }),
        None => None,
    };
    Ok(LiveData {
        albedo: albedo.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        matrix: Matrix { rows, cols, vals },
        suns,
        texels: TexelMap {
            patch,
            share,
            corners: corners
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
            pixel,
            page,
            padding,
        },
        probes,
        header,
    })
}

/// Every index within its range, every value finite: what the runtime
/// then reads without checks.
fn check_body(d: &LiveData) -> Result<()> {
    let h = &d.header;
    let p = h.patches as usize;
    if d.albedo
        .iter()
        .flatten()
        .any(|a| !(a.is_finite() && *a >= 0.0))
    {
        return Err(bad("an albedo negative or not finite"));
    }
    let m = &d.matrix;
    let rising = m.rows.first() == Some(&0)
        && m.rows.windows(2).all(|w| w[0] <= w[1])
        && *m.rows.last().unwrap() as u64 == h.entries;
    if !rising {
        return Err(bad("F's row starts do not rise from 0 to its entry count"));
    }
    for i in 0..p {
        let cols = &m.cols[m.rows[i] as usize..m.rows[i + 1] as usize];
        if cols.windows(2).any(|w| w[0] >= w[1]) || cols.last().is_some_and(|&c| c as usize >= p) {
            return Err(bad(format!("F's row {i}: columns out of order or range")));
        }
    }
    if m.vals.iter().any(|&v| {
        let f = half::f16::from_bits(v);
        !f.is_finite() || f < half::f16::ZERO
    }) {
        return Err(bad("an entry of F is negative or not finite"));
    }
    let t = &d.texels;
    let pages = &h.pages;
    if t.patch.iter().any(|&q| q as usize >= p) {
        return Err(bad("a texel's patch out of range"));
    }
    if t.share.iter().any(|s| !(0.0..=1.0001).contains(s)) {
        return Err(bad("a texel's area share outside [0, 1]"));
    }
    if t.corners
        .iter()
        .flatten()
        .any(|&q| q != u32::MAX && q as usize >= p)
    {
        return Err(bad("a texel's corner patch out of range"));
    }
    let size = |page: usize| pages[page].width as u64 * pages[page].height as u64;
    let on_page = (t.pixel.iter().zip(&t.page))
        .all(|(&i, &pg)| (pg as usize) < pages.len() && (i as u64) < size(pg as usize));
    if !on_page {
        return Err(bad("a texel's pixel out of its page"));
    }
    for (pg, list) in t.padding.iter().enumerate() {
        let (w, hgt) = (pages[pg].width as i64, pages[pg].height as i64);
        let ok = |&(i, n): &(u32, u8)| {
            let (x, y) = (i as i64 % w, i as i64 / w);
            let (dx, dy) = (n as i64 % 3 - 1, n as i64 / 3 - 1);
            (i as u64) < size(pg)
                && n <= 8
                && (0..w).contains(&(x + dx))
                && (0..hgt).contains(&(y + dy))
        };
        if !list.iter().all(ok) {
            return Err(bad("a padding pixel or its neighbour out of its page"));
        }
    }
    if let Some(q) = &d.probes {
        if q.hits.iter().any(|&x| x != u32::MAX && x as usize >= p) {
            return Err(bad("a probe ray's patch out of range"));
        }
        if q.baked.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("a patch's baked radiance is not finite"));
        }
    }
    Ok(())
}
