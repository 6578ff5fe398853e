//! Arguments of the pipeline commands: ingest, export, scripted, augment, cameras, convert,
//! stats.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use dexjoco_augment::VideoEncoding;

use super::{GeometryArg, QualityArg, RendererArgs, TasksDirArgs, WorkerArgs};

/// `ingest` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data ingest recordings/                      # raw folders and *.mcap, recursively
  dexjoco-data ingest teleop.mcap ../raw/click_mouse/episode_000003
  dexjoco-data ingest old_demos/ --task pick_bucket    # folders whose path names no task
  dexjoco-data ingest recordings/ --out my_store/      # another store than <work-dir>/ingest
  dexjoco-data ingest recordings/ --overwrite          # redo inputs already in the store

Good episodes land in the store (<work-dir>/ingest by default) in the DexJoCo raw layout,
<task>/episode_NNNNNN/{replay.zarr, videos/}; rejected inputs are copied under
quarantine/<id>/ with reason.json. manifest.json lists both, with every problem's file,
episode, field and frame. Re-running skips inputs already stored (ids are content
hashes); a killed run is completed by running it again. One run writes a store at a
time (a second one stops at once, naming the first). With --overwrite, a stored episode
that fails its re-check is kept as it was and reported. Exit code 3 when any input was
rejected.")]
pub struct IngestArgs {
    /// MCAP files and folders; folders are searched recursively for DexJoCo raw episode
    /// folders (holding replay.zarr) and *.mcap files.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The episode store to add to (default: <work-dir>/ingest).
    #[arg(short, long, visible_alias = "store", env = "DEXJOCO_STORE")]
    pub out: Option<PathBuf>,
    /// Re-read and rewrite inputs already in the store (they keep their folders and ids;
    /// one that now fails its checks is kept as it was and reported).
    #[arg(long, visible_alias = "force")]
    pub overwrite: bool,
    /// Task of raw folders whose path does not name one (<task>/episode_N or <task>_demo_...).
    #[arg(long)]
    pub task: Option<String>,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
    /// Allowed deviation of a quaternion's norm from 1.
    #[arg(long, default_value_t = 1e-3)]
    pub quat_tolerance: f64,
    /// Allowed relative deviation of a timestamp step from 1/fps.
    #[arg(long, default_value_t = 0.1)]
    pub timestep_tolerance: f64,
    /// Print the run's report as JSON on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Containers `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// One MCAP teleop log per episode (schemas/mcap-teleop.md), readable in Foxglove.
    Mcap,
}

/// `export` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data export --to mcap                        # every episode of <work-dir>/ingest
  dexjoco-data export --to mcap store/click_mouse/episode_000002 --out logs/
  dexjoco-data export --to mcap store_a/ store_b/ --overwrite

Each episode becomes <out>/<task>_<folder>.mcap; two episodes that would get the same
name (stores with the same folder names) get -2, -3... in input order. A file already
in <out> is never replaced without --overwrite. Files are written whole (temporary file,
then rename). An episode that cannot be read is left out and named, the others are
written, and the exit code is 3; so are MCAP logs among the inputs (they are MCAP
already).")]
pub struct ExportArgs {
    /// Output container.
    #[arg(long, value_enum)]
    pub to: ExportFormat,
    /// Episode folders, or stores (every landed episode) (default: <work-dir>/ingest).
    #[arg(value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// Output folder (default: <work-dir>/export).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Replace files already in the output folder.
    #[arg(long)]
    pub overwrite: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}

