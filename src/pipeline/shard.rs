//! Bakes split into shards that any batch scheduler can run (`radbake
//! shard`), merged into exactly the bytes of a one-process bake.
//!
//! A sharded bake runs the same [`crate::bake`] in every job, each job
//! computing one slice of the bake's expensive per-item loops and reading
//! the other slices from the files earlier jobs wrote:
//!
//! ```text
//! plan               the atlas, texels, burial planes and patches, once (prepared)
//! phase 1 (N jobs)   form-factor rows of a slice of patches, direct light of a slice of texels
//! merge 1 (1 job)    every phase-1 slice read back; the solve
//! phase 2 (N jobs)   the final gather of a slice of texels (sliced by cost)
//! merge 2 (1 job)    every slice read back; denoising, lightmaps, probes, outputs
//! ```
//!
//! Every item's result depends only on its index (each texel and patch
//! draws from its own seeded stream), so a slice computed alone equals the
//! same slice of a whole bake, and the merged outputs are byte-identical to
//! `radbake bake`'s for any number of shards and any order of completion.
//!
//! A [`Sharding`] is what the loops ask: [`Sharding::items`] computes,
//! writes or reads a stage's items; [`Sharding::once`] does the same for a
//! merge's product (the solve); [`Sharding::checkpoint`] ends a job whose
//! part is done ([`Error::ShardDone`]). A slice file holds a JSON header
//! (stage, item range, the plan's content hash, a BLAKE3 checksum of the
//! payload) and the items, postcard-encoded and zstd-compressed; it is
//! written atomically, so a job killed and run again leaves the same bytes.
//!
//! `shard plan` computes the stages before the sliced ones once and writes
//! them ([`Sharding::prepared`]: atlas, texels, burial planes, patches);
//! every job imports the work folder's copy of the scene, reads those, and
//! builds the world triangles and the BVH again.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Which part of a sharded bake this process runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    /// The whole bake in one process (`radbake bake`).
    Whole,
    /// `shard plan`: the stages before the sliced ones (texels, burial),
    /// computed once and written for every job to read.
    Prepare,
    /// Job `index` of `count` of phase `phase` (1 or 2).
    Run {
        /// 1: rows and direct light; 2: the final gather.
        phase: u8,
        /// This job's slice.
        index: u32,
        /// Jobs in the phase.
        count: u32,
    },
    /// The merge of phase `phase` (1: the solve; 2: the outputs).
    Merge {
        /// 1 or 2.
        phase: u8,
    },
}

/// What the bake's sliced loops read: the job, where slice files live,
/// how many shards each phase has, and the plan's content hash (a slice
/// of another plan is refused).
#[derive(Clone, Debug)]
pub struct Sharding {
    /// This process's part.
    pub job: Job,
    /// `<work>/shards`.
    pub dir: PathBuf,
    /// Jobs per phase (phase 1, phase 2).
    pub shards: [u32; 2],
    /// The plan's content hash ([`crate::pipeline::incremental::content_hash`]).
    pub hash: String,
}

/// The stages that are sliced, the phase each belongs to.
const STAGES: [(&str, u8); 3] = [("rows", 1), ("direct", 1), ("gather", 2)];

/// Header of a slice file.
#[derive(Debug, Serialize, Deserialize, PartialEq)]
struct Header {
    stage: String,
    items: u64,
    start: u64,
    end: u64,
    plan: String,
    /// BLAKE3 of the payload, hex.
    blake3: String,
}

const MAGIC: &[u8; 8] = b"RBSHARD1";

impl Sharding {
    /// A whole bake: every loop computes everything, nothing is written.
    pub fn whole() -> Sharding {
        Sharding {
            job: Job::Whole,
            dir: PathBuf::new(),
            shards: [1, 1],
            hash: String::new(),
        }
    }

    /// True for a whole bake.
    pub fn is_whole(&self) -> bool {
        self.job == Job::Whole
    }

    fn phase_of(stage: &str) -> u8 {
        STAGES.iter().find(|s| s.0 == stage).map_or(2, |s| s.1)
    }

