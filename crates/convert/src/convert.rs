//! The conversion driver: output folder checks, parallel preparation in bounded batches,
//! sequential writing, and an atomic finish.

use std::path::{Path, PathBuf};

use dexjoco_core::Progress;
use dexjoco_formats::dataset::language::subtask_rows;
use dexjoco_formats::dataset::{
    DatasetWriter, PreparedEpisode, V3Options, V3Writer, V21Writer, VideoLayout, ZarrWriter,
};
use dexjoco_formats::fs::StagedDir;
use dexjoco_formats::openpi::{NormStats, NormStatsOptions};
use dexjoco_formats::raw::{RenderFlag, ReplayLabel};
use rayon::prelude::*;

use crate::config::Selection;
use crate::error::ConvertError;
use crate::prepare::{InputEpisode, VideoOptions, prepare};

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
    /// The `--format` name.
    pub fn name(self) -> &'static str {
        match self {
            Self::LeRobotV3 => "lerobot-v3",
            Self::LeRobotV21 => "lerobot-v2.1",
            Self::DiffusionPolicy => "diffusion-policy",
        }
    }

    /// Whether the format stores action and state as float32 (LeRobot) rather than as
    /// recorded (Diffusion Policy: float64).
    fn stores_float32(self) -> bool {
        self != Self::DiffusionPolicy
    }

    fn layout(self, videos: bool) -> VideoLayout {
        match self {
            Self::LeRobotV3 => VideoLayout::Joined,
            Self::LeRobotV21 => VideoLayout::Encoded,
            Self::DiffusionPolicy if videos => VideoLayout::PerEpisode,
            Self::DiffusionPolicy => VideoLayout::Frames,
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
    /// Write openpi's `norm_stats.json` into the dataset folder, fed as these options say
    /// (openpi's `action_horizon` and `batch_size`).
    pub norm_stats: Option<NormStatsOptions>,
    /// Episodes prepared in parallel at a time (0: twice the worker threads). Memory is
    /// bounded by this many episodes.
    pub batch: usize,
    /// Also convert replays whose record (`replay.json`) says the task failed
    /// (augment's `--keep-failed`); by default they are left out and named.
    pub include_failed: bool,
    /// Also convert replays a render check flagged (their record's `flags`); by default
    /// they are left out and named with their flags.
    pub include_flagged: bool,
    /// The state features to export beyond the proprioception (`--environment-state`,
    /// `--privileged-state`), with the task specs that name their columns.
    pub state_features: Option<crate::StateFeatures>,
    /// Carry each camera's depth (augment's `videos/<camera>_depth.npz`): LeRobot v3.0
    /// as lerobot 0.6.1 stores depth, Diffusion Policy as `data/<camera>_depth`; refused
    /// for LeRobot v2.1.
    pub depth: bool,
    /// Inputs: a non-empty output folder that holds one of them, or lies inside one, is
    /// never replaced (even with `overwrite`).
    pub protected_inputs: Vec<PathBuf>,
    /// Folders a non-empty output folder may not hold or be (the work folder).
    pub protected_dirs: Vec<PathBuf>,
}

/// The file convert writes into every dataset folder it makes; `overwrite` replaces
/// only folders holding it (or empty ones).
pub const CONVERT_MARKER: &str = ".dexjoco-convert.json";

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
    /// Episodes that could not be converted, and why; the rest of the dataset is written.
    pub failed: Vec<FailedEpisode>,
    /// Camera videos joined by stream copy / encoded.
    pub videos_copied: usize,
    /// Camera videos encoded.
    pub videos_encoded: usize,
    /// Of the copied videos, those cut off a keyframe by a smart cut.
    pub videos_smart_cut: usize,
    /// Frames those smart cuts re-encoded.
    pub frames_reencoded: usize,
}

/// An input episode left out because it could not be read, prepared or fit the dataset.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FailedEpisode {
    /// The episode id, or the input folder when the episode could not be read.
    pub episode: String,
    /// The error, naming file, episode, field and frame where known.
    pub reason: String,
}

