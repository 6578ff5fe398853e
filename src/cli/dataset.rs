//! `dataset` subcommands: management of any LeRobot v3.0 dataset after it is made.

use std::path::PathBuf;

use clap::{Args, Subcommand};

/// The `dataset` subcommands.
#[derive(Debug, Subcommand)]
pub enum DatasetCommand {
    /// What a LeRobot v3.0 dataset holds: episodes, frames, tasks, features and codecs,
    /// per-episode columns, splits, size.
    Info(DatasetInfoArgs),
    /// Keep (or drop) episodes by index, task, length or any per-episode column, into a
    /// new dataset: re-indexed, every custom column kept, videos cut by stream copy,
    /// statistics recomputed.
    Filter(DatasetFilterArgs),
    /// Deal episodes into train/validation/... datasets by a seeded shuffle stratified
    /// per task.
    Split(DatasetSplitArgs),
    /// Join several datasets into one: features renamed by a mapping, 1-D float widths
    /// zero-padded, tasks and per-episode columns unioned, videos copied whole.
    Merge(DatasetMergeArgs),
    /// Remove or rename features (a camera, the state) into a new dataset.
    Features(DatasetFeaturesArgs),
    /// Cut idle frames at the start and end of each episode (or keep given frame
    /// ranges), videos by smart cut: only the frames before the next keyframe re-encoded.
    Trim(DatasetTrimArgs),
    /// Encode the videos again (codec, CRF, keyframe interval) into a new dataset, a
    /// keyframe at every episode start.
    Reencode(DatasetReencodeArgs),
    /// Recompute meta/stats.json exactly from all frames, in place (the previous one kept
    /// as stats.json.bak), and openpi's norm_stats.json on request.
    Stats(DatasetStatsArgs),
    /// Write the dataset as LeRobot v2.1 (what openpi's pinned lerobot reads): one parquet
    /// and one mp4 per camera for each episode, cut by stream copy.
    #[command(name = "to-v21")]
    ToV21(DatasetToV21Args),
}

/// `dataset info` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data dataset info                          # the dataset convert wrote
  dexjoco-data dataset info ~/.cache/huggingface/lerobot/lerobot/pusht --json")]
pub struct DatasetInfoArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `dataset filter` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Every condition given must hold for an episode to be kept (with --drop: to be dropped).

Examples:
  dexjoco-data dataset filter --where 'outcome/success == true'   # successful replays only
  dexjoco-data dataset filter ds/ --episodes 0,2,5-7 --drop --out ds_clean/
  dexjoco-data dataset filter ds/ --task 'Click the mouse.' --min-length 200
  dexjoco-data dataset filter ds/ --where 'randomization/camera_azimuth < 0.5' --where 'outcome/flagged == false'

The source is never changed. The new dataset is written beside OUT and renamed into
place whole; an existing OUT is replaced only with --overwrite.")]
pub struct DatasetFilterArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Output dataset folder (default: DATASET_filtered beside it).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Episode indices (comma-separated, ranges as 3-7).
    #[arg(long, value_delimiter = ',')]
    pub episodes: Vec<String>,
    /// Episodes of this task (repeatable).
    #[arg(long)]
    pub task: Vec<String>,
    /// Episodes of at least this many frames.
    #[arg(long)]
    pub min_length: Option<usize>,
    /// Episodes of at most this many frames.
    #[arg(long)]
    pub max_length: Option<usize>,
    /// A per-episode column compared with a value: 'COLUMN OP VALUE', OP one of
    /// == != < <= > >= (repeatable; `dataset info` lists the columns).
    #[arg(long = "where", value_name = "PREDICATE")]
    pub predicates: Vec<String>,
    /// Drop the episodes matching instead of keeping them.
    #[arg(long)]
    pub drop: bool,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// `dataset split` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Each task's episodes are shuffled (seeded) and dealt in the given fractions (largest