    /// The file of `stage`'s slice `index`.
    pub fn slice_path(&self, stage: &str, index: u32) -> PathBuf {
        self.dir.join(format!("{stage}_{index:04}.bin"))
    }

    /// The file of a merge's product.
    pub fn merged_path(&self, stage: &str) -> PathBuf {
        self.dir.join(format!("{stage}.bin"))
    }

    /// `stage`'s `n` items. A whole bake computes them all. The job of
    /// `stage`'s phase computes its slice (`ranges(count)[index]`), writes
    /// it, and returns it with default items elsewhere (nothing reads
    /// them: the job ends at its [`Sharding::checkpoint`]). Later jobs and
    /// merges read every slice back. `compute` must give the items of a
    /// range, in order, each depending only on its index.
    ///
    /// # Errors
    /// [`Error::Shard`]: a slice missing, corrupt, of another plan or not
    /// covering its range; [`Error::Io`] writing one.
    pub fn items<T>(
        &self,
        stage: &str,
        n: usize,
        ranges: impl FnOnce(u32) -> Vec<Range<usize>>,
        compute: impl FnOnce(Range<usize>) -> Vec<T>,
    ) -> Result<Vec<T>>
    where
        T: Serialize + DeserializeOwned + Default + Clone,
    {
        let phase = Self::phase_of(stage);
        let count = self.shards[phase as usize - 1];
        match self.job {
            Job::Whole => Ok(compute(0..n)),
            Job::Run {
                phase: p, index, ..
            } if p == phase => {
                let ranges = ranges(count);
                let range = ranges.get(index as usize).cloned().ok_or_else(|| {
                    shard_error(&self.dir, format!("phase {phase} has no job {index}"))
                })?;
                let slice = compute(range.clone());
                self.write(
                    &self.slice_path(stage, index),
                    stage,
                    n,
                    range.clone(),
                    &slice,
                )?;
                let mut all = vec![T::default(); n];
                all[range].clone_from_slice(&slice);
                Ok(all)
            }
            _ => {
                let ranges = ranges(count);
                let mut all = Vec::with_capacity(n);
                for (index, range) in ranges.into_iter().enumerate() {
                    let path = self.slice_path(stage, index as u32);
                    let slice: Vec<T> = self.read(&path, stage, n, range)?;
                    all.extend(slice);
                }
                Ok(all)
            }
        }
    }

    /// A product of the stages before the sliced ones: computed (and
    /// written) by `shard plan`, read by every job; a whole bake just
    /// computes it. The job that prepares stops after the last of them
    /// ([`Sharding::checkpoint`] with phase 0).
    ///
    /// # Errors
    /// As [`Sharding::items`].
    pub fn prepared<T>(&self, stage: &str, compute: impl FnOnce() -> Result<T>) -> Result<T>
    where
        T: Serialize + DeserializeOwned,
    {
        let path = self.merged_path(stage);
        match self.job {
            Job::Whole => compute(),
            Job::Prepare => {
                let v = compute()?;
                self.write(&path, stage, 1, 0..1, std::slice::from_ref(&v))?;
                Ok(v)
            }
            _ => {
                let mut v: Vec<T> = self.read(&path, stage, 1, 0..1)?;
                v.pop().ok_or_else(|| shard_error(&path, "empty".into()))
            }
        }
    }

    /// A merge's product: computed by merge `phase` (and written), read
    /// by every later job; a whole bake just computes it.
    ///
    /// # Errors
    /// As [`Sharding::items`].
    pub fn once<T>(&self, stage: &str, phase: u8, compute: impl FnOnce() -> Result<T>) -> Result<T>
    where
        T: Serialize + DeserializeOwned,
    {
        let path = self.merged_path(stage);
        match self.job {
            Job::Whole => compute(),
            Job::Merge { phase: p } if p == phase => {
                let v = compute()?;
                self.write(&path, stage, 1, 0..1, std::slice::from_ref(&v))?;
                Ok(v)
            }
            _ => {
                let mut v: Vec<T> = self.read(&path, stage, 1, 0..1)?;
                v.pop().ok_or_else(|| shard_error(&path, "empty".into()))
            }
        }
    }