/// Converts episodes (read lazily from `inputs`, in dataset order) into a dataset at `out`.
///
/// One run writes `out` at a time: the lock `.NAME.lock` beside it is held for the
/// whole run (a second run fails at once with [`dexjoco_formats::FormatError::Locked`]).
/// The dataset is written into `.NAME.partial-PID` beside `out` and renamed into place
/// when complete, so an interrupted run leaves no dataset that looks complete; the next
/// run removes what a killed one left. A non-empty `out` is refused unless
/// `options.overwrite`, and even then when it holds or lies inside an input, holds a
/// protected folder, or was not made by convert (no [`CONVERT_MARKER`]).
pub fn convert<I>(
    inputs: I,
    out: &Path,
    options: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<Summary, ConvertError>
where
    I: IntoIterator<Item = Result<InputEpisode, ConvertError>>,
{
    if out.is_file() {
        return Err(ConvertError::OutputNotEmpty(out.to_path_buf()));
    }
    if options.depth && options.format == OutputFormat::LeRobotV21 {
        return Err(ConvertError::Unsupported {
            format: options.format.name(),
            message: "--depth is not supported: openpi's lerobot (v2.1) has no depth decoding \
                          (lerobot 0.6.1 reads depth from v3.0 only); use --format lerobot-v3 \
                          or diffusion-policy"
                .into(),
        });
    }
    let staged = StagedDir::begin(out)?;
    check_output(out, options)?;
    let mut summary = run(inputs, staged.path(), options, progress)?;
    let marker = serde_json::json!({
        "written_by": "dexjoco-data convert",
        "format": options.format.name(),
    });
    dexjoco_formats::write_atomic(
        &staged.path().join(CONVERT_MARKER),
        format!("{marker}\n").as_bytes(),
    )?;
    staged.commit()?;
    summary.out = out.to_path_buf();
    Ok(summary)
}

/// Refuses to replace a non-empty `out` that is not a dataset convert made, or whose
/// removal would take an input or a protected folder with it.
pub fn check_output(out: &Path, options: &ConvertOptions) -> Result<(), ConvertError> {
    use dexjoco_formats::fs::{is_non_empty_dir, is_within, overlaps};
    if !is_non_empty_dir(out) {
        return Ok(());
    }
    let refuse = |reason: String| ConvertError::OverwriteRefused {
        out: out.to_path_buf(),
        reason,
    };
    for input in &options.protected_inputs {
        if overlaps(out, input) {
            let how = if is_within(input, out) {
                "holds"
            } else {
                "lies inside"
            };
            return Err(refuse(format!("it {how} the input '{}'", input.display())));
        }
    }
    for dir in &options.protected_dirs {
        if is_within(dir, out) {
            return Err(refuse(format!("it holds '{}'", dir.display())));
        }
    }
    if !options.overwrite {
        return Err(ConvertError::OutputNotEmpty(out.to_path_buf()));
    }
    if !out.join(CONVERT_MARKER).is_file() {
        return Err(refuse(format!(
            "it was not made by convert (no {CONVERT_MARKER})"
        )));
    }
    Ok(())
}

/// Episodes the dataset's layout is chosen from (see [`layout_leader`]).
const LAYOUT_WINDOW: usize = 8;

/// Opens the dataset writer of `options.format` with the layout of `p`.
fn new_writer(
    root: &Path,
    p: &PreparedEpisode,
    options: &ConvertOptions,
) -> Result<Box<dyn DatasetWriter>, ConvertError> {
    Ok(match options.format {
        OutputFormat::LeRobotV3 => Box::new(V3Writer::try_new(root, p, options.v3.clone())?),
        OutputFormat::LeRobotV21 => {
            Box::new(V21Writer::try_new(root, p, options.v3.robot_type.clone())?)
        }
        OutputFormat::DiffusionPolicy => Box::new(ZarrWriter::try_new(root, p, options.videos)?),
    })
}

/// The `language_persistent` slice length a LeRobot v3.0 dataset of these episode
/// folders needs ([`dexjoco_formats::dataset::lerobot_v3::V3Options::language_slots`]):
/// read from their replay records before any episode is written, since every episode's
/// slice must have it. Folders without a readable record count as none; every episode
/// may get as many `task_aug` rows as `selection` gives any task.
pub fn language_slots<'a>(
    dirs: impl IntoIterator<Item = &'a Path>,
    selection: &Selection,
) -> usize {
    let rows = dirs
        .into_iter()
        .map(|dir| match dexjoco_formats::raw::read_replay_label(dir) {
            Ok(Some(l)) => subtask_rows(&l.subtasks, 0, l.steps.max(1)).len(),
            _ => 0,
        });
    dexjoco_formats::dataset::language::slots_for(rows, selection.most_task_aug())
}

