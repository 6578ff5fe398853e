//! What an augment run is asked to do ([`AugmentConfig`]) and the names of the files it
//! writes.

use std::path::PathBuf;

use dexjoco_render::warp::WarpOptions;
use dexjoco_render::{RenderSettings, RendererKind};
use dexjoco_sim::SceneSource;
use dexjoco_video::{Codec, Keyframes, X264Preset};
use serde::{Deserialize, Serialize};

/// Name of the randomized third-person camera's video (`videos/third_person.mp4`).
pub const THIRD_PERSON: &str = "third_person";
/// The report, JSON.
pub const REPORT_JSON: &str = "augment_report.json";
/// The report, readable.
pub const REPORT_MD: &str = "augment_report.md";
/// The per-replay record inside each replay folder (written last, before the rename).
pub(crate) const RECORD: &str = dexjoco_formats::raw::REPLAY_RECORD;
/// Work in progress: each replay is written here whole, then renamed into place.
pub(crate) const STAGING: &str = ".staging";
/// First frames of the replays' third-person views, for the contact sheet.
pub(crate) const PREVIEWS: &str = ".previews";
/// The settings that decide an output's bytes (see the `fingerprint` module).
pub const SETTINGS_FILE: &str = "augment_settings.json";
/// The contact sheet of the replays' first frames.
pub const CONTACT_SHEET: &str = "contact_sheet.png";
/// The default of `--replays`.
pub const DEFAULT_REPLAYS: usize = 10;
/// The default of `--extend-steps`: one second at DexJoCo's 30 Hz.
pub const DEFAULT_EXTEND_STEPS: usize = dexjoco_core::DEFAULT_EXTEND_STEPS;
/// Records of replays that failed under `--dynamics` and were not kept
/// (`.dropped/<task>/<replay>.json`), so a resumed run does not simulate them again and
/// the report can list them.
pub(crate) const DROPPED: &str = ".dropped";

/// What to do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentConfig {
    /// Raw episode folders, episode stores or MCAP files.
    pub inputs: Vec<PathBuf>,
    /// Output folder (one folder per replay: `<task>/<episode>__rNN/`).
    pub out: PathBuf,
    /// Replays per episode.
    pub replays: usize,
    /// Global seed.
    pub seed: u64,
    /// A folder of task specs replacing the built-in ones of the same id.
    pub tasks_dir: Option<PathBuf>,
    /// Where the task scenes come from.
    pub scene: SceneSource,
    /// Camera pool file; default: the reference pool beside `--scene-dir`, else built-in.
    pub camera_pool: Option<PathBuf>,
    /// Fixed scene cameras rendered besides the randomized third-person view.
    pub cameras: Vec<String>,
    /// Image size and quality.
    pub settings: RenderSettings,
    /// Keep replays whose task failed (flagged in the report).
    pub keep_failed: bool,
    /// Only the first N frames of each episode (quick looks and tests).
    pub max_frames: Option<usize>,
    /// The reference approach: simulate every replay on its own (for comparisons).
    pub resimulate_per_replay: bool,
    /// Write a contact sheet of the sampled views.
    pub contact_sheet: bool,
    /// Also write each camera's depth (`videos/<camera>_depth.npz`, float32 metres).
    pub depth: bool,
    /// Dynamics randomization per replay (the task spec's `[[dynamics]]`): every replay is
    /// simulated on its own model copy and kept only if the task still succeeds.
    pub dynamics: bool,
    /// After a recording that ends without success, repeat its last action up to this
    /// many more steps, stopping at the first success (0: the reference's strict replay).
    pub extend_steps: usize,
    /// This run's share of the work (`--shard I/N`); `None`: everything, and the report.
    pub shard: Option<Shard>,
    /// Start clean when the output folder was made with other settings (removes only what
    /// augment wrote there).
    pub overwrite: bool,
    /// How the camera videos are encoded.
    pub video: VideoEncoding,
    /// Which renderer draws the frames (MuJoCo's OpenGL one unless `--renderer warp`).
    #[serde(default)]
    pub renderer: RendererKind,
    /// How the Warp renderer's worker runs (with `--renderer warp`).
    #[serde(default)]
    pub warp: WarpOptions,
}

/// How augment encodes its camera videos: H.264 (libx264, yuv420p), one encoder process
/// per camera. The keyframe interval decides what training pays: `convert` stream-copies
/// these videos into LeRobot datasets, and lerobot decodes from the keyframe before each
/// random item (docs/performance.md, "Video encoding").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct VideoEncoding {
    /// x264's constant rate factor (DexJoCo's recorder: 21); 0: lossless RGB.
    pub crf: u8,
    /// x264's speed preset.
    pub preset: X264Preset,
    /// At most this many frames from one keyframe to the next; 0: x264's own (250).
    pub keyframe_interval: u32,
}

