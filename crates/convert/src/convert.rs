//! The conversion driver: output folder checks, parallel preparation in bounded batches,
//! sequential writing, and an atomic finish.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::config::Selection;
use crate::diffusion_policy::ZarrWriter;
use crate::error::ConvertError;
use crate::lerobot_v3::{V3Options, V3Writer};
use crate::lerobot_v21::V21Writer;
use crate::openpi::NormStats;
use crate::prepare::{InputEpisode, PreparedEpisode, VideoLayout, VideoOptions, prepare};

/// Output dataset formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputFormat {
    /// LeRobot v3.0 (lerobot >= 0.4).
    #[default]
    LeRobotV3,
    /// LeRobot v2.1 (openpi's pinned lerobot).
    LeRobotV21,
    /// Diffusion Policy's Zarr v2 replay buffer (`replay_buffer.zarr`).
    DiffusionPolicy,
}

impl OutputFormat {
    fn layout(self, videos: bool) -> VideoLayout {
        match self {
            Self::LeRobotV3 => VideoLayout::Joined,
            Self::LeRobotV21 => VideoLayout::Encoded,
            Self::DiffusionPolicy if videos => VideoLayout::PerEpisode,
            Self::DiffusionPolicy => VideoLayout::Frames,
        }
    }
}

enum Writer {
    V3(Box<V3Writer>),
    V21(Box<V21Writer>),
    Zarr(Box<ZarrWriter>),
}

impl Writer {
    fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), ConvertError> {
        match self {
            Self::V3(w) => w.write_episode(ep),
            Self::V21(w) => w.write_episode(ep),
            Self::Zarr(w) => w.write_episode(ep),
        }
    }

    fn counts(&self) -> (usize, usize) {
        match self {
            Self::V3(w) => (w.episodes(), w.frames()),
            Self::V21(w) => (w.episodes(), w.frames()),
            Self::Zarr(w) => (w.episodes(), w.frames()),
        }
    }

    fn finish(self) -> Result<(), ConvertError> {
        match self {
            Self::V3(w) => w.finish(),
            Self::V21(w) => w.finish(),
            Self::Zarr(w) => w.finish(),
        }
    }
}

/// Everything a conversion needs besides its input and output.
#[derive(Debug, Clone, Default)]
pub struct ConvertOptions {
    /// Output format.
    pub format: OutputFormat,
    /// What to take from each episode.
    pub selection: Selection,
    /// Video handling.
    pub video: VideoOptions,
    /// LeRobot v3.0 sizes and names.
    pub v3: V3Options,
    /// Replace a non-empty output folder.
    pub overwrite: bool,
    /// Diffusion Policy: keep each episode's videos beside the replay buffer.
    pub videos: bool,
    /// Write openpi's `norm_stats.json` into the dataset folder, with actions over
    /// chunks of this many frames (openpi's `action_horizon`).
    pub norm_stats: Option<usize>,
    /// Episodes prepared in parallel at a time (0: twice the worker threads). Memory is
    /// bounded by this many episodes.
    pub batch: usize,
}

/// Progress reports of a conversion (the CLI draws them; libraries never print).
pub trait Reporter: Sync {
    /// An episode was written (or left out, with `excluded`).
    fn episode(&self, _id: &str, _excluded: bool) {}
}

/// A reporter that reports nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Reporter for Silent {}

/// What a conversion did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Summary {
    /// The dataset folder.
    pub out: PathBuf,
    /// Episodes written.
    pub episodes: usize,
    /// Frames written.
    pub frames: usize,
    /// Static leading frames skipped, over all episodes.
    pub skipped_frames: usize,
    /// Episodes left out by the bad-episodes list.
    pub excluded: Vec<String>,
    /// Camera videos joined by stream copy / encoded.
    pub videos_copied: usize,
    /// Camera videos encoded.
    pub videos_encoded: usize,
}

/// True when `dir` exists and has any entry.
pub fn is_non_empty_dir(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|mut d| d.next().is_some())
}