/// `scripted` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Writes OUT/<task>/episode_NNNNNN (action, state, timestamps; no videos), numbered in the
order the successful plans were made. The same --seed, task and scene give identical
files. OUT/<task> is written beside and renamed into place whole; one an earlier run wrote
is replaced only with --overwrite. Exit code 3: some plans did not succeed (not written);
1: none did.")]
pub struct ScriptedArgs {
    /// Task id, e.g. pinch_tongs.
    #[arg(long)]
    pub task: String,
    /// Random resets to plan from (1 to 1000000).
    #[arg(long, default_value_t = 1,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1_000_000))]
    pub episodes: usize,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace OUT/<task> written by an earlier run, whole (no episode of a bigger
    /// earlier run stays).
    #[arg(long)]
    pub overwrite: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}

/// Dataset formats `convert` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ConvertFormatArg {
    /// LeRobot v3.0: what lerobot >= 0.4 reads (0.6.1 reads only this).
    #[value(name = "lerobot-v3")]
    LerobotV3,
    /// LeRobot v2.1: what openpi's pinned lerobot reads (per-episode files, jsonl metadata).
    #[value(name = "lerobot-v2.1")]
    LerobotV21,
    /// Diffusion Policy: replay_buffer.zarr (Zarr v2) with images as uint8 (T, H, W, C).
    #[value(name = "diffusion-policy")]
    DiffusionPolicy,
}

/// Video codecs `convert` encodes with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum VideoCodecArg {
    /// AV1 (libsvtav1, crf 30, preset 12, GOP 2): lerobot's default.
    Av1,
    /// H.264 (libx264, crf 21, GOP 2).
    H264,
}

/// `convert` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data convert dexjoco-work/ingest --out datasets/click_mouse
  dexjoco-data convert raw/ --config ../shared/dexjoco-upstream/converter-configs/multi_task
  dexjoco-data convert raw/ --config selection.toml --reencode --video-codec h264
  dexjoco-data convert raw/ --overwrite --no-skip-static
  dexjoco-data convert raw/ --format diffusion-policy --videos --norm-stats
  dexjoco-data convert dexjoco-work/augment --instructions paraphrases.yaml

