//! The kept episodes' videos: a source file whose episodes are all kept whole is copied
//! byte for byte; otherwise the kept frames are cut out of it by stream copy (each
//! episode starts a closed group of pictures where it was encoded on its own and
//! joined, as lerobot and convert write them), so every frame stays bit-exact. A
//! trimmed episode whose first or last kept frame is no place a stream copy can start or
//! end gets a smart cut: only the frames outside the copyable span are re-encoded, with
//! the source's own stream headers; where no encoder setting reproduces those, the
//! output file is re-encoded whole (keyframes at every episode start).

use std::collections::HashMap;
use std::path::Path;

use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_video::{
    ConcatInput, CutPoints, Encoding, Keyframes, StatedEncoding, VideoSpec, candidate_encodings,
    concat_copy, smart_cut, transcode,
};
use serde_json::Value;

use crate::EditError;

/// Where a kept episode's frames of one video feature are in the output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct VideoPlace {
    pub chunk: i64,
    pub file: i64,
    pub from: f64,
    pub to: f64,
}

/// How the output's video files were made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct VideoCounts {
    /// Files copied whole.
    pub copied: usize,
    /// Files made by cutting episodes out by stream copy.
    pub cut: usize,
    /// Frames re-encoded by smart cuts.
    pub frames_reencoded: usize,
    /// Files re-encoded whole.
    pub reencoded: usize,
}

/// One feature's source placement of every episode.
pub(crate) struct Placement {
    chunk: Vec<i64>,
    file: Vec<i64>,
    from: Vec<f64>,
    to: Vec<f64>,
    lengths: Vec<i64>,
}

impl Placement {
    /// The placement of video feature `key`'s episodes, each checked against its file
    /// before anything is cut or copied: its span holds its length in frames and lies
    /// within the file's frames (counted by probing each file once). A span past the end
    /// would otherwise be cut short, silently.
    pub(crate) fn checked(ds: &LeRobotDataset, key: &str) -> Result<Self, EditError> {
        let col = |s: &str| format!("videos/{key}/{s}");
        let place = Self {
            chunk: ds.int_column(&col("chunk_index"))?,
            file: ds.int_column(&col("file_index"))?,
            from: ds.float_column(&col("from_timestamp"))?,
            to: ds.float_column(&col("to_timestamp"))?,
            lengths: ds.lengths()?,
        };
        let mut frames: HashMap<(i64, i64), u64> = HashMap::new();
        for row in 0..ds.len() {
            let (chunk, file) = place.source(row);
            let src = ds.video_file(key, chunk, file);
            let context = |r: usize| format!("video '{}' of episode {r} ({key})", src.display());
            let in_file = match frames.get(&(chunk, file)) {
                Some(n) => *n,
                None => {
                    let n = dexjoco_video::probe(&src)
                        .map_err(|source| EditError::Video {
                            context: context(row),
                            source,
                        })?
                        .frames;
                    *frames.entry((chunk, file)).or_insert(n)
                }
            };
            place.check_within(row, in_file, ds.fps, &context)?;
        }
        Ok(place)
    }

    /// Episode `row`'s video file (chunk and file indices).
    pub(crate) fn source(&self, row: usize) -> (i64, i64) {
        (self.chunk[row], self.file[row])
    }

    /// Episode `row`'s first frame and frame count in its file: its span must hold its
    /// length in frames, at a non-negative time.
    pub(crate) fn span(
        &self,
        row: usize,
        fps: f64,
        context: &dyn Fn(usize) -> String,
    ) -> Result<(i64, i64), EditError> {
        let start = (self.from[row] * fps).round() as i64;
        let n = ((self.to[row] - self.from[row]) * fps).round() as i64;
        if n != self.lengths[row] || start < 0 || n < 1 || !self.from[row].is_finite() {
            return Err(EditError::Selection(format!(
                "{}: its timestamps {}..{} s hold {n} frames but the episode has {}",
                context(row),
                self.from[row],
                self.to[row],
                self.lengths[row]
            )));
        }
        Ok((start, n))
    }