impl Default for VideoEncoding {
    /// augment's defaults (`--crf`, `--x264-preset`, `--keyframe-interval`), chosen by
    /// measurement (docs/performance.md, "Video encoding"): x264 ultrafast with a keyframe
    /// every 5 frames spends about half the encoder CPU of the DexJoCo recorder's
    /// settings, and the LeRobot dataset convert stream-copies from it reads at random
    /// faster than the reference converter's (AV1, GOP 2) at 1.4x its size.
    fn default() -> Self {
        Self {
            crf: 21,
            preset: X264Preset::Ultrafast,
            keyframe_interval: 5,
        }
    }
}

impl VideoEncoding {
    /// What augment wrote before the encoding was chosen by measurement (the DexJoCo
    /// recorder's x264 settings): crf 21, preset medium, x264's keyframe interval (250).
    pub const LEGACY: Self = Self {
        crf: 21,
        preset: X264Preset::Medium,
        keyframe_interval: 0,
    };

    /// The codec these settings encode with.
    pub fn codec(self) -> Codec {
        Codec::H264 {
            crf: self.crf,
            preset: self.preset,
        }
    }

    /// The keyframes of a video whose frames `at` must be keyframes.
    pub fn keyframes(self, at: Vec<usize>) -> Keyframes {
        Keyframes {
            interval: (self.keyframe_interval > 0).then_some(self.keyframe_interval),
            at,
        }
    }

    /// For `serde(default)`: settings files written before this field.
    pub(crate) fn legacy() -> Self {
        Self::LEGACY
    }
}

impl AugmentConfig {
    /// The renderer settings of a unit: the image settings, with depth as `--depth` says.
    pub(crate) fn unit_render_settings(&self) -> RenderSettings {
        RenderSettings {
            depth: self.depth,
            ..self.settings
        }
    }

    /// `inputs` replayed into `out` with `augment`'s documented defaults: 10 replays,
    /// seed 0, the built-in scenes and camera pool, only the randomized third-person view
    /// at 640x640 in the paper quality, failed replays dropped, whole episodes, a contact
    /// sheet, no depth, no dynamics, the 30-step extension, everything in one run, nothing
    /// replaced. Change what differs with struct update syntax.
    pub fn new(inputs: Vec<PathBuf>, out: impl Into<PathBuf>) -> Self {
        Self {
            inputs,
            out: out.into(),
            replays: DEFAULT_REPLAYS,
            seed: 0,
            tasks_dir: None,
            scene: SceneSource::BuiltIn,
            camera_pool: None,
            cameras: Vec::new(),
            settings: RenderSettings {
                quality: dexjoco_render::RenderQuality::PAPER,
                ..RenderSettings::default()
            },
            keep_failed: false,
            max_frames: None,
            resimulate_per_replay: false,
            contact_sheet: true,
            depth: false,
            dynamics: false,
            extend_steps: DEFAULT_EXTEND_STEPS,
            shard: None,
            overwrite: false,
            renderer: RendererKind::Opengl,
            warp: WarpOptions::default(),
            video: VideoEncoding::default(),
        }
    }
}

pub use dexjoco_core::Shard;

/// The folder name of replay `r` of `episode`.
pub fn replay_name(episode: &str, r: usize) -> String {
    format!("{episode}__r{r:02}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from(vars: &[(&str, &str)]) -> Result<Shard, String> {
        Shard::from_env(|name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| (*v).to_owned())
        })
        .map_err(|e| e.to_string())
    }

    #[test]
    fn shard_auto_reads_slurm_arrays_relative_to_their_first_index() {
        let s = from(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert_eq!(s, Ok(Shard { index: 2, count: 4 }));
        let s = from(&[
            ("SLURM_ARRAY_TASK_ID", "7"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert_eq!(s, Ok(Shard { index: 2, count: 4 }));
        let e = from(&[
            ("SLURM_ARRAY_TASK_ID", "4"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert!(e.unwrap_err().contains("--array=0-3"));
        let e = from(&[("SLURM_ARRAY_TASK_ID", "1")]).unwrap_err();
        assert!(e.contains("SLURM_ARRAY_TASK_COUNT"), "{e}");
    }

    #[test]
    fn shard_auto_reads_kubernetes_indexed_jobs_with_the_documented_count() {
        let s = from(&[("JOB_COMPLETION_INDEX", "3"), ("DEXJOCO_SHARD_COUNT", "8")]);
        assert_eq!(s, Ok(Shard { index: 3, count: 8 }));
        let e = from(&[("JOB_COMPLETION_INDEX", "3")]).unwrap_err();
        assert!(e.contains("DEXJOCO_SHARD_COUNT"), "{e}");
        let e = from(&[("JOB_COMPLETION_INDEX", "x"), ("DEXJOCO_SHARD_COUNT", "8")]);
        assert!(e.unwrap_err().contains("JOB_COMPLETION_INDEX=x"));
        assert!(from(&[]).unwrap_err().contains("neither"));
    }
}