/// Converts episodes (read lazily from `inputs`, in dataset order) into a dataset at `out`.
///
/// The dataset is written into a temporary folder beside `out` and renamed into place
/// when complete, so an interrupted run leaves no dataset that looks complete. A
/// non-empty `out` is refused unless `options.overwrite`.
pub fn convert<I>(
    inputs: I,
    out: &Path,
    options: &ConvertOptions,
    reporter: &dyn Reporter,
) -> Result<Summary, ConvertError>
where
    I: IntoIterator<Item = Result<InputEpisode, ConvertError>>,
{
    if out.is_file() || (is_non_empty_dir(out) && !options.overwrite) {
        return Err(ConvertError::OutputNotEmpty(out.to_path_buf()));
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs_err::create_dir_all(&parent)?;
    let name = out
        .file_name()
        .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
    if tmp.exists() {
        fs_err::remove_dir_all(&tmp)?;
    }
    fs_err::create_dir_all(&tmp)?;
    let result = run(inputs, &tmp, options, reporter);
    match result {
        Ok(mut summary) => {
            if out.exists() {
                fs_err::remove_dir_all(out)?;
            }
            fs_err::rename(&tmp, out)?;
            summary.out = out.to_path_buf();
            Ok(summary)
        }
        Err(e) => {
            let _ = fs_err::remove_dir_all(&tmp);
            Err(e)
        }
    }
}

fn run<I>(
    inputs: I,
    root: &Path,
    options: &ConvertOptions,
    reporter: &dyn Reporter,
) -> Result<Summary, ConvertError>
where
    I: IntoIterator<Item = Result<InputEpisode, ConvertError>>,
{
    let work = root.join(".work");
    fs_err::create_dir_all(&work)?;
    let batch = if options.batch == 0 {
        2 * rayon::current_num_threads()
    } else {
        options.batch
    };
    let mut summary = Summary::default();
    let mut writer: Option<Writer> = None;
    let layout = options.format.layout(options.videos);
    let mut norm = options.norm_stats.map(NormStats::new);
    let mut inputs = inputs.into_iter();
    let mut ordinal = 0usize;
    loop {
        let mut pending = Vec::with_capacity(batch);
        for item in inputs.by_ref() {
            let item = item?;
            if options.selection.bad_episodes.contains(&item.episode.id) {
                reporter.episode(&item.episode.id, true);
                summary.excluded.push(item.episode.id);
                continue;
            }
            pending.push((ordinal, item));
            ordinal += 1;
            if pending.len() == batch {
                break;
            }
        }
        if pending.is_empty() {
            break;
        }
        let prepared: Vec<Result<PreparedEpisode, ConvertError>> = pending
            .par_iter()
            .map(|(i, input)| prepare(input, &options.selection, options.video, layout, &work, *i))
            .collect();
        for p in prepared {
            let p = p?;
            let id = p.id.clone();
            summary.skipped_frames += p.skipped;
            summary.videos_copied += p.videos.iter().filter(|v| v.copied).count();
            summary.videos_encoded += p.videos.iter().filter(|v| !v.copied).count();
            if let Some(norm) = norm.as_mut() {
                norm.add_episode(
                    &crate::prepare::as_f32(&p.state),
                    p.state.width(),
                    &crate::prepare::as_f32(&p.action),
                    p.action.width(),
                );
            }
            let w = match writer.as_mut() {
                Some(w) => w,
                None => writer.insert(match options.format {
                    OutputFormat::LeRobotV3 => {
                        Writer::V3(Box::new(V3Writer::try_new(root, &p, options.v3.clone())?))
                    }
                    OutputFormat::LeRobotV21 => Writer::V21(Box::new(V21Writer::try_new(
                        root,
                        &p,
                        options.v3.robot_type.clone(),
                    )?)),
                    OutputFormat::DiffusionPolicy => {
                        Writer::Zarr(Box::new(ZarrWriter::try_new(root, &p, options.videos)?))
                    }
                }),
            };
            w.write_episode(p)?;
            reporter.episode(&id, false);
        }
    }
    let w = writer.ok_or(ConvertError::NoEpisodes)?;
    (summary.episodes, summary.frames) = w.counts();
    w.finish()?;
    if let Some(norm) = norm {
        norm.write(root)?;
    }
    fs_err::remove_dir_all(&work)?;
    Ok(summary)
}