/// The episode whose layout (fps, widths, cameras and their videos) the dataset takes:
/// the most common one in the first batch; among equals the one with more cameras (a
/// missing video is likelier than an extra one), then the first. A broken first episode
/// thus does not decide the layout of the whole dataset.
fn layout_leader(prepared: &[Result<PreparedEpisode, ConvertError>]) -> Option<&PreparedEpisode> {
    let ok: Vec<&PreparedEpisode> = prepared.iter().filter_map(|p| p.as_ref().ok()).collect();
    let key = |p: &PreparedEpisode| {
        let videos: Vec<_> = p
            .videos
            .iter()
            .map(|v| {
                (
                    v.name.clone(),
                    v.info.width,
                    v.info.height,
                    v.info.codec.clone(),
                    v.info.pix_fmt.clone(),
                )
            })
            .collect();
        (
            p.fps,
            p.action.width(),
            p.state.width(),
            videos,
            p.vector_layout(),
        )
    };
    let keys: Vec<_> = ok.iter().map(|p| key(p)).collect();
    (0..ok.len())
        .max_by_key(|&i| {
            let count = keys.iter().filter(|k| **k == keys[i]).count();
            (count, ok[i].videos.len(), std::cmp::Reverse(i))
        })
        .map(|i| ok[i])
}

/// Episodes left out so far, keyed by input position: `(k, 0)` for an input that could not
/// be read just before the k-th readable one, `(k, 1)` for the k-th readable one.
type Failures = Vec<((usize, u8), FailedEpisode)>;

/// Records an episode left out, and tells the progress.
fn fail(
    failures: &mut Failures,
    key: (usize, u8),
    progress: &dyn Progress,
    episode: String,
    e: &ConvertError,
) {
    tracing::warn!(%episode, "left out: {e}");
    progress.note(&format!("LEFT OUT {episode}: {e}"));
    progress.advance(1, &episode);
    failures.push((
        key,
        FailedEpisode {
            episode,
            reason: e.to_string(),
        },
    ));
}

fn run<I>(
    inputs: I,
    root: &Path,
    options: &ConvertOptions,
    progress: &dyn Progress,
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
    let layout = options.format.layout(options.videos);
    let mut run = Run {
        root,
        options,
        progress,
        summary: Summary::default(),
        writer: None,
        norm: options.norm_stats.map(NormStats::new),
        ordinal: 0,
        failures: Failures::new(),
    };
    let mut inputs = inputs.into_iter();
    loop {
        // Until the layout is chosen, batches are LAYOUT_WINDOW episodes whatever the
        // thread count, so the choice (and the output) does not depend on it.
        let size = if run.writer.is_none() {
            LAYOUT_WINDOW
        } else {
            batch
        };
        let pending = run.take_batch(&mut inputs, size);
        if pending.is_empty() {
            break;
        }
        let prepared: Vec<Result<PreparedEpisode, ConvertError>> = pending
            .par_iter()
            .map(|(i, input, label)| {
                let float32 = options.format.stores_float32();
                let mut p = prepare(
                    input,
                    &options.selection,
                    options.video,
                    layout,
                    float32,
                    &work,
                    *i,
                )?;
                p.label.clone_from(label);
                if let Some(l) = label {
                    p.subtasks = subtask_rows(&l.subtasks, p.skipped, p.len());
                }
                if options.depth {
                    crate::depth::add_depth(&mut p, input, &options.selection, layout, &work, *i)?;
                }
                if let Some(features) = &options.state_features {
                    crate::vectors::add_state_features(&mut p, input, features)?;
                }
                Ok(p)
            })
            .collect();
        if run.writer.is_none()
            && let Some(leader) = layout_leader(&prepared)
        {
            run.writer = Some(new_writer(root, leader, options)?);
        }
        run.write_batch(prepared, &pending)?;
    }
    run.finish(&work)
}

/// An input taken for preparation: its ordinal, the episode and its replay record.
type Pending = (usize, InputEpisode, Option<ReplayLabel>);

/// One conversion between its batches: what was written and left out so far.
struct Run<'a> {
    root: &'a Path,
    options: &'a ConvertOptions,
    progress: &'a dyn Progress,
    summary: Summary,
    /// Made from the first batch's layout leader.
    writer: Option<Box<dyn DatasetWriter>>,
    norm: Option<NormStats>,
    /// Readable inputs taken so far.
    ordinal: usize,
    failures: Failures,
}

