//! One episode made ready for writing: selected arrays, trimmed start, per-camera video
//! parts (the source file for stream copy, or a re-encoded file) and statistics. Runs in
//! parallel over episodes; writing stays sequential.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::{ArmSetup, Episode, FrameArray, Location};
use dexjoco_formats::dataset::stats::{FeatureStats, ImageSampler, column_stats, sample_indices};
use dexjoco_formats::dataset::{PreparedEpisode, VideoLayout, VideoPart};
use dexjoco_video::{Codec, Keyframes, VideoReader, VideoSpec, VideoWriter};

use crate::config::{Selection, first_moving_frame};
use crate::error::ConvertError;

/// An episode and the folder its camera video paths are relative to.
#[derive(Debug, Clone)]
pub struct InputEpisode {
    /// The episode.
    pub episode: Episode,
    /// The episode folder (videos are `dir.join(camera.video)`).
    pub dir: PathBuf,
}

/// Video codec for encoding (when a source video cannot be stream-copied, or always
/// with `reencode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VideoCodec {
    /// AV1 (libsvtav1, crf 30, preset 12, GOP 2): lerobot's default.
    #[default]
    Av1,
    /// H.264 (libx264, crf 21, GOP 2).
    H264,
}

impl VideoCodec {
    pub(crate) fn codec(self) -> Codec {
        match self {
            Self::Av1 => Codec::Av1 {
                crf: 30,
                preset: 12,
            },
            Self::H264 => Codec::DEXJOCO,
        }
    }

    /// The codec's name as ffprobe and lerobot's info.json give it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Av1 => "av1",
            Self::H264 => "h264",
        }
    }
}

/// How videos are produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VideoOptions {
    /// Encoder for videos that are encoded.
    pub codec: VideoCodec,
    /// Encode every video, even when the source could be stream-copied.
    pub reencode: bool,
}

/// Codecs lerobot's decoders accept in an mp4 and that concatenate by stream copy.
const COPYABLE: [&str; 3] = ["h264", "hevc", "av1"];

fn setup_of(width: usize) -> Option<ArmSetup> {
    match width {
        22 | 23 => Some(ArmSetup::SingleArm),
        44 | 46 => Some(ArmSetup::Bimanual),
        _ => None,
    }
}

fn slice_columns(a: &FrameArray, range: std::ops::Range<usize>, from: usize) -> FrameArray {
    let w = range.len();
    let mut data = Vec::with_capacity((a.len() - from) * w);
    for i in from..a.len() {
        data.extend_from_slice(&a.row(i)[range.clone()]);
    }
    FrameArray::new(w.max(1), data).expect("whole rows")
}

/// Selects, trims and measures one episode; encodes its videos into `work_dir` when
/// `layout` cannot use the source as it is. `ordinal` names temporary files. `float32`:
/// the output stores the values as float32 (static leading frames are then found on
/// the rounded values, as the reference converter's LeRobot writer does).
pub fn prepare(
    input: &InputEpisode,
    selection: &Selection,
    video: VideoOptions,
    layout: VideoLayout,
    float32: bool,
    work_dir: &Path,
    ordinal: usize,
) -> Result<PreparedEpisode, ConvertError> {
    let ep = &input.episode;
    ep.check_consistent()?;
    let sel = selection.for_task(&ep.task);
    let arrays = select_arrays(input, selection, float32)?;
    let fps = ep.fps.round();
    if !(fps >= 1.0 && (ep.fps - fps).abs() < 1e-9) {
        return Err(ConvertError::episode(
            &ep.id,
            format!("fps {} is not a whole number", ep.fps),
        ));
    }
    let fps = fps as u32;
    let Selected {
        action,
        state,
        setup,
        state_range,
        skipped,
    } = arrays;

    let action_names = column_names(&action, setup, sel.action.array_name(), 0..action.width());
    let state_names = match setup {
        Some(s) if state_range.end <= s.proprio_dim() => {
            let l = s.proprio_layout();
            state_range.clone().map(|c| l.column_name(c)).collect()
        }
        _ => state_range.clone().map(|c| format!("state[{c}]")).collect(),
    };

    let mut stats = BTreeMap::new();
    // lerobot stores float32 and computes on what it stores.
    stats.insert(
        "action".to_owned(),
        column_stats(&as_f32(&action), action.width()),
    );
    stats.insert(
        "observation.state".to_owned(),
        column_stats(&as_f32(&state), state.width()),
    );

    let cameras = Cameras {
        input,
        skipped,
        fps,
        video,
        layout,
        work_dir,
        ordinal,
    };
    let mut videos = Vec::new();
    for (name, raw) in camera_mapping(ep, &sel.cameras) {
        let (part, sample_stats) = cameras.part(&name, &raw)?;
        if let Some(s) = sample_stats {
            stats.insert(format!("observation.images.{name}"), s);
        }
        videos.push(part);
    }
    videos.sort_by(|a, b| a.name.cmp(&b.name));
    let instruction = selection.instruction(&ep.task, &ep.prompt);
    Ok(PreparedEpisode {
        id: ep.id.clone(),
        task: ep.task.clone(),
        instruction: instruction.clone(),
        fps,
        action,
        state,
        action_names,
        state_names,
        skipped,
        videos,
        stats,
        label: None,
        vectors: Vec::new(),
        depth: Vec::new(),
        subtasks: Vec::new(),
        task_aug: selection.task_aug(&ep.task, &instruction),
    })
}