    /// Refuses episode `row` when its span runs past the `frames` of its video file.
    fn check_within(
        &self,
        row: usize,
        frames: u64,
        fps: f64,
        context: &dyn Fn(usize) -> String,
    ) -> Result<(), EditError> {
        let (start, n) = self.span(row, fps, context)?;
        if (start + n) as u64 > frames {
            return Err(EditError::Selection(format!(
                "{}: its timestamps {}..{} s place frames {start}..{} but the file holds {frames} \
                 frames: the episode rows do not describe this file (a truncated or replaced \
                 video?)",
                context(row),
                self.from[row],
                self.to[row],
                start + n
            )));
        }
        Ok(())
    }
}

/// Writes the video files of feature `key` for the kept source `rows` (in output
/// order), frames `frames[i]` of row `i`, under `dir`; returns each kept episode's
/// placement.
pub(crate) fn write_videos(
    ds: &LeRobotDataset,
    key: &str,
    rows: &[usize],
    frames: &[(i64, i64)],
    dir: &Path,
    progress: &dyn Progress,
) -> Result<(Vec<VideoPlace>, VideoCounts), EditError> {
    let place = Placement::checked(ds, key)?;
    let mut per_file: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for row in 0..ds.len() {
        per_file.entry(place.source(row)).or_default().push(row);
    }
    let kept: HashMap<usize, (i64, i64)> =
        rows.iter().copied().zip(frames.iter().copied()).collect();
    let whole = |r: &usize| kept[r] == (0, place.lengths[*r]);
    let (mut places, mut counts) = (Vec::with_capacity(rows.len()), VideoCounts::default());
    let same_file = |a: &usize, b: &usize| place.source(*a) == place.source(*b);
    progress.phase(key, rows.chunk_by(same_file).count() as u64);
    for (k, group) in rows.chunk_by(same_file).enumerate() {
        let (chunk, file) = ds.placement(k);
        let out = dir.join(ds.video_rel(key, chunk, file));
        fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
        let (src_chunk, src_file) = place.source(group[0]);
        let src = ds.video_file(key, src_chunk, src_file);
        let context = |row: usize| format!("video '{}' of episode {row} ({key})", src.display());
        progress.advance(1, &format!("{key} file {k}"));
        if per_file[&(src_chunk, src_file)] == group && group.iter().all(whole) {
            fs_err::copy(&src, &out)?;
            counts.copied += 1;
            places.extend(group.iter().map(|r| VideoPlace {
                chunk,
                file,
                from: place.from[*r],
                to: place.to[*r],
            }));
            continue;
        }
        let group_frames: Vec<(i64, i64)> = group.iter().map(|r| kept[r]).collect();
        let inputs = cut_inputs(&place, group, &group_frames, &src, ds.fps, &context)?;
        let join = Join {
            src: &src,
            out: &out,
            fps: ds.fps.round() as u32,
            feature: &ds.features()[key],
            scratch: &dir.join(".smart-cut"),
        };
        join.write(&inputs, &group_frames, &mut counts)
            .map_err(|source| EditError::Video {
                context: context(group[0]),
                source,
            })?;
        let mut at = 0i64;
        for (from, to) in group_frames {
            places.push(VideoPlace {
                chunk,
                file,
                from: at as f64 / ds.fps,
                to: (at + to - from) as f64 / ds.fps,
            });
            at += to - from;
        }
    }
    Ok((places, counts))
}

/// One output video file made of cuts of one source file.
struct Join<'a> {
    src: &'a Path,
    out: &'a Path,
    fps: u32,
    /// The feature's info.json entry (its encoder settings).
    feature: &'a Value,
    scratch: &'a Path,
}