impl Run<'_> {
    /// The next `size` inputs to prepare, each with its ordinal; inputs that cannot be
    /// read or are left out on the way are recorded.
    fn take_batch(
        &mut self,
        inputs: &mut impl Iterator<Item = Result<InputEpisode, ConvertError>>,
        size: usize,
    ) -> Vec<Pending> {
        let mut pending = Vec::with_capacity(size);
        for item in inputs {
            let item = match item {
                Ok(item) => item,
                Err(e) => {
                    let source = match &e {
                        ConvertError::Input { path, .. } => path.display().to_string(),
                        _ => String::from("?"),
                    };
                    fail(
                        &mut self.failures,
                        (self.ordinal, 0),
                        self.progress,
                        source,
                        &e,
                    );
                    continue;
                }
            };
            let Some((item, label)) = self.admit(item) else {
                continue;
            };
            pending.push((self.ordinal, item, label));
            self.ordinal += 1;
            if pending.len() == size {
                break;
            }
        }
        pending
    }

    /// Leaves out an episode of the bad-episodes list, a replay whose record says it
    /// failed its task (unless `include_failed`) or that a render check flagged (unless
    /// `include_flagged`); returns the others with their replay record.
    fn admit(&mut self, item: InputEpisode) -> Option<(InputEpisode, Option<ReplayLabel>)> {
        if self
            .options
            .selection
            .bad_episodes
            .contains(&item.episode.id)
        {
            self.progress
                .note(&format!("left out {} (bad-episodes list)", item.episode.id));
            self.progress.advance(1, &item.episode.id);
            self.summary.excluded.push(item.episode.id);
            return None;
        }
        let e = match dexjoco_formats::raw::read_replay_label(&item.dir) {
            Ok(Some(l)) if !l.success && !l.evaluated && !self.options.include_failed => {
                ConvertError::FailedReplay {
                    dir: item.dir.clone(),
                }
            }
            Ok(Some(l)) if l.flagged() && !self.options.include_flagged => {
                ConvertError::FlaggedReplay {
                    dir: item.dir.clone(),
                    flags: l
                        .flags
                        .iter()
                        .map(RenderFlag::describe)
                        .collect::<Vec<_>>()
                        .join("; "),
                }
            }
            Ok(label) => return Some((item, label)),
            Err(e) => ConvertError::Format(e),
        };
        let key = (self.ordinal, 0);
        fail(&mut self.failures, key, self.progress, item.episode.id, &e);
        None
    }

    /// Writes a prepared batch in input order; episodes that failed to prepare or do not
    /// fit the dataset are left out.
    fn write_batch(
        &mut self,
        prepared: Vec<Result<PreparedEpisode, ConvertError>>,
        pending: &[Pending],
    ) -> Result<(), ConvertError> {
        for (p, (i, input, _)) in prepared.into_iter().zip(pending) {
            let p = match p {
                Ok(p) => p,
                Err(e) => {
                    let id = input.episode.id.clone();
                    fail(&mut self.failures, (*i, 1), self.progress, id, &e);
                    continue;
                }
            };
            if let Some(w) = self.writer.as_ref()
                && let Err(e) = w.check_compatible(&p)
            {
                let e = ConvertError::from(e);
                fail(&mut self.failures, (*i, 1), self.progress, p.id.clone(), &e);
                continue;
            }
            self.write(p)?;
        }
        Ok(())
    }

    /// Writes one episode and counts it (videos, skipped frames, norm statistics).
    fn write(&mut self, p: PreparedEpisode) -> Result<(), ConvertError> {
        let id = p.id.clone();
        self.summary.skipped_frames += p.skipped;
        self.summary.videos_copied += p.videos.iter().filter(|v| v.copied).count();
        self.summary.videos_encoded += p.videos.iter().filter(|v| !v.copied).count();
        let smart = p.videos.iter().filter(|v| v.reencoded_frames > 0);
        self.summary.videos_smart_cut += smart.clone().count();
        self.summary.frames_reencoded += smart.map(|v| v.reencoded_frames).sum::<usize>();
        if let Some(norm) = self.norm.as_mut() {
            norm.add_episode(
                &crate::prepare::as_f32(&p.state),
                p.state.width(),
                &crate::prepare::as_f32(&p.action),
                p.action.width(),
            );
        }
        let w = self.writer.as_mut().expect("made from the first batch");
        w.write_episode(p)?;
        self.progress.advance(1, &id);
        Ok(())
    }

    /// Finishes the dataset (and openpi's norm stats) and removes the work folder.
    fn finish(mut self, work: &Path) -> Result<Summary, ConvertError> {
        self.failures.sort_by_key(|(k, _)| *k);
        self.summary.failed = self.failures.into_iter().map(|(_, f)| f).collect();
        let Some(w) = self.writer else {
            // Nothing to write: say why when every episode failed.
            return Err(match self.summary.failed.first() {
                Some(f) => ConvertError::AllFailed {
                    count: self.summary.failed.len(),
                    first: format!("{}: {}", f.episode, f.reason),
                },
                None => ConvertError::NoEpisodes,
            });
        };
        (self.summary.episodes, self.summary.frames) = (w.episodes(), w.frames());
        w.finish()?;
        if let Some(norm) = self.norm {
            norm.write(self.root)?;
        }
        fs_err::remove_dir_all(work)?;
        Ok(self.summary)
    }
}