/// The selected, trimmed (and merged) arrays of an episode.
struct Selected {
    action: FrameArray,
    state: FrameArray,
    /// The arm setup the columns are named after.
    setup: Option<ArmSetup>,
    /// The state columns taken.
    state_range: std::ops::Range<usize>,
    /// Leading frames skipped.
    skipped: usize,
}

/// Selects the action and state columns, skips static leading frames (found on the
/// selected action, rounded to float32 with `float32`) and, with `merge_bimanual`, lays
/// one-arm episodes into the two-arm layout.
fn select_arrays(
    input: &InputEpisode,
    selection: &Selection,
    float32: bool,
) -> Result<Selected, ConvertError> {
    let ep = &input.episode;
    let sel = selection.for_task(&ep.task);
    let at = |field: &str| Location::episode(&ep.id).field(field).path(&input.dir);
    let missing = |name: &str| ConvertError::Episode {
        at: at(name).into(),
        message: "array missing".into(),
    };
    let action_full = select_action(input, sel.action.array_name())?;
    let state_full = ep
        .array(Episode::STATE)
        .ok_or_else(|| missing(Episode::STATE))?;
    let setup = setup_of(action_full.width());
    let state_range = match (sel.state, setup) {
        (Some(s), _) => s.range(state_full.width()),
        (None, Some(setup)) => 0..setup.proprio_dim().min(state_full.width()),
        (None, None) => 0..state_full.width(),
    };
    if state_range.is_empty() {
        return Err(ConvertError::Episode {
            at: at(Episode::STATE).into(),
            message: format!(
                "the state slice selects no column of {}",
                state_full.width()
            ),
        });
    }
    if ep.is_empty() {
        return Err(ConvertError::episode(&ep.id, "the episode has no frames"));
    }
    let skipped = if selection.skip_static_frames {
        first_moving_frame(&action_full, float32)
    } else {
        0
    };
    let action = slice_columns(&action_full, 0..action_full.width(), skipped);
    let state = slice_columns(state_full, state_range.clone(), skipped);
    if !(selection.merge_bimanual && setup == Some(ArmSetup::SingleArm)) {
        return Ok(Selected {
            action,
            state,
            setup,
            state_range,
            skipped,
        });
    }
    // One arm into the two-arm layout: needs exactly the proprioceptive state.
    let proprio = 0..ArmSetup::SingleArm.proprio_dim();
    let merge_error = || ConvertError::Episode {
        at: at(Episode::STATE).into(),
        message: format!(
            "merging into the two-arm layout needs the proprioceptive state {proprio:?} \
                 (the state slice selects {state_range:?})"
        ),
    };
    let (Some(a), Some(s)) = (
        crate::merge::action_to_bimanual(&action),
        crate::merge::state_to_bimanual(&state),
    ) else {
        return Err(merge_error());
    };
    if state_range != proprio {
        return Err(merge_error());
    }
    Ok(Selected {
        action: a,
        state: s,
        setup: Some(ArmSetup::Bimanual),
        state_range: 0..ArmSetup::Bimanual.proprio_dim(),
        skipped,
    })
}