Input: an episode store (a folder with manifest.json, as `ingest` writes it: its landed
episodes) or any folder of DexJoCo raw episode folders (replay.zarr + videos/<camera>.mp4),
searched recursively (folders starting with `.`, such as augment's .staging/, are not
read). Without an input: <work-dir>/augment. Replays whose replay.json says the task
failed (augment --keep-failed) are left out and named unless --include-failed, those a
render check flagged unless --include-flagged. Every replay converted carries its outcome
and randomization draw as per-episode metadata (LeRobot v3.0: meta/episodes columns
outcome/*, randomization/*; Diffusion Policy: meta/<name> arrays and meta/.zattrs).

Videos are joined per camera by stream copy when the source codec fits (H.264, HEVC,
AV1 in yuv420p at the dataset's rate): no re-encode, and static leading frames are
skipped through the episodes' from_timestamp. Otherwise, or with --reencode, they are
encoded (AV1 by default).

--format diffusion-policy writes <out>/replay_buffer.zarr (data/action, data/state,
data/timestamp as float64, data/<camera> as uint8 frames, meta/episode_ends); --videos
also keeps <out>/videos/<episode>/<camera>.mp4 with videos/name_map.json.
--norm-stats writes openpi's <out>/norm_stats.json (state, actions: mean, std, q01, q99).

Subtasks: replays that carry subtask spans (augment's replay.json) get each frame's
running subtask: LeRobot v3.0 in lerobot 0.6's language columns (language_persistent:
a `subtask` row where the running subtask changes, and `task_aug` rows with the
instruction and its paraphrases: the task spec's prompt_variants, or --instructions),
LeRobot v2.1 and Diffusion Policy as a per-frame subtask_index (texts in
meta/subtasks.jsonl, meta/.zattrs).

An episode that cannot be read, lacks what the selection asks for or does not fit the
dataset's layout is left out and named with its reason; the rest is written and the exit
code is 3. The dataset appears in <out> only when complete. One run writes <out> at a
time (lock file .<name>.lock beside it). --overwrite replaces only a dataset convert
made; never a folder that holds or lies inside an input, or holds the work folder.")]
pub struct ConvertArgs {
    /// Episode stores or folders of DexJoCo raw episodes (default: <work-dir>/augment).
    #[arg(value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// The same as INPUT (repeatable).
    #[arg(
        short,
        long = "input",
        value_name = "INPUT",
        env = "DEXJOCO_CONVERT_INPUT"
    )]
    pub input_flag: Vec<PathBuf>,
    /// Output dataset folder (default: <work-dir>/convert/<format>).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ConvertFormatArg::LerobotV3)]
    pub format: ConvertFormatArg,
    /// Selection config: a TOML/YAML file, or a DexJoCo reference converter config
    /// folder (selected_data.yaml, slice_config.yaml, language_instructions.yaml).
    #[arg(long, env = "DEXJOCO_CONVERT_CONFIG")]
    pub config: Option<PathBuf>,
    /// Prompt variants: a TOML/YAML file of task id -> paraphrases of its instruction
    /// (a list, or one text), written as `task_aug` rows in LeRobot v3.0 (replaces the
    /// task spec's prompt_variants for the tasks it names).
    #[arg(long, value_name = "FILE")]
    pub instructions: Option<PathBuf>,
    /// Replace a non-empty output folder (only a dataset convert made).
    #[arg(long)]
    pub overwrite: bool,
    /// Also convert replays whose replay.json says the task failed (augment
    /// --keep-failed); by default they are left out and named (exit code 3).
    #[arg(long)]
    pub include_failed: bool,
    /// Also convert replays a render check flagged (blank frames, a frozen video,
    /// non-finite values: replay.json's flags); by default they are left out and named
    /// with their flags (exit code 3).
    #[arg(long)]
    pub include_flagged: bool,
    /// Also export the privileged state (the task spec's state columns after the
    /// proprioception: objects' reset-time poses, dh) as `privileged.state` (LeRobot, outside
    /// observation.*, so policies do not take it as input) or data/privileged_state
    /// (Diffusion Policy), one name per column from the task spec.
    #[arg(long)]
    pub privileged_state: bool,
    /// Also export the environment state at every frame (each of the task's state objects'
    /// pose now, the targets its success derives from the reset, then the table offset dh,
    /// as augment, generate, scripted and eval record
    /// it) as `observation.environment_state` (LeRobot's key: its ACT and Diffusion Policy
    /// take it as input) or data/environment_state (Diffusion Policy), one name per column
    /// from the task spec. An episode without it (a recording not replayed) is left out
    /// and named.
    #[arg(long)]
    pub environment_state: bool,
    /// Also carry each camera's depth (augment --depth's videos/<camera>_depth.npz, float32
    /// metres): LeRobot v3.0 as lerobot 0.6.1 stores depth (video feature
    /// observation.images.<camera>_depth, 12-bit log-quantized, lossless HEVC), Diffusion
    /// Policy as data/<camera>_depth (float32 metres); not with --format lerobot-v2.1. An
    /// episode without its archives is left out and named.
    #[arg(long)]
    pub depth: bool,
    /// Keep static leading frames (skipped by default, by the reference converter's rule).
    #[arg(long)]
    pub no_skip_static: bool,
    /// Multi-task merge: one-arm episodes go into the right-arm slots of the two-arm
    /// layout, so single-arm and bimanual tasks share one dataset (same as
    /// `merge_bimanual = true` in --config).
    #[arg(long)]
    pub merge_bimanual: bool,
    /// Episode ids to leave out (repeatable; added to the config's list).
    #[arg(long = "exclude", value_name = "EPISODE")]
    pub exclude: Vec<String>,
    /// Encode every video, even where stream copy would do.
    #[arg(long)]
    pub reencode: bool,
    /// Codec for encoded videos.
    #[arg(long, value_enum, default_value_t = VideoCodecArg::Av1)]
    pub video_codec: VideoCodecArg,
    /// `robot_type` recorded in info.json.
    #[arg(long, default_value = "panda_allegro")]
    pub robot_type: String,
    /// Diffusion Policy: keep each episode's videos beside the replay buffer.
    #[arg(long)]
    pub videos: bool,
    /// openpi's norm stats.
    #[command(flatten)]
    pub norm_stats: NormStatsArgs,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}

/// `convert`'s openpi normalization statistics options.
#[derive(Debug, Args)]
pub struct NormStatsArgs {
    /// Also write openpi's norm_stats.json into the dataset folder.
    #[arg(long)]
    pub norm_stats: bool,
    /// Action chunk length for --norm-stats (openpi's action_horizon).
    #[arg(long, default_value_t = 50, value_name = "FRAMES",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub norm_stats_horizon: usize,
    /// Frames per update for --norm-stats (openpi's batch_size); the frames after the
    /// last whole batch are left out, as openpi's compute_norm_stats does.
    #[arg(long, default_value_t = 32, value_name = "FRAMES",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub norm_stats_batch: usize,
}

/// `augment` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data augment --replays 10                      # the sample demos, built-in scenes
  dexjoco-data augment --replays 10 --dry-run            # the plan and a time estimate first
  dexjoco-data augment --replays 10 --scene-dir ../shared/dexjoco-upstream/xmls
  dexjoco-data augment recordings/ --replays 5 --size 224 --quality fast -j 8
  dexjoco-data augment --replays 2 --camera handcam_rgb --keep-failed --out aug/
  dexjoco-data augment --replays 2 --camera front --depth --size 224  # + <camera>_depth.npz
  dexjoco-data augment --replays 10 --dynamics           # + mass/friction/stiffness per replay
  dexjoco-data augment --replays 10 --size 224 --renderer warp   # MuJoCo Warp's batch ray tracer (GPU)
  dexjoco-data augment data/ --out /shared/aug --shard 2/8   # one eighth, e.g. on one node
  dexjoco-data augment data/ --out /shared/aug --shard auto  # Slurm array / Kubernetes Indexed Job
  dexjoco-data augment data/ --out /shared/aug               # after the shards: the report
  scripts/slurm/submit.sh 8 data/ --out /shared/aug --replays 10   # the whole job on Slurm

Output: one DexJoCo raw folder per replay, <out>/<task>/<episode>__rNN/ (replay.zarr with
the recorded actions, recomputed state and action_rotvec; videos/third_person.mp4 plus one
video per --camera; with --depth videos/<camera>_depth.npz), augment_report.json / .md,
contact_sheet.png and augment_settings.json (the settings that decide the bytes: a later run
into the same --out with other settings is refused, naming the difference).

Workers: -j N worker processes (default: one per core), each with its own MuJoCo model and
EGL renderer; --egl-devices 0,1 spreads them over GPUs. A killed run resumes where it
stopped when run again; a crashed worker's unit is retried once. The same --seed gives the
same bytes whatever -j or --shard is.

Shards: --shard I/N renders a balanced, deterministic share (by frames) into a shared --out;
the same command without --shard afterwards renders nothing new and writes the report.
--shard auto reads SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT (a contiguous --array=0-N-1),
or JOB_COMPLETION_INDEX with DEXJOCO_SHARD_COUNT (a Kubernetes Indexed Job).

Inputs that cannot be replayed (unreadable, unknown task, missing field) are skipped and
listed; the rest of the batch goes on.
Exit code 3: some episodes were skipped, did not replay to success, or a unit failed twice.")]
pub struct AugmentArgs {
    /// Raw episode folders, episode stores or MCAP files (default: the sample data in
    /// datasets/demos).
    pub inputs: Vec<PathBuf>,
    /// Randomized replays per episode (1 to 10000).
    #[arg(long, default_value_t = dexjoco_augment::DEFAULT_REPLAYS,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000))]
    pub replays: usize,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Camera pose pool, JSON {"rows": [[azimuth, elevation, distance, ...]]} (default:
    /// the reference pool beside --scene-dir, else the built-in pool).
    #[arg(long)]
    pub camera_pool: Option<PathBuf>,
    /// Fixed scene camera to render too, with the same light/table randomization
    /// (repeatable), e.g. handcam_rgb.
    #[arg(short, long = "camera")]
    pub cameras: Vec<String>,
    /// Image width and height in pixels, even (H.264), at most 8192 (224 is the small
    /// preset).
    #[arg(long, default_value_t = 640, value_parser = super::image_side())]
    pub size: u32,
    /// Quality preset (paper = the reference's 8x multisampling).
    #[arg(long, value_enum, default_value_t = QualityArg::Paper)]
    pub quality: QualityArg,
    /// The renderer's meshes: full (the reference look), or light (simplified to half a
    /// pixel's error at this size: faster on a CPU; `bench augment --geometry full,light`
    /// measures the speed-up and the image difference).
    #[arg(long, value_enum, default_value_t = GeometryArg::Full)]
    pub geometry: GeometryArg,
    /// Keep replays whose task failed (flagged in the report).
    #[arg(long)]
    pub keep_failed: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
    /// Also write each camera's depth as videos/<camera>_depth.npz (key "depth", float32
    /// (T, H, W), metres, as numpy.savez_compressed writes it). Large: 1.6 MB per
    /// 640x640 frame before compression.
    #[arg(long)]
    pub depth: bool,
    /// Randomize dynamics per replay as the task spec says (object masses, joint friction
    /// losses and stiffnesses, drawn from the scene's values); each replay is then
    /// simulated on its own and kept only if the task still succeeds.
    #[arg(long)]
    pub dynamics: bool,
    /// Only the first N frames of each episode (a quick look; success needs the whole;
    /// 0: whole episodes, as without the flag).
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// Output folder (default: <work-dir>/augment).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// After a recording that ends without success, repeat its last action up to N more
    /// steps, stopping at the first success. The DexJoCo recorder stops on the step that
    /// first succeeds, so a replay that drifts by a step (another MuJoCo version, rounding)
    /// would otherwise be dropped; 30 = one second at 30 Hz. 0: the reference's strict
    /// replay.
    #[arg(long, default_value_t = dexjoco_augment::DEFAULT_EXTEND_STEPS, value_name = "N")]
    pub extend_steps: usize,
    /// How the camera videos are encoded.
    #[command(flatten)]
    pub video: VideoEncodingArgs,
    /// Render only this share of the work: I/N (0-based), or `auto` from the cluster's
    /// environment (Slurm job array, Kubernetes Indexed Job).
    #[arg(long, value_name = "I/N|auto")]
    pub shard: Option<String>,
    /// Print the plan (episodes, replays, frames per task, what is done) and a time
    /// estimate from a short calibration render; render nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Where the worker processes render.
    #[command(flatten)]
    pub workers: WorkerArgs,
    /// Which renderer draws the frames.
    #[command(flatten)]
    pub renderer: RendererArgs,
    /// When --out was made with other settings, start clean: remove what augment wrote
    /// there (replays, records, report), nothing else.
    #[arg(long)]
    pub overwrite: bool,
}

/// `augment-worker`: internal, started by `augment` (JSON lines on stdin/stdout).
#[derive(Debug, Args)]
pub struct AugmentWorkerArgs {}

/// `cameras` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data cameras --task click_mouse --preview
  dexjoco-data cameras --task bimanual_hanoi --scene-dir ../shared/dexjoco-upstream/xmls
  dexjoco-data cameras --task click_mouse --count 30 --elevation -10,-40 --azimuth -70,70 --out my_pool.json
  dexjoco-data augment --camera-pool my_pool.json --replays 10

Poses are sampled uniformly on the sphere band around the look-at point (0, 0, 1):
uniform azimuth, uniform sine of the altitude. Each is scored in the task's default initial
state by casting a ray from the camera to the centre of every visible geom of the task's
objects (its state objects and derived poses); a point is occluded when the first visible
geom the ray hits belongs to something else (robot, table, another object). The --count
least occluded poses are kept and written as {\"rows\": [[azimuth, elevation, distance, 45],
...]}, the format of the reference replay_cameras.json. Defaults follow the reference
pools: 1.4 m and elevations -2..-30 for one arm, 2.4 m and -25..-50 for two.")]
pub struct CamerasArgs {
    /// Task id (its scene and objects).
    #[arg(long)]
    pub task: String,
    /// Scene pack folder (e.g. the DexJoCo xmls/); default: the built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Poses kept.
    #[arg(long, default_value_t = 50,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub count: usize,
    /// Poses sampled and scored (at least --count).
    #[arg(long, default_value_t = 2000,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub candidates: usize,
    /// Distance from the look-at point in metres (default: 1.4 one arm, 2.4 two arms).
    #[arg(long)]
    pub distance: Option<f64>,
    /// Elevation band in degrees, negative = above, e.g. -2,-30.
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 2,
        allow_negative_numbers = true
    )]
    pub elevation: Option<Vec<f64>>,
    /// Azimuth band in degrees, e.g. -90,90.
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 2,
        allow_negative_numbers = true
    )]
    pub azimuth: Option<Vec<f64>>,
    /// Pool file (default: <work-dir>/cameras/<task>.json).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Also write a contact sheet of 16 kept views (<out>_preview.png).
    #[arg(long)]
    pub preview: bool,
    /// Replace the pool file (and preview) written by an earlier run.
    #[arg(long)]
    pub overwrite: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}
/// Log base of the Jensen-Shannon divergence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum JsBaseArg {
    /// Bits: divergences lie in [0, 1].
    #[value(name = "2")]
    Two,
    /// Nats (SciPy's default): divergences lie in [0, ln 2].
    #[value(name = "e")]
    E,
}

/// `stats` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data stats --language-eval                    # the shipped EXAMPLE input (not results)
  dexjoco-data stats --language-eval outputs/ipad_language/
  dexjoco-data stats --language-eval trials.csv --js-base e
  dexjoco-data stats --success-table outputs/           # one subfolder per policy
  dexjoco-data stats --success-table                    # the shipped EXAMPLE runs (not results)
  dexjoco-data stats --language-eval --success-table --out report/ --json
  dexjoco-data stats --dataset                          # the ingest store <work-dir>/ingest
  dexjoco-data stats raw_demos/ --dataset               # any folder of DexJoCo raw episodes
  dexjoco-data stats --dataset dexjoco-work/augment     # augment output: + replay success rates

The input of one analysis can be given as INPUT or after its flag; with several
analyses, give each its input after its flag.

Language evaluation input: a folder <config>/<task>_seed<s>/episode_XX_{success|failure}_{<digits>|no_password_input}/
as the DexJoCo evaluator writes it (instructions.csv at its root names each config's instruction
and expected answer), or a tidy .csv/.json with instruction, expected, seed, episode, output.
Writes <out>/language-eval/ (summary.md, language_eval.json, CSVs, heatmap.png/.svg) and
<out>/success-table/ (success_table.md/.tex/.csv/.json) and <out>/dataset/ (dataset_stats.json,
summary.md, source_norm_stats.json, plots; replay_success.md/.json when the folder holds an
augment_report.json); the summary goes to stdout. Each of these folders is replaced
whole, so nothing of an earlier run remains in it. An episode that cannot be read, or
whose array widths differ from the other episodes of its task, is left out and named
(exit code 3).")]
pub struct StatsArgs {
    /// The input of the one analysis asked for (the same as giving it after its flag).
    #[arg(value_name = "INPUT")]
    pub input: Option<PathBuf>,
    /// The same as INPUT.
    #[arg(long = "input", value_name = "INPUT", conflicts_with = "input")]
    pub input_flag: Option<PathBuf>,
    /// Language-generalization analysis (DexJoCo paper, appendix A) of an evaluation
    /// folder or a tidy .csv/.json file. Without a value: the example input shipped in
    /// datasets/examples/language-eval (made up, not results).
    #[arg(long, value_name = "INPUT", num_args = 0..=1)]
    pub language_eval: Option<Option<PathBuf>>,
    /// Success-rate table (mean ± std over seeds per task x regime x policy) of the
    /// evaluation runs under DIR (run folders `<task>[_rand_full]_seed<s>`, or DIR itself:
    /// one `eval --output` folder of any name). A run whose success_rate_*.txt marker
    /// disagrees with its episode folders is left out, named (exit 3). Without a value:
    /// the example runs shipped in datasets/examples/success-table (made up, not results).
    #[arg(long, value_name = "DIR", num_args = 0..=1)]
    pub success_table: Option<Option<PathBuf>>,
    /// Dataset statistics (episodes, frames, per-task counts, lengths, per-dimension
    /// action/state distributions with plots, openpi norm stats) of an episode store or a
    /// folder of DexJoCo raw episodes; for an augment output folder also the replay
    /// success rates per task from its report. Without a value: the ingest store
    /// <work-dir>/ingest.
    #[arg(long, value_name = "STORE", num_args = 0..=1)]
    pub dataset: Option<Option<PathBuf>>,
    /// Output folder (default: <work-dir>/stats).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Log base of the Jensen-Shannon divergences.
    #[arg(long, value_enum, default_value_t = JsBaseArg::Two)]
    pub js_base: JsBaseArg,
    /// Significance level of the chi-square test in the verdict.
    #[arg(long, default_value_t = 0.05)]
    pub alpha: f64,
    /// Normalized mutual information below which the verdict calls a dependence
    /// negligible.
    #[arg(long, default_value_t = 0.1)]
    pub nmi_weak: f64,
    /// Print the reports as JSON on stdout instead of the Markdown summaries.
    #[arg(long)]
    pub json: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}

/// `augment`'s video encoding flags.
#[derive(Debug, Args)]
pub struct VideoEncodingArgs {
    /// x264's constant rate factor of the camera videos (lower: better and larger; 21 is
    /// the DexJoCo recorder's). 0 writes lossless RGB (libx264rgb), the rendered frames
    /// bit for bit, for measuring or re-encoding later (large; convert re-encodes it).
    #[arg(long, default_value_t = VideoEncoding::default().crf, value_name = "CRF", value_parser = clap::value_parser!(u8).range(0..=51))]
    pub crf: u8,
    /// x264's speed preset of the camera videos: ultrafast, superfast, veryfast, faster,
    /// fast, medium (x264's default, the DexJoCo recorder's), slow. The default was chosen
    /// by measurement (docs/performance.md, "Video encoding").
    #[arg(long, default_value_t = VideoEncoding::default().preset, value_name = "PRESET")]
    pub x264_preset: dexjoco_video::X264Preset,
    /// At most N frames from one keyframe to the next in the camera videos. convert
    /// stream-copies them into LeRobot datasets, where a random item decodes from the
    /// keyframe before it: short intervals read fast at training time. 0: x264's own (250);
    /// at most 2^31 - 1 (ffmpeg's).
    #[arg(long, default_value_t = VideoEncoding::default().keyframe_interval, value_name = "N",
          value_parser = clap::value_parser!(u32).range(0..=i64::from(i32::MAX)))]
    pub keyframe_interval: u32,
}

impl VideoEncodingArgs {
    /// The encoding these flags ask for.
    pub fn encoding(&self) -> VideoEncoding {
        VideoEncoding {
            crf: self.crf,
            preset: self.x264_preset,
            keyframe_interval: self.keyframe_interval,
        }
    }
}
