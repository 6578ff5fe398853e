//! One episode made ready for writing: selected arrays, trimmed start, per-camera video
//! parts (the source file for stream copy, or a re-encoded file) and statistics. Runs in
//! parallel over episodes; writing stays sequential.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::{ArmSetup, Episode, FrameArray, Location};
use dexjoco_video::{Codec, VideoInfo, VideoReader, VideoSpec, VideoWriter};

use crate::config::{Selection, first_moving_frame};
use crate::error::ConvertError;
use crate::stats::{FeatureStats, ImageSampler, column_stats, sample_indices};

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
            Self::H264 => Codec::H264 { crf: 21 },
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

/// How a format lays its videos out; decides when a source video is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VideoLayout {
    /// Episodes joined into shared files by stream copy (LeRobot v3.0): the source is
    /// used as it is (trimmed by timestamps) when its codec fits.
    #[default]
    Joined,
    /// One file per episode starting at its first kept frame (Diffusion Policy
    /// `--videos`): the source is copied when nothing is trimmed and its codec is the
    /// chosen one.
    PerEpisode,
    /// One file per episode, every one encoded with the same settings (LeRobot v2.1:
    /// lerobot's v2.1 -> v3.0 script joins them by stream copy, which needs files from
    /// one encoder configuration).
    Encoded,
    /// No video output, only decoded frames (Diffusion Policy images): never encoded.
    Frames,
}

/// Codecs lerobot's decoders accept in an mp4 and that concatenate by stream copy.
const COPYABLE: [&str; 3] = ["h264", "hevc", "av1"];

/// A camera's frames for one episode, as a part of the dataset's video file.
#[derive(Debug, Clone)]
pub struct VideoPart {
    /// Output camera name (the feature key is `observation.images.<name>`).
    pub name: String,
    /// The mp4 to join (the source, or an encoded file in the work folder).
    pub path: PathBuf,
    /// Whether `path` is a temporary file of ours.
    pub temporary: bool,
    /// Frames of `path` before the episode's first kept frame.
    pub skip: usize,
    /// All frames of `path`.
    pub frames: usize,
    /// Size of `path` in bytes.
    pub bytes: u64,
    /// Codec, size and pixel format of `path`.
    pub info: VideoInfo,
    /// Whether the part is the source, stream-copied.
    pub copied: bool,
    /// The source video (all frames, before trimming).
    pub source: PathBuf,
}

/// An episode ready to be written.
#[derive(Debug, Clone)]
pub struct PreparedEpisode {
    /// Episode id.
    pub id: String,
    /// Task id.
    pub task: String,
    /// Language instruction.
    pub instruction: String,
    /// Frames per second (integer).
    pub fps: u32,
    /// Selected action, from the first kept frame.
    pub action: FrameArray,
    /// Selected state columns, from the first kept frame.
    pub state: FrameArray,
    /// Column names of action and state.
    pub action_names: Vec<String>,
    /// Column names of the state.
    pub state_names: Vec<String>,
    /// Leading frames skipped.
    pub skipped: usize,
    /// Per output camera, in name order.
    pub videos: Vec<VideoPart>,
    /// Statistics of action, state and each camera (`observation.images.<name>`).
    pub stats: BTreeMap<String, FeatureStats>,
}

impl PreparedEpisode {
    /// Checks that this episode fits a dataset of `fps`, action/state widths and camera
    /// names (in order): every writer appends episodes of one layout.
    pub(crate) fn check_layout(
        &self,
        fps: u32,
        action_width: usize,
        state_width: usize,
        cameras: &[&str],
    ) -> Result<(), ConvertError> {
        let bad = |m: String| Err(ConvertError::episode(&self.id, m));
        if self.fps != fps {
            return bad(format!("fps {} differs from the dataset's {fps}", self.fps));
        }
        if self.action.width() != action_width || self.state.width() != state_width {
            return bad(format!(
                "action/state widths {}/{} differ from the dataset's {action_width}/{state_width} (select the same arrays for every task)",
                self.action.width(),
                self.state.width(),
            ));
        }
        let names: Vec<&str> = self.videos.iter().map(|v| v.name.as_str()).collect();
        if names != cameras {
            return bad(format!(
                "cameras {names:?} differ from the dataset's {cameras:?} (map cameras to shared names)"
            ));
        }
        Ok(())
    }