/// The whole action array `name` of an episode; `action_rotvec` is computed from
/// `action` as the recorder does when the episode lacks it.
fn select_action(input: &InputEpisode, name: &str) -> Result<FrameArray, ConvertError> {
    let ep = &input.episode;
    let at = |field: &str| Location::episode(&ep.id).field(field).path(&input.dir);
    let missing = |name: &str| ConvertError::Episode {
        at: at(name).into(),
        message: "array missing".into(),
    };
    match ep.array(name) {
        Some(a) => Ok(a.clone()),
        None if name == Episode::ACTION_ROTVEC => {
            let a = ep
                .array(Episode::ACTION)
                .ok_or_else(|| missing(Episode::ACTION_ROTVEC))?;
            let setup = setup_of(a.width()).ok_or_else(|| ConvertError::Episode {
                at: at(Episode::ACTION).into(),
                message: format!(
                    "{} values per frame is neither one arm (23) nor two (46)",
                    a.width()
                ),
            })?;
            let mut e = ep.clone();
            e.compute_action_rotvec(setup)?;
            Ok(e.arrays
                .remove(Episode::ACTION_ROTVEC)
                .expect("just computed"))
        }
        None => Err(missing(name)),
    }
}

/// Output camera name -> raw camera: the selection's mapping, or every camera with a
/// video under its own name.
pub(crate) fn camera_mapping(
    ep: &Episode,
    mapping: &BTreeMap<String, String>,
) -> Vec<(String, String)> {
    if mapping.is_empty() {
        ep.cameras
            .iter()
            .filter(|c| c.video.is_some())
            .map(|c| (c.name.clone(), c.name.clone()))
            .collect()
    } else {
        mapping
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    }
}

/// What every camera's video part of one episode is made with.
struct Cameras<'a> {
    input: &'a InputEpisode,
    skipped: usize,
    fps: u32,
    video: VideoOptions,
    layout: VideoLayout,
    work_dir: &'a Path,
    ordinal: usize,
}

