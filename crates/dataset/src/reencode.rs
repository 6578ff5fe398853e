//! `dataset reencode`: a dataset's videos encoded again with another codec, quality or
//! keyframe interval, into a new dataset; every other file copied as it is. Each video
//! file is decoded (as yuv420p, no colour conversion) and encoded with a keyframe at
//! every episode's first frame, whatever the interval, so later filters and splits
//! still cut it by stream copy. Files are independent: they run in parallel and the
//! bytes do not depend on the worker count (one encoder thread each).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::fs::StagedDir;
use dexjoco_video::{Codec, ConcatInput, Encoding, Keyframes, VideoSpec, probe, transcode};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{Value, json};

use crate::EditError;
use crate::subset::check_output;

/// What to re-encode, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ReencodeOptions {
    /// Codec, quality and keyframe interval of the new videos.
    pub encoding: Encoding,
    /// The video features to re-encode (empty: all).
    pub keys: Vec<String>,
    /// Files encoded at once.
    pub jobs: usize,
}

/// What a re-encode did.
#[derive(Debug, Clone, Default, Serialize, PartialEq, Eq)]
pub struct ReencodeReport {
    /// Video files re-encoded.
    pub files: usize,
    /// Frames encoded.
    pub frames: u64,
    /// Bytes of those files before.
    pub bytes_before: u64,
    /// Bytes of the new files.
    pub bytes_after: u64,
}

/// One video file to encode again: source, output and its episodes' first frames.
struct Job {
    key: String,
    src: PathBuf,
    out: PathBuf,
    starts: Vec<usize>,
}

/// Writes `source` with the videos of `options.keys` encoded again to `out` (staged and
/// renamed; an existing `out` is replaced only with `overwrite`).
pub fn reencode(
    source: &Path,
    options: &ReencodeOptions,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<ReencodeReport, EditError> {
    let ds = LeRobotDataset::open(source)?;
    let all = ds.video_keys();
    if let Some(k) = options.keys.iter().find(|k| !all.contains(k)) {
        return Err(EditError::Selection(format!(
            "'{k}' is no video feature of '{}' (video features: {all:?})",
            source.display()
        )));
    }
    let keys: Vec<String> = match options.keys.is_empty() {
        true => all,
        false => options.keys.clone(),
    };
    if keys.is_empty() {
        return Err(EditError::Selection(format!(
            "'{}' has no video features: nothing to re-encode",
            source.display()
        )));
    }
    check_output(source, out, overwrite)?;
    let staged = StagedDir::begin(out)?;
    let jobs = plan(&ds, &keys, staged.path())?;
    let skip: BTreeSet<&Path> = jobs.iter().map(|j| j.src.as_path()).collect();
    copy_except(&ds.root, staged.path(), &skip)?;
    progress.phase("reencode", jobs.len() as u64);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.jobs.max(1))
        .build()
        .map_err(|e| EditError::Selection(format!("worker threads: {e}")))?;
    let done: Vec<Result<(u64, u64, u64), EditError>> = pool.install(|| {
        jobs.par_iter()
            .map(|job| {
                let r = encode(job, options.encoding, ds.fps.round() as u32);
                progress.advance(1, &job.src.display().to_string());
                r
            })
            .collect()
    });
    let mut report = ReencodeReport::default();
    for r in done {
        let (frames, before, after) = r?;
        report.files += 1;
        report.frames += frames;
        report.bytes_before += before;
        report.bytes_after += after;
    }
    record_encoding(&ds, &keys, &jobs, options.encoding, staged.path())?;
    staged.commit()?;
    Ok(report)
}