impl Join<'_> {
    /// Writes `inputs` (cuts of the source) into the output: by stream copy, with smart
    /// cuts where needed, else re-encoded whole with a keyframe at each episode start.
    fn write(
        &self,
        inputs: &[ConcatInput],
        frames: &[(i64, i64)],
        counts: &mut VideoCounts,
    ) -> Result<(), dexjoco_video::VideoError> {
        if frames.iter().all(|(from, _)| *from == 0) && inputs.iter().all(|i| i.take.is_some()) {
            // Whole episodes or ends cut: concat_copy checks each end itself.
            if let Ok(()) = concat_copy(inputs, self.out, self.fps) {
                counts.cut += 1;
                return Ok(());
            }
        }
        let cuts = CutPoints::of(self.src)?;
        let copyable = |i: &ConcatInput| {
            let end = i.skip + i.take.unwrap_or(cuts.frames() - i.skip);
            cuts.can_start(i.skip) && cuts.can_end(end)
        };
        if inputs.iter().all(copyable) {
            concat_copy(inputs, self.out, self.fps)?;
            counts.cut += 1;
            return Ok(());
        }
        let recorded = dexjoco_video::x264_settings(self.src)?;
        let candidates = encodings(self.feature, recorded);
        fs_err::create_dir_all(self.scratch).map_err(|source| dexjoco_video::VideoError::Io {
            path: self.scratch.to_path_buf(),
            source,
        })?;
        let mut joined = Vec::new();
        let mut reencoded = 0;
        for input in inputs {
            if copyable(input) {
                joined.push(input.clone());
                continue;
            }
            let take = input.take.unwrap_or(cuts.frames() - input.skip);
            match smart_cut(self.src, input.skip, take, &cuts, &candidates, self.scratch)? {
                Some(cut) => {
                    reencoded += cut.reencoded;
                    joined.extend(cut.inputs);
                }
                None => {
                    joined.clear();
                    break;
                }
            }
        }
        let result =
            if joined.is_empty() {
                counts.reencoded += 1;
                let first = candidates.first().copied().ok_or_else(|| {
                    dexjoco_video::VideoError::Failed {
                        program: "smart cut".into(),
                        path: self.src.to_path_buf(),
                        message: "no encoder for this codec (H.264 and AV1 only)".into(),
                    }
                })?;
                self.reencode(inputs, frames, first)
            } else {
                counts.cut += 1;
                counts.frames_reencoded += reencoded;
                concat_copy(&joined, self.out, self.fps)
            };
        let _ = fs_err::remove_dir_all(self.scratch);
        result
    }

    /// Re-encodes `inputs` whole with `encoding`, a keyframe at each episode's start.
    fn reencode(
        &self,
        inputs: &[ConcatInput],
        frames: &[(i64, i64)],
        encoding: Encoding,
    ) -> Result<(), dexjoco_video::VideoError> {
        let info = dexjoco_video::probe(self.src)?;
        let spec = VideoSpec {
            width: info.width,
            height: info.height,
            fps: self.fps,
            codec: encoding.codec,
        };
        let mut at = Vec::new();
        let mut start = 0;
        for (from, to) in frames {
            at.push(start);
            start += (to - from) as usize;
        }
        let keyframes = Keyframes {
            interval: encoding.interval,
            at,
        };
        transcode(inputs, self.out, spec, &keyframes).map(|_| ())
    }
}

/// The encoder settings to try for re-encoded frames of a video feature: the crf and
/// keyframe interval x264 `recorded` in the file, else its info.json entry's
/// (`video.crf`, `video.preset`, `video.g`, as lerobot and convert record them).
fn encodings(feature: &Value, recorded: Option<dexjoco_video::X264Settings>) -> Vec<Encoding> {
    let info = &feature["info"];
    let stated = StatedEncoding {
        crf: info["video.crf"].as_u64().map(|c| c.min(63) as u8),
        preset: match &info["video.preset"] {
            Value::String(p) => Some(p.clone()),
            Value::Number(n) => Some(n.to_string()),
            _ => None,
        },
        interval: info["video.g"].as_u64().map(|g| g as u32),
    };
    let codec = info["video.codec"].as_str().unwrap_or("av1");
    candidate_encodings(codec, &stated, recorded)
}

/// The stream-copy cuts of `group`'s episodes (frames `frames[i]` of episode
/// `group[i]`) out of `src`, cuts that follow one another in the source joined.
fn cut_inputs(
    place: &Placement,
    group: &[usize],
    frames: &[(i64, i64)],
    src: &Path,
    fps: f64,
    context: &dyn Fn(usize) -> String,
) -> Result<Vec<ConcatInput>, EditError> {
    let mut inputs: Vec<ConcatInput> = Vec::new();
    let mut end_of_last = None;
    for (&r, &(first, last)) in group.iter().zip(frames) {
        let (start, _) = place.span(r, fps, context)?;
        let (skip, frames) = (start + first, last - first);
        match inputs.last_mut() {
            Some(last) if end_of_last == Some(skip) => {
                last.take = last.take.map(|t| t + frames as usize);
            }
            _ => inputs.push(ConcatInput {
                path: src.to_path_buf(),
                skip: skip as usize,
                take: Some(frames as usize),
            }),
        }
        end_of_last = Some(skip + frames);
    }
    Ok(inputs)
}