impl Cameras<'_> {
    /// The video part of output camera `name` (raw camera `raw`) and the statistics of
    /// its sampled frames.
    fn part(
        &self,
        name: &str,
        raw: &str,
    ) -> Result<(VideoPart, Option<FeatureStats>), ConvertError> {
        let ep = &self.input.episode;
        let n = ep.len();
        if name.contains('/') {
            return Err(ConvertError::episode(
                &ep.id,
                format!("camera name '{name}' contains '/'"),
            ));
        }
        let cam_at = || Location::episode(&ep.id).field(format!("camera {raw}"));
        let rel = ep
            .cameras
            .iter()
            .find(|c| c.name == raw)
            .and_then(|c| c.video.as_ref())
            .ok_or_else(|| ConvertError::Episode {
                at: cam_at().path(&self.input.dir).into(),
                message: format!("no video of camera '{raw}' (cameras: {})", camera_list(ep)),
            })?;
        let src = self.input.dir.join(rel);
        let vid_err = |source: dexjoco_video::VideoError| ConvertError::Video {
            at: cam_at().into(),
            source: source.into(),
        };
        let info = dexjoco_video::probe(&src).map_err(vid_err)?;
        // An evaluated rollout's video holds one frame more: the one after the last step.
        let rollout = self
            .input
            .dir
            .join(dexjoco_formats::raw::EVAL_RECORD)
            .is_file();
        let extra = info.frames as usize == n + 1 && rollout;
        if info.frames as usize != n && !extra {
            return Err(ConvertError::Episode {
                at: cam_at().path(&src).into(),
                message: format!("the video has {} frames, the episode {n}", info.frames),
            });
        }
        let fits = COPYABLE.contains(&info.codec.as_str())
            && info.pix_fmt == "yuv420p"
            && (info.fps - f64::from(self.fps)).abs() < 1e-6;
        let use_source = self
            .use_source(&src, &info, fits, extra, n)
            .map_err(vid_err)?;
        let mut frames = Frames {
            reader: VideoReader::open(&src, None).map_err(vid_err)?,
            skipped: self.skipped,
            end: n,
            samples: sample_indices(n - self.skipped),
            sampler: ImageSampler::default(),
        };
        // Cut off a keyframe: re-encode only the frames before the next one (a smart cut)
        // where an encoder setting reproduces the source's stream headers.
        let smart = match !use_source && fits && !self.video.reencode {
            true if self.layout == VideoLayout::Joined => {
                self.smart_cut(name, &src, &info, n).map_err(vid_err)?
            }
            _ => None,
        };
        let part = match (use_source, smart) {
            (true, _) => {
                frames.sample(|_| Ok(())).map_err(vid_err)?;
                VideoPart {
                    name: name.to_owned(),
                    path: src.clone(),
                    temporary: false,
                    skip: self.skipped,
                    frames: n,
                    bytes: fs_err::metadata(&src)?.len(),
                    info,
                    copied: self.layout != VideoLayout::Frames,
                    reencoded_frames: 0,
                    source: src.clone(),
                }
            }
            (false, Some((out, reencoded))) => {
                frames.sample(|_| Ok(())).map_err(vid_err)?;
                self.made_part(name, &src, out, Some(reencoded))?
            }
            (false, None) => {
                let out = self
                    .work_dir
                    .join(format!("{:06}-{name}.mp4", self.ordinal));
                // Re-encoded to cut: in the source's codec, so that the part joins the
                // dataset's file (or starts one when its parameters differ).
                let codec = match info.codec.as_str() {
                    "h264" if fits && !self.video.reencode => VideoCodec::H264,
                    "av1" if fits && !self.video.reencode => VideoCodec::Av1,
                    _ => self.video.codec,
                };
                self.encode(&mut frames, &out, codec).map_err(vid_err)?;
                self.made_part(name, &src, out, None)?
            }
        };
        Ok((part, frames.sampler.finish()))
    }

    /// Whether the part is the source itself (`fits`: a codec, pixel format and rate
    /// lerobot reads; `extra`: it holds one frame after the episode's `n`).
    fn use_source(
        &self,
        src: &Path,
        info: &dexjoco_video::VideoInfo,
        fits: bool,
        extra: bool,
        n: usize,
    ) -> Result<bool, dexjoco_video::VideoError> {
        // Joined files cut a source's static leading frames by stream copy, which starts
        // at a keyframe only: augment puts one there; others get a smart cut.
        let cuts_at_keyframe =
            self.skipped == 0 || info.keyframes.binary_search(&self.skipped).is_ok();
        Ok(match self.layout {
            VideoLayout::Joined => {
                // A copy leaves the extra last frame out only where no kept frame refers
                // to it.
                let ends_cleanly = !extra || dexjoco_video::CutPoints::of(src)?.can_end(n);
                fits && !self.video.reencode && cuts_at_keyframe && ends_cleanly
            }
            // Every episode's file must end up in the same codec.
            VideoLayout::PerEpisode => {
                fits && !self.video.reencode
                    && self.skipped == 0
                    && !extra
                    && info.codec == self.video.codec.name()
            }
            VideoLayout::Encoded => false,
            VideoLayout::Frames => true,
        })
    }

    /// The part for a file of ours in the work folder holding the kept frames: made by a
    /// smart cut (`Some(frames re-encoded)`) or encoded (`None`).
    fn made_part(
        &self,
        name: &str,
        src: &Path,
        out: PathBuf,
        smart_cut: Option<usize>,
    ) -> Result<VideoPart, ConvertError> {
        let ep = &self.input.episode;
        let info = dexjoco_video::probe(&out).map_err(|source| ConvertError::Video {
            at: Location::episode(&ep.id)
                .field(format!("camera {name}"))
                .into(),
            source: source.into(),
        })?;
        Ok(VideoPart {
            name: name.to_owned(),
            bytes: fs_err::metadata(&out)?.len(),
            temporary: true,
            skip: 0,
            frames: info.frames as usize,
            info,
            copied: smart_cut.is_some(),
            reencoded_frames: smart_cut.unwrap_or(0),
            source: src.to_path_buf(),
            path: out,
        })
    }

    /// The kept frames `skipped..n` of `src` (camera `name`) as a file in the work folder
    /// made by a smart cut, and the frames it re-encoded; `None` where no encoder setting
    /// reproduces the source's stream headers.
    fn smart_cut(
        &self,
        name: &str,
        src: &Path,
        info: &dexjoco_video::VideoInfo,
        n: usize,
    ) -> Result<Option<(PathBuf, usize)>, dexjoco_video::VideoError> {
        let recorded = dexjoco_video::x264_settings(src)?;
        let stated = dexjoco_video::StatedEncoding::default();
        let candidates = dexjoco_video::candidate_encodings(&info.codec, &stated, recorded);
        if candidates.is_empty() {
            return Ok(None);
        }
        let cuts = dexjoco_video::CutPoints::of(src)?;
        let stem = format!("{:06}-{name}", self.ordinal);
        let scratch = self.work_dir.join(format!("{stem}-cut"));
        let io = |source| dexjoco_video::VideoError::Io {
            path: scratch.clone(),
            source,
        };
        fs_err::create_dir_all(&scratch).map_err(io)?;
        let take = n - self.skipped;
        let made = match dexjoco_video::smart_cut(
            src,
            self.skipped,
            take,
            &cuts,
            &candidates,
            &scratch,
        )? {
            Some(cut) => {
                let out = self.work_dir.join(format!("{stem}.mp4"));
                dexjoco_video::concat_copy(&cut.inputs, &out, self.fps)?;
                Some((out, cut.reencoded))
            }
            None => None,
        };
        let _ = fs_err::remove_dir_all(&scratch);
        Ok(made)
    }

    /// Encodes the kept frames into `out` with `codec` (GOP 2) while sampling them.
    fn encode(
        &self,
        frames: &mut Frames,
        out: &Path,
        codec: VideoCodec,
    ) -> Result<(), dexjoco_video::VideoError> {
        let (width, height) = frames.reader.size();
        let spec = VideoSpec {
            width,
            height,
            fps: self.fps,
            codec: codec.codec(),
        };
        let mut writer = VideoWriter::create_with(
            out,
            spec,
            &Keyframes {
                interval: Some(2),
                at: Vec::new(),
            },
        )?;
        frames.sample(|frame| writer.write_frame(frame))?;
        writer.finish()?;
        Ok(())
    }
}