/// The video files of `keys` and where each episode starts in them.
fn plan(ds: &LeRobotDataset, keys: &[String], dir: &Path) -> Result<Vec<Job>, EditError> {
    let mut jobs = Vec::new();
    for key in keys {
        let col = |s: &str| format!("videos/{key}/{s}");
        let chunk = ds.int_column(&col("chunk_index"))?;
        let file = ds.int_column(&col("file_index"))?;
        let from = ds.float_column(&col("from_timestamp"))?;
        let mut starts: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
        for e in 0..ds.len() {
            let at = (from[e] * ds.fps).round().max(0.0) as usize;
            starts.entry((chunk[e], file[e])).or_default().push(at);
        }
        for ((c, f), mut at) in starts {
            at.sort_unstable();
            let src = ds.video_file(key, c, f);
            let rel = src.strip_prefix(&ds.root).map_err(|_| {
                EditError::Selection(format!(
                    "video '{}' lies outside the dataset",
                    src.display()
                ))
            })?;
            jobs.push(Job {
                key: key.clone(),
                out: dir.join(rel),
                src,
                starts: at,
            });
        }
    }
    Ok(jobs)
}

/// Encodes one file; its frames and bytes before and after.
fn encode(job: &Job, encoding: Encoding, fps: u32) -> Result<(u64, u64, u64), EditError> {
    let context = || format!("video '{}' ({})", job.src.display(), job.key);
    let video = |source| EditError::Video {
        context: context(),
        source,
    };
    let info = probe(&job.src).map_err(video)?;
    let spec = VideoSpec {
        width: info.width,
        height: info.height,
        fps,
        codec: encoding.codec,
    };
    let keyframes = Keyframes {
        interval: encoding.interval,
        at: job.starts.clone(),
    };
    if let Some(parent) = job.out.parent() {
        fs_err::create_dir_all(parent)?;
    }
    let input = ConcatInput::whole(&job.src);
    let frames = transcode(&[input], &job.out, spec, &keyframes).map_err(video)?;
    if frames as u64 != info.frames {
        return Err(EditError::Selection(format!(
            "{}: {frames} frames encoded, the file has {}",
            context(),
            info.frames
        )));
    }
    let size = |p: &Path| fs_err::metadata(p).map(|m| m.len());
    Ok((frames as u64, size(&job.src)?, size(&job.out)?))
}

/// Copies every file under `from` to `to` but those in `skip`.
fn copy_except(from: &Path, to: &Path, skip: &BTreeSet<&Path>) -> Result<(), EditError> {
    fs_err::create_dir_all(to)?;
    for entry in fs_err::read_dir(from)? {
        let path = entry?.path();
        let target = to.join(path.file_name().unwrap_or_default());
        if path.is_dir() {
            copy_except(&path, &target, skip)?;
        } else if !skip.contains(path.as_path()) {
            fs_err::copy(&path, &target)?;
        }
    }
    Ok(())
}

/// info.json with each re-encoded feature's `video.*` entries describing the new files
/// (codec and pixel format as probed, the encoder settings as given).
fn record_encoding(
    ds: &LeRobotDataset,
    keys: &[String],
    jobs: &[Job],
    encoding: Encoding,
    dir: &Path,
) -> Result<(), EditError> {
    let mut info = ds.info.clone();
    for key in keys {
        let Some(job) = jobs.iter().find(|j| &j.key == key) else {
            continue;
        };
        let probed = probe(&job.out).map_err(|source| EditError::Video {
            context: format!("video '{}'", job.out.display()),
            source,
        })?;
        let (crf, preset) = match encoding.codec {
            Codec::H264 { crf, preset } => (crf, json!(preset.name())),
            Codec::Av1 { crf, preset } => (crf, json!(preset)),
        };
        let entry = &mut info["features"][key]["info"];
        if !entry.is_object() {
            *entry = json!({});
        }
        for (name, value) in [
            ("video.codec", json!(probed.codec)),
            ("video.pix_fmt", json!(probed.pix_fmt)),
            ("video.g", json!(encoding.interval)),
            ("video.crf", json!(crf)),
            ("video.preset", preset),
        ] {
            entry[name] = value;
        }
    }
    let text = serde_json::to_string_pretty(&Value::Object(info)).expect("json");
    fs_err::write(dir.join("meta/info.json"), text + "\n")?;
    Ok(())
}