remainder), so every split has every task in proportion. Writes OUT/<split>/ (a dataset
each, info.json's splits naming it) and OUT/split.json (the source episodes of each).

Examples:
  dexjoco-data dataset split --splits train=0.9,val=0.1
  dexjoco-data dataset split ds/ --splits train=0.8,val=0.1,test=0.1 --seed 7 --out ds_splits/")]
pub struct DatasetSplitArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Split names and fractions: NAME=FRACTION,... summing to at most 1.
    #[arg(long, default_value = "train=0.9,val=0.1")]
    pub splits: String,
    /// Seed of the shuffle.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output folder (default: DATASET_split beside it).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// `dataset merge` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Episodes in the order of the datasets given. Every dataset must have the same features
(after --rename) with the same dtype and shape (1-D float features of different widths
with --pad), the same fps and the same video codec; what differs is named. A per-episode
column some datasets lack is null for their episodes.

Examples:
  dexjoco-data dataset merge run1/convert/lerobot-v3 run2/convert/lerobot-v3 --out both/
  dexjoco-data dataset merge sim/ real/ --rename observation.images.cam_high=observation.images.third_person --out all/
  dexjoco-data dataset merge click_mouse/ hanoi_bimanual/ --pad --out all/   # 23- and 46-wide actions")]
pub struct DatasetMergeArgs {
    /// The dataset folders, in order (two or more).
    #[arg(value_name = "DATASET", required = true, num_args = 2..)]
    pub datasets: Vec<PathBuf>,
    /// Output dataset folder.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Rename a feature in every dataset before merging: OLD=NEW (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub rename: Vec<String>,
    /// Zero-pad 1-D float features of different widths to the widest.
    #[arg(long)]
    pub pad: bool,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// `dataset features` options.
#[derive(Debug, Args)]
#[command(after_help = "\
A removed feature's data column, videos and per-episode columns are left out; a renamed
one keeps its values under the new key (data column, video folder, per-episode columns).
timestamp, frame_index, episode_index, index and task_index stay.

Examples:
  dexjoco-data dataset features ds/ --remove observation.images.handcam_rgb --out ds_one_camera/
  dexjoco-data dataset features ds/ --rename observation.images.third_person=observation.images.base --out ds_renamed/")]
pub struct DatasetFeaturesArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Output dataset folder.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Leave out this feature (repeatable).
    #[arg(long, value_name = "KEY")]
    pub remove: Vec<String>,
    /// Rename a feature: OLD=NEW (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub rename: Vec<String>,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// `dataset stats` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Numeric features from every frame (min, max, mean, std, quantiles: as lerobot's
get_feature_stats on all frames, not merged per-episode estimates); video features
combined from the episodes' own statistics. The new stats.json is written atomically; the
previous one, where it differed, is kept as meta/stats.json.bak, and the largest change per
feature is printed. Edits (filter, split, merge, features) recompute both files already.

Examples:
  dexjoco-data dataset stats ~/.cache/huggingface/lerobot/lerobot/pusht
  dexjoco-data dataset stats ds/ --norm-stats --norm-stats-horizon 10   # pi0.5 on DexJoCo")]
pub struct DatasetStatsArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// openpi's statistics.
    #[command(flatten)]
    pub norm_stats: super::NormStatsArgs,
}

/// `dataset to-v21` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Frames and videos bit-exact (each episode's video cut out by stream copy); per-episode
columns with a JSON form go into meta/episodes.jsonl, per-episode statistics into
meta/episodes_stats.jsonl; lerobot 0.6's language features have no v2.1 form and are
left out (named). openpi's norm_stats.json is computed from the same frames either way.

Examples:
  dexjoco-data dataset to-v21 --out ds_v21/          # the dataset convert wrote
  dexjoco-data dataset to-v21 ds/ --out ~/.cache/huggingface/lerobot/me/ds_v21")]