    /// Ends the job here if its part is done: phase `phase`'s jobs after
    /// its stages (`merge = false`), merge `phase` after its product.
    ///
    /// # Errors
    /// [`Error::ShardDone`] when this job is done (not a failure).
    pub fn checkpoint(&self, phase: u8, merge: bool) -> Result<()> {
        let done = match self.job {
            Job::Prepare => phase == 0,
            Job::Run { phase: p, .. } => !merge && p == phase,
            Job::Merge { phase: p } => merge && p == phase,
            Job::Whole => false,
        };
        if done {
            Err(Error::ShardDone)
        } else {
            Ok(())
        }
    }

    fn write<T: Serialize>(
        &self,
        path: &Path,
        stage: &str,
        n: usize,
        range: Range<usize>,
        items: &[T],
    ) -> Result<()> {
        let encoded = postcard::to_stdvec(items)
            .map_err(|e| shard_error(path, format!("cannot encode: {e}")))?;
        let payload = zstd::bulk::compress(&encoded, 3)
            .map_err(|e| shard_error(path, format!("cannot compress: {e}")))?;
        let header = Header {
            stage: stage.into(),
            items: n as u64,
            start: range.start as u64,
            end: range.end as u64,
            plan: self.hash.clone(),
            blake3: blake3::hash(&payload).to_hex().to_string(),
        };
        let header = serde_json::to_vec(&header).unwrap_or_default();
        let mut bytes = Vec::with_capacity(16 + header.len() + payload.len());
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&header);
        bytes.extend_from_slice(&payload);
        std::fs::create_dir_all(&self.dir).map_err(|source| Error::Io {
            path: self.dir.clone(),
            source,
        })?;
        crate::util::files::write_bytes_atomic(path, &bytes)
    }

    fn read<T: DeserializeOwned>(
        &self,
        path: &Path,
        stage: &str,
        n: usize,
        range: Range<usize>,
    ) -> Result<Vec<T>> {
        let bytes = std::fs::read(path).map_err(|e| {
            let why = if e.kind() == std::io::ErrorKind::NotFound {
                "missing: its job has not run, or did not finish".to_string()
            } else {
                format!("cannot be read: {e}")
            };
            shard_error(path, why)
        })?;
        let corrupt = |why: &str| shard_error(path, format!("corrupt ({why}); run its job again"));
        if bytes.len() < 16 || &bytes[..8] != MAGIC {
            return Err(corrupt("not a radbake shard file"));
        }
        let hlen = u64::from_le_bytes(bytes[8..16].try_into().unwrap_or_default()) as usize;
        let body = bytes.get(16..).unwrap_or_default();
        if hlen > body.len() {
            return Err(corrupt("truncated header"));
        }
        let header: Header =
            serde_json::from_slice(&body[..hlen]).map_err(|_| corrupt("unreadable header"))?;
        let payload = &body[hlen..];
        if blake3::hash(payload).to_hex().as_str() != header.blake3 {
            return Err(corrupt("checksum mismatch"));
        }
        if header.plan != self.hash {
            return Err(shard_error(
                path,
                "written for another scene or other settings; run its job again".into(),
            ));
        }
        let want = (stage, n as u64, range.start as u64, range.end as u64);
        let got = (
            header.stage.as_str(),
            header.items,
            header.start,
            header.end,
        );
        if want != got {
            return Err(shard_error(
                path,
                format!(
                    "holds {} items {}..{} of {}, expected {} items {}..{} of {}",
                    got.0, got.2, got.3, got.1, want.0, want.2, want.3, want.1
                ),
            ));
        }
        let decoded = zstd::bulk::decompress(payload, 1 << 34).map_err(|_| corrupt("zstd"))?;
        let items: Vec<T> = postcard::from_bytes(&decoded).map_err(|_| corrupt("decoding"))?;
        if items.len() != range.len() {
            return Err(corrupt("item count"));
        }
        Ok(items)
    }
}

fn shard_error(path: &Path, message: String) -> Error {
    Error::Shard {
        path: path.to_path_buf(),
        message,
    }
}