/// A camera's source video read once: the kept frames are sampled for statistics.
struct Frames {
    reader: VideoReader,
    /// Leading frames skipped.
    skipped: usize,
    /// Frames kept end before this one (an evaluated rollout's video holds one more).
    end: usize,
    /// Indices (among the kept frames) sampled for statistics.
    samples: Vec<usize>,
    sampler: ImageSampler,
}

impl Frames {
    /// Reads every frame, handing each kept one to `keep` and sampling it.
    fn sample(
        &mut self,
        mut keep: impl FnMut(&[u8]) -> Result<(), dexjoco_video::VideoError>,
    ) -> Result<(), dexjoco_video::VideoError> {
        let (w, h) = self.reader.size();
        let mut want = self.samples.iter().peekable();
        let mut frame = Vec::new();
        let mut k = 0;
        while self.reader.next_frame(&mut frame)? {
            if k >= self.skipped && k < self.end {
                keep(&frame)?;
                if want.peek().is_some_and(|&&s| s == k - self.skipped) {
                    while want.peek().is_some_and(|&&s| s == k - self.skipped) {
                        want.next();
                    }
                    self.sampler.add_frame(&frame, w, h);
                }
            }
            k += 1;
        }
        Ok(())
    }
}

fn camera_list(ep: &Episode) -> String {
    let v: Vec<&str> = ep
        .cameras
        .iter()
        .filter(|c| c.video.is_some())
        .map(|c| c.name.as_str())
        .collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

fn column_names(
    a: &FrameArray,
    setup: Option<ArmSetup>,
    array: &str,
    range: std::ops::Range<usize>,
) -> Vec<String> {
    let layout = match (setup, array) {
        (Some(s), Episode::ACTION_ROTVEC) => Some(s.action_rotvec_layout()),
        (Some(s), _) => Some(s.action_layout()),
        _ => None,
    };
    match layout {
        Some(l) if l.width() == a.width() => range.map(|c| l.column_name(c)).collect(),
        _ => range.map(|c| format!("{array}[{c}]")).collect(),
    }
}

/// The values as lerobot stores them (float32), back in f64.
pub(crate) fn as_f32(a: &FrameArray) -> Vec<f64> {
    a.as_slice().iter().map(|v| f64::from(*v as f32)).collect()
}