pub struct DatasetToV21Args {
    /// The v3.0 dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Output dataset folder.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// `dataset trim` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Every episode is kept, with fewer frames: frame_index and timestamp start at 0 again,
per-episode statistics and stats.json are recomputed. A frame moves when some element of
--column differs from the frame before by more than --threshold (LIBERO's no-op rule, for
absolute actions); the idle frames before the first moving frame and after the last go,
but --margin of them. An episode that never moves is kept whole (named).

Videos: the kept frames are cut by stream copy; where an episode's first (or last) kept
frame is no place a stream copy can start (or end), only the frames up to the next
keyframe (or after the last place it can end) are re-encoded, with the source's own stream
headers (a smart cut), so almost every frame stays bit-exact. Where no encoder setting
reproduces the headers, that video file is re-encoded whole (counted).

Examples:
  dexjoco-data dataset trim --idle                              # the dataset convert wrote
  dexjoco-data dataset trim ds/ --idle --threshold 1e-3 --margin 2 --out ds_trimmed/
  dexjoco-data dataset trim ds/ --frames 0=10..250 --frames 3=0..180 --out ds_cut/")]
pub struct DatasetTrimArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Output dataset folder (default: DATASET_trimmed beside it).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Remove idle frames at the start and end of every episode.
    #[arg(long, conflicts_with = "frames")]
    pub idle: bool,
    /// The per-frame feature whose changes count as movement.
    #[arg(long, default_value = "action")]
    pub column: String,
    /// Largest change of any element between consecutive frames still counted as idle.
    #[arg(long, default_value_t = 1e-4)]
    pub threshold: f64,
    /// Idle frames kept before the first and after the last movement.
    #[arg(long, default_value_t = 0)]
    pub margin: usize,
    /// Keep frames FROM..TO (end excluded) of episode EPISODE: EPISODE=FROM..TO
    /// (repeatable; other episodes stay whole).
    #[arg(long, value_name = "EPISODE=FROM..TO")]
    pub frames: Vec<String>,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// Codecs `dataset reencode` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ReencodeCodecArg {
    /// H.264 (libx264, yuv420p): what most players and openpi's decoders read fastest.
    H264,
    /// AV1 (libsvtav1, yuv420p): lerobot's default, smaller files.
    Av1,
}

/// `dataset reencode` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Each video file is decoded (yuv420p, no colour conversion) and encoded again with a
keyframe at every episode's first frame, whatever --gop, so later filters and splits still
cut it by stream copy. Data, metadata and statistics are copied as they are (video
statistics describe the frames before re-encoding; `dataset stats` recomputes numbers
only). Files are encoded in parallel (-j); the bytes do not depend on it.

Examples:
  dexjoco-data dataset reencode ds/ --codec h264 --crf 23 --gop 2 --out ds_h264/
  dexjoco-data dataset reencode ds/ --codec av1 --crf 30 --preset 8 --out ds_small/
  dexjoco-data dataset reencode ds/ --keys observation.images.wrist --codec h264 --out ds_wrist/")]
pub struct DatasetReencodeArgs {
    /// The dataset folder (default: <work-dir>/convert/lerobot-v3).
    #[arg(value_name = "DATASET")]
    pub dataset: Option<PathBuf>,
    /// Output dataset folder (default: DATASET_reencoded beside it).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// The codec.
    #[arg(long, value_enum, default_value = "h264")]
    pub codec: ReencodeCodecArg,
    /// Constant rate factor (lower: better and larger; default 23 for H.264, 30 for AV1).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=63))]
    pub crf: Option<u8>,
    /// Encoder preset: x264's name (ultrafast .. slow; default medium) or SVT-AV1's
    /// number (0 slowest .. 13 fastest; default 12).
    #[arg(long)]
    pub preset: Option<String>,
    /// Frames from one keyframe to the next at most (lerobot: 2, for fast random
    /// access; default: the encoder's own, 250 for x264).
    #[arg(long, value_name = "FRAMES", value_parser = clap::value_parser!(u32).range(1..))]
    pub gop: Option<u32>,
    /// Only these video features (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    pub keys: Vec<String>,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub overwrite: bool,
}