/// `n` items in `count` contiguous ranges of (nearly) equal length.
pub fn even(n: usize, count: u32) -> Vec<Range<usize>> {
    let count = count.max(1) as usize;
    (0..count)
        .map(|k| (k * n / count)..((k + 1) * n / count))
        .collect()
}

/// Items in `count` contiguous ranges of (nearly) equal total `cost`: each
/// range ends where the running cost first reaches its share.
pub fn balanced(cost: &[f64], count: u32) -> Vec<Range<usize>> {
    let count = count.max(1) as usize;
    let total: f64 = cost.iter().sum();
    let mut ranges = Vec::with_capacity(count);
    let (mut start, mut sum, mut i) = (0usize, 0.0f64, 0usize);
    for k in 1..=count {
        let target = total * k as f64 / count as f64;
        while i < cost.len() && (k == count || sum + cost[i] * 0.5 < target) {
            sum += cost[i];
            i += 1;
        }
        ranges.push(start..i);
        start = i;
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ranges cover every item once, in order; balanced ranges split the
    /// cost evenly where it is uneven.
    #[test]
    fn ranges_cover_everything_once() {
        for (n, count) in [(0usize, 3u32), (1, 4), (10, 3), (1000, 7)] {
            let r = even(n, count);
            assert_eq!(r.len(), count as usize);
            assert_eq!(r[0].start, 0);
            assert_eq!(r.last().unwrap().end, n);
            assert!(r.windows(2).all(|w| w[0].end == w[1].start));
        }
        // The first half costs 9 × the second: two shards split at 10 %… of items.
        let cost: Vec<f64> = (0..100).map(|i| if i < 50 { 9.0 } else { 1.0 }).collect();
        let r = balanced(&cost, 2);
        assert_eq!(r.len(), 2);
        assert_eq!(r[1].end, 100);
        let sums: Vec<f64> = r.iter().map(|r| cost[r.clone()].iter().sum()).collect();
        assert!((sums[0] - sums[1]).abs() <= 9.0, "{sums:?}");
        assert_eq!(balanced(&[], 3), vec![0..0, 0..0, 0..0]);
    }

    /// A slice round-trips; a flipped byte, a missing file, another plan's
    /// slice and a wrong range are refused with the file named.
    #[test]
    fn slices_round_trip_and_refuse_bad_files() {
        let dir = std::env::temp_dir().join(format!("radbake-shard-unit-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let job = |index| Sharding {
            job: Job::Run {
                phase: 1,
                index,
                count: 2,
            },
            dir: dir.clone(),
            shards: [2, 2],
            hash: "abc".into(),
        };
        let compute = |r: Range<usize>| r.map(|i| i as u32 * 3).collect::<Vec<u32>>();
        for i in 0..2 {
            job(i).items("rows", 10, |c| even(10, c), compute).unwrap();
        }
        let merge = Sharding {
            job: Job::Merge { phase: 1 },
            ..job(0)
        };
        let all = merge.items("rows", 10, |c| even(10, c), compute).unwrap();
        assert_eq!(all, compute(0..10));
        let path = merge.slice_path("rows", 1);
        let good = std::fs::read(&path).unwrap();
        let mut bad = good.clone();
        *bad.last_mut().unwrap() ^= 1;
        std::fs::write(&path, &bad).unwrap();
        let e = merge
            .items("rows", 10, |c| even(10, c), compute)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rows_0001.bin") && e.contains("checksum"), "{e}");
        std::fs::remove_file(&path).unwrap();
        let e = merge
            .items("rows", 10, |c| even(10, c), compute)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rows_0001.bin") && e.contains("missing"), "{e}");
        std::fs::write(&path, &good).unwrap();
        let other = Sharding {
            hash: "def".into(),
            ..merge.clone()
        };
        let e = other
            .items("rows", 10, |c| even(10, c), compute)
            .unwrap_err()
            .to_string();
        assert!(e.contains("another scene"), "{e}");
        let e = merge
            .items("rows", 12, |c| even(12, c), compute)
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
