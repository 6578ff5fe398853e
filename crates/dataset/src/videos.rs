//! The kept episodes' videos: a source file whose episodes are all kept is copied byte
//! for byte; otherwise the kept episodes are cut out of it by stream copy (each
//! episode starts a closed group of pictures where it was encoded on its own and
//! joined, as lerobot and convert write them), so every frame stays bit-exact.

use std::collections::HashMap;
use std::path::Path;

use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::{LeRobotDataset, fill_template};
use dexjoco_video::{ConcatInput, concat_copy};

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
}

/// One feature's source placement of every episode.
struct Placement {
    chunk: Vec<i64>,
    file: Vec<i64>,
    from: Vec<f64>,
    to: Vec<f64>,
    lengths: Vec<i64>,
}

impl Placement {
    fn read(ds: &LeRobotDataset, key: &str) -> Result<Self, EditError> {
        let col = |s: &str| format!("videos/{key}/{s}");
        Ok(Self {
            chunk: ds.int_column(&col("chunk_index"))?,
            file: ds.int_column(&col("file_index"))?,
            from: ds.float_column(&col("from_timestamp"))?,
            to: ds.float_column(&col("to_timestamp"))?,
            lengths: ds.lengths()?,
        })
    }

    fn source(&self, row: usize) -> (i64, i64) {
        (self.chunk[row], self.file[row])
    }
}

/// Writes the video files of feature `key` for the kept source `rows` (in output
/// order) under `dir`; returns each kept episode's placement.
pub(crate) fn write_videos(
    ds: &LeRobotDataset,
    key: &str,
    rows: &[usize],
    dir: &Path,
    chunks_size: i64,
    progress: &dyn Progress,
) -> Result<(Vec<VideoPlace>, VideoCounts), EditError> {
    let place = Placement::read(ds, key)?;
    let mut per_file: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for row in 0..ds.len() {
        per_file.entry(place.source(row)).or_default().push(row);
    }
    let template = ds.info["video_path"].as_str().unwrap_or("").to_owned();
    let fps = ds.fps.round() as u32;
    let (mut places, mut counts) = (Vec::with_capacity(rows.len()), VideoCounts::default());
    let same_file = |a: &usize, b: &usize| place.source(*a) == place.source(*b);
    progress.phase(key, rows.chunk_by(same_file).count() as u64);
    for (k, group) in rows.chunk_by(same_file).enumerate() {
        let done = || progress.advance(1, &format!("{key} file {k}"));
        let (chunk, file) = (k as i64 / chunks_size, k as i64 % chunks_size);
        let rel = fill_template(
            &template,
            &[
                ("video_key", key, 0),
                ("chunk_index", "", chunk),
                ("file_index", "", file),
            ],
        );
        let out = dir.join(rel);
        fs_err::create_dir_all(out.parent().unwrap_or(dir))?;
        let (src_chunk, src_file) = place.source(group[0]);
        let src = ds.video_file(key, src_chunk, src_file);
        let context = |row: usize| format!("video '{}' of episode {row} ({key})", src.display());
        if per_file[&(src_chunk, src_file)] == group {
            fs_err::copy(&src, &out)?;
            counts.copied += 1;
            done();
            places.extend(group.iter().map(|r| VideoPlace {
                chunk,
                file,
                from: place.from[*r],
                to: place.to[*r],
            }));
            continue;
        }
        let inputs = cut_inputs(&place, group, &src, ds.fps, &context)?;
        concat_copy(&inputs, &out, fps).map_err(|source| EditError::Video {
            context: context(group[0]),
            source,
        })?;
        counts.cut += 1;
        done();
        let mut frames = 0i64;
        for r in group {
            let n = place.lengths[*r];
            places.push(VideoPlace {
                chunk,
                file,
                from: frames as f64 / ds.fps,
                to: (frames + n) as f64 / ds.fps,
            });
            frames += n;
        }
    }
    Ok((places, counts))
}

/// The stream-copy cuts of `group`'s episodes out of `src`, episodes that follow one
/// another in the source joined into one cut.
fn cut_inputs(
    place: &Placement,
    group: &[usize],
    src: &Path,
    fps: f64,
    context: &dyn Fn(usize) -> String,
) -> Result<Vec<ConcatInput>, EditError> {
    let mut inputs: Vec<ConcatInput> = Vec::new();
    let mut end_of_last = None;
    for &r in group {
        let skip = (place.from[r] * fps).round() as i64;
        let frames = ((place.to[r] - place.from[r]) * fps).round() as i64;
        if frames != place.lengths[r] || skip < 0 || frames < 1 || !place.from[r].is_finite() {
            return Err(EditError::Selection(format!(
                "{}: its timestamps {}..{} s hold {frames} frames but the episode has {}",
                context(r),
                place.from[r],
                place.to[r],
                place.lengths[r]
            )));
        }
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