    /// Frames kept.
    pub fn len(&self) -> usize {
        self.action.len()
    }

    /// True when no frame is kept.
    pub fn is_empty(&self) -> bool {
        self.action.is_empty()
    }
}

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
/// `layout` cannot use the source as it is. `ordinal` names temporary files.
pub fn prepare(
    input: &InputEpisode,
    selection: &Selection,
    video: VideoOptions,
    layout: VideoLayout,
    work_dir: &Path,
    ordinal: usize,
) -> Result<PreparedEpisode, ConvertError> {
    let ep = &input.episode;
    ep.check_consistent()?;
    let sel = selection.for_task(&ep.task);
    let at = |field: &str| Location::episode(&ep.id).field(field).path(&input.dir);
    let missing = |name: &str| ConvertError::Episode {
        at: at(name).into(),
        message: "array missing".into(),
    };
    let action_full: FrameArray = match ep.array(sel.action.array_name()) {
        Some(a) => a.clone(),
        None if sel.action.array_name() == Episode::ACTION_ROTVEC => {
            // Computed from `action` as the recorder does.
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
            e.arrays
                .remove(Episode::ACTION_ROTVEC)
                .expect("just computed")
        }
        None => return Err(missing(sel.action.array_name())),
    };
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
    let n = ep.len();
    if n == 0 {
        return Err(ConvertError::episode(&ep.id, "the episode has no frames"));
    }
    let skipped = if selection.skip_static_frames {
        first_moving_frame(ep.array(Episode::ACTION).unwrap_or(&action_full))
    } else {
        0
    };
    let action = slice_columns(&action_full, 0..action_full.width(), skipped);
    let state = slice_columns(state_full, state_range.clone(), skipped);
    let (action, state, setup, state_range) = if selection.merge_bimanual
        && setup == Some(ArmSetup::SingleArm)
    {
        let proprio = 0..ArmSetup::SingleArm.proprio_dim();
        let (Some(a), Some(s)) = (
            crate::merge::action_to_bimanual(&action),
            crate::merge::state_to_bimanual(&state),
        ) else {
            return Err(ConvertError::Episode {
                at: at(Episode::STATE).into(),
                message: format!(
                    "merging into the two-arm layout needs the proprioceptive state {proprio:?} \
                         (the state slice selects {state_range:?})"
                ),
            });
        };
        if state_range != proprio {
            return Err(ConvertError::Episode {
                at: at(Episode::STATE).into(),
                message: format!(
                    "merging into the two-arm layout needs the proprioceptive state {proprio:?} \
                         (the state slice selects {state_range:?})"
                ),
            });
        }
        (
            a,
            s,
            Some(ArmSetup::Bimanual),
            0..ArmSetup::Bimanual.proprio_dim(),
        )
    } else {
        (action, state, setup, state_range)
    };
    let fps = ep.fps.round();
    if !(fps >= 1.0 && (ep.fps - fps).abs() < 1e-9) {
        return Err(ConvertError::episode(
            &ep.id,
            format!("fps {} is not a whole number", ep.fps),
        ));
    }
    let fps = fps as u32;

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

    // Cameras: output name -> raw camera.
    let mapping: Vec<(String, String)> = if sel.cameras.is_empty() {
        ep.cameras
            .iter()
            .filter(|c| c.video.is_some())
            .map(|c| (c.name.clone(), c.name.clone()))
            .collect()
    } else {
        sel.cameras
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    };
    let mut videos = Vec::new();
    for (name, raw) in mapping {
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
                at: cam_at().path(&input.dir).into(),
                message: format!("no video of camera '{raw}' (cameras: {})", camera_list(ep)),
            })?;
        let src = input.dir.join(rel);
        let vid_err = |source: dexjoco_video::VideoError| ConvertError::Video {
            at: cam_at().into(),
            source: source.into(),
        };
        let info = dexjoco_video::probe(&src).map_err(vid_err)?;
        if info.frames as usize != n {
            return Err(ConvertError::Episode {
                at: cam_at().path(&src).into(),
                message: format!("the video has {} frames, the episode {n}", info.frames),
            });
        }
        let fits = COPYABLE.contains(&info.codec.as_str())
            && info.pix_fmt == "yuv420p"
            && (info.fps - f64::from(fps)).abs() < 1e-6;
        let key = format!("observation.images.{name}");
        let samples = sample_indices(n - skipped);
        let mut sampler = ImageSampler::default();
        let mut want = samples.iter().peekable();
        let mut reader = VideoReader::open(&src, None).map_err(vid_err)?;
        let (w, h) = reader.size();
        let mut frame = Vec::new();
        let use_source = match layout {
            VideoLayout::Joined => fits && !video.reencode,
            // Every episode's file must end up in the same codec.
            VideoLayout::PerEpisode => {
                fits && !video.reencode && skipped == 0 && info.codec == video.codec.name()
            }
            VideoLayout::Encoded => false,
            VideoLayout::Frames => true,
        };
        let part = if use_source {
            let mut k = 0;
            while reader.next_frame(&mut frame).map_err(vid_err)? {
                if k >= skipped && want.peek().is_some_and(|&&s| s == k - skipped) {
                    while want.peek().is_some_and(|&&s| s == k - skipped) {
                        want.next();
                    }
                    sampler.add_frame(&frame, w, h);
                }
                k += 1;
            }
            let bytes = fs_err::metadata(&src)?.len();
            VideoPart {
                name: name.clone(),
                path: src.clone(),
                temporary: false,
                skip: skipped,
                frames: n,
                bytes,
                info,
                copied: layout != VideoLayout::Frames,
                source: src.clone(),
            }
        } else {
            let out = work_dir.join(format!("{ordinal:06}-{name}.mp4"));
            let spec = VideoSpec {
                width: w,
                height: h,
                fps,
                codec: video.codec.codec(),
            };
            let enc_err = |source: dexjoco_video::VideoError| ConvertError::Video {
                at: cam_at().into(),
                source: source.into(),
            };
            let mut writer = VideoWriter::create_with(&out, spec, Some(2)).map_err(enc_err)?;
            let mut k = 0;
            while reader.next_frame(&mut frame).map_err(vid_err)? {
                if k >= skipped {
                    writer.write_frame(&frame).map_err(enc_err)?;
                    if want.peek().is_some_and(|&&s| s == k - skipped) {
                        while want.peek().is_some_and(|&&s| s == k - skipped) {
                            want.next();
                        }
                        sampler.add_frame(&frame, w, h);
                    }
                }
                k += 1;
            }
            writer.finish().map_err(enc_err)?;
            let info = dexjoco_video::probe(&out).map_err(enc_err)?;
            VideoPart {
                name: name.clone(),
                path: out.clone(),
                temporary: true,
                skip: 0,
                frames: n - skipped,
                bytes: fs_err::metadata(&out)?.len(),
                info,
                copied: false,
                source: src.clone(),
            }
        };
        if let Some(s) = sampler.finish() {
            stats.insert(key, s);
        }
        videos.push(part);
    }
    videos.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(PreparedEpisode {
        id: ep.id.clone(),
        task: ep.task.clone(),
        instruction: selection.instruction(&ep.task, &ep.prompt),
        fps,
        action,
        state,
        action_names,
        state_names,
        skipped,
        videos,
        stats,
    })
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
