//! Every clap definition of the `dexjoco-data` command line, in one place.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

const AFTER_HELP: &str = "\
Examples:
  dexjoco-data doctor                         # check MuJoCo, EGL rendering, ffmpeg, Python readers
  dexjoco-data render                         # render the built-in tabletop scene's cameras
  dexjoco-data render scene.xml --camera front --depth
  dexjoco-data bench render --frames 20       # rendering frames/s per quality preset
  dexjoco-data ingest recordings/             # validate and store MCAP logs and raw folders
  dexjoco-data export --to mcap               # stored episodes -> MCAP teleop logs
  dexjoco-data augment --replays 10           # randomized replays of the sample demos
  dexjoco-data convert                        # augment output -> LeRobot v3.0
  dexjoco-data stats --language-eval
  dexjoco-data scripted --task pinch_tongs --episodes 5 --out demos/

Stages chain through the work folder (default ./dexjoco-work, one subfolder per stage),
so `augment`, `convert` and `stats` need no paths; every path can be overridden.

Exit codes:
  0  success
  1  the command failed (bad input, missing file, rendering unavailable...)
  2  usage error (unknown flag, bad value)
  3  finished, but some episodes were rejected (see the report)
  4  this subcommand is not available in this version yet";

/// Data pipeline for DexJoCo dexterous-manipulation demonstrations: ingest teleop
/// episodes, replay them in MuJoCo under randomization, convert to LeRobot / Diffusion
/// Policy datasets, and analyse results.
#[derive(Debug, Parser)]
#[command(name = "dexjoco-data", version, after_help = AFTER_HELP, propagate_version = true)]
pub struct Cli {
    /// Options every subcommand takes.
    #[command(flatten)]
    pub global: GlobalArgs,
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// Options shared by every subcommand.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// More log output (-v: debug, -vv: trace). Logs go to stderr.
    #[arg(short, long, global = true, action = clap::ArgAction::Count, conflicts_with = "quiet")]
    pub verbose: u8,
    /// Only errors; no progress bars.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(short, long, global = true, env = "DEXJOCO_JOBS",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub jobs: Option<usize>,
    /// Seed of every random choice; the same seed and inputs give identical outputs.
    #[arg(long, global = true, env = "DEXJOCO_SEED", default_value_t = 0)]
    pub seed: u64,
    /// Work folder: each stage writes its own subfolder (ingest/, augment/, convert/,
    /// stats/, render/, bench/) and reads the previous stage's.
    #[arg(
        long,
        global = true,
        env = "DEXJOCO_WORK_DIR",
        default_value = "dexjoco-work"
    )]
    pub work_dir: PathBuf,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Report what this machine has: MuJoCo, the EGL device (GPU or software), ffmpeg
    /// encoders and the Python readers.
    Doctor(DoctorArgs),
    /// Render PNGs of an MJCF scene's cameras (RGB, optional depth) and a contact sheet.
    Render(RenderArgs),
    /// Measure performance (rendering frames/s per quality preset and resolution).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Read raw teleop episodes (MCAP logs, DexJoCo raw folders), validate and store them.
    Ingest(IngestArgs),
    /// Write stored episodes in another container (MCAP teleop logs).
    Export(ExportArgs),
    /// Replay each episode under sampled camera/light/texture randomization; keep successes.
    Augment(AugmentArgs),
    /// Build a third-person camera pose pool for a task: sample poses on a sphere, keep the
    /// least occluded (the DexJoCo paper's way); `augment --camera-pool` reads it.
    Cameras(CamerasArgs),
    /// Convert episodes to LeRobot v3.0 / v2.1 or a Diffusion Policy Zarr replay buffer.
    Convert(ConvertArgs),
    /// Dataset statistics, success tables and the language-generalization analysis.
    Stats(StatsArgs),
    /// Plan scripted demonstrations of a task from random resets and write the
    /// successful ones in the DexJoCo raw layout.
    Scripted(crate::commands::scripted::ScriptedArgs),
}

/// `doctor` options.
#[derive(Debug, Args)]
pub struct DoctorArgs {
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Rendering quality presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum QualityArg {
    /// 8x multisampling, shadows, reflections, skybox: as the DexJoCo reference renders.
    Paper,
    /// As paper, without multisampling.
    NoMsaa,
    /// Without multisampling and shadows.
    NoMsaaNoShadows,
    /// No multisampling, shadows, reflections or skybox: several times faster on a CPU.
    Fast,
}

impl QualityArg {
    /// The preset's name in `RenderQuality::PRESETS`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::NoMsaa => "no-msaa",
            Self::NoMsaaNoShadows => "no-msaa-no-shadows",
            Self::Fast => "fast",
        }
    }
}

/// `render` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data render
  dexjoco-data render ../shared/dexjoco-upstream/xmls/arena_arm_hand_plant.xml --quality paper
  dexjoco-data render scene.xml --camera front --camera left --depth --size 224
  dexjoco-data render scene.xml --steps 500 --out frames/
  dexjoco-data render --video --steps 1000 --camera front    # 2 s clip, 30 fps, H.264
  dexjoco-data render --task click_mouse                       # built-in scene, the task's cameras
  dexjoco-data render --task click_mouse --scene-dir ../shared/dexjoco-upstream/xmls
  dexjoco-data render --task all --size 320    # sheet: every built-in scene next to the reference")]
pub struct RenderArgs {
    /// MJCF scene file (default: the built-in tabletop scene).
    pub scene: Option<PathBuf>,
    /// Camera to render (repeatable; default: every camera of the scene, or a free view
    /// when it has none).
    #[arg(short, long = "camera")]
    pub cameras: Vec<String>,
    /// Image width and height in pixels (square); see --width/--height for others.
    #[arg(long, default_value_t = 640)]
    pub size: u32,
    /// Image width (overrides --size).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (overrides --size).
    #[arg(long)]
    pub height: Option<u32>,
    /// Quality preset.
    #[arg(long, value_enum, default_value_t = QualityArg::Paper)]
    pub quality: QualityArg,
    /// Also write depth (16-bit PNG preview, near = dark) and report its range in metres.
    #[arg(long)]
    pub depth: bool,
    /// Simulate this many physics steps from the initial state before rendering (with
    /// --video: the length of the clip; default 1000 steps = 2 s).
    #[arg(long, default_value_t = 0)]
    pub steps: usize,
    /// Write an H.264 video per camera (through ffmpeg) of the simulation over --steps,
    /// instead of still images.
    #[arg(long)]
    pub video: bool,
    /// Frames per second of --video (one frame per 1/fps of simulated time).
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    /// Output folder (default: <work-dir>/render).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Render a task's scene at its reset (robot at home) from the task's cameras; `all`:
    /// every task, its built-in scene next to the reference scene (when found) from the
    /// same camera, on one contact sheet.
    #[arg(long, conflicts_with = "scene")]
    pub task: Option<String>,
    /// With --task: a scene pack folder (e.g. the DexJoCo reference `xmls/`) instead of
    /// the built-in scenes; with --task all: the reference scenes to compare with
    /// (default: ../shared/dexjoco-upstream/xmls when present).
    #[arg(long, requires = "task")]
    pub scene_dir: Option<PathBuf>,
    /// With --task: a folder of task specs (`<task_id>.toml`) that replace the built-in
    /// ones of the same id or add tasks.
    #[arg(long, requires = "task")]
    pub tasks_dir: Option<PathBuf>,
}

/// `bench` subcommands.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Frames/s of offscreen rendering per scene, resolution and quality preset.
    Render(BenchRenderArgs),
    /// Episodes/s and MB/s of `ingest` on generated raw folders and MCAP files.
    Ingest(BenchIngestArgs),
    /// `convert` against lerobot's own dataset writer on the same episodes, and our
    /// peak memory for few vs many short episodes.
    Convert(BenchConvertArgs),
    /// `augment` (physics once per episode, parallel) against the reference approach
    /// (re-simulate and render every replay in one process), per resolution and preset.
    Augment(BenchAugmentArgs),
}

/// `bench augment` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench augment
  dexjoco-data bench augment --replays 10 --max-frames 300 --size 640 --preset paper
  dexjoco-data bench augment --jobs 16 datasets/demos

Each configuration runs three ways on the same episodes and seed:
  reference  re-simulate and render every replay, one after another, one thread
             (what the DexJoCo replay script does)
  ours x1    simulate each episode once, render every replay from it, one thread
  ours xN    the same with N worker threads (--jobs, default: all cores)
Outputs are written to a temporary folder and removed; the table goes to stdout and
<work-dir>/bench/augment.json.")]
pub struct BenchAugmentArgs {
    /// Episodes to replay (default: the sample demos in datasets/demos).
    pub inputs: Vec<PathBuf>,
    /// Replays per episode.
    #[arg(long, default_value_t = 2)]
    pub replays: usize,
    /// Only the first N frames of each episode (keeps the benchmark short).
    #[arg(long, default_value_t = 60)]
    pub max_frames: usize,
    /// Image sizes (square), comma-separated.
    #[arg(long = "size", value_delimiter = ',', default_values_t = [224, 640])]
    pub sizes: Vec<u32>,
    /// Quality presets, comma-separated.
    #[arg(long = "preset", value_enum, value_delimiter = ',',
          default_values_t = [QualityArg::Fast, QualityArg::Paper])]
    pub presets: Vec<QualityArg>,
    /// Skip the one-thread run of our approach.
    #[arg(long)]
    pub no_single_thread: bool,
}

/// `bench convert` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench convert
  dexjoco-data bench convert --episodes 50 --frames 120 --memory-episodes 100,1000

Needs the test venv (`scripts/setup.sh --python`, or DEXJOCO_PYTHON) for lerobot's writer
and /usr/bin/time for peak memory (maximum resident set size of each child process).")]
pub struct BenchConvertArgs {
    /// Generated click_mouse episodes converted by both tools.
    #[arg(long, default_value_t = 50)]
    pub episodes: usize,
    /// Frames per episode.
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Camera frame size (square; at least 64 for lerobot's AV1 encoder).
    #[arg(long, default_value_t = 96)]
    pub size: u32,
    /// Episode counts for our peak-memory runs (short episodes).
    #[arg(long, value_delimiter = ',', default_values_t = [100, 1000])]
    pub memory_episodes: Vec<usize>,
    /// Frames per episode in the peak-memory runs.
    #[arg(long, default_value_t = 10)]
    pub memory_frames: usize,
    /// Skip lerobot's writer (our side only).
    #[arg(long)]
    pub no_lerobot: bool,
}

/// `bench render` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench render
  dexjoco-data bench render --scene ../shared/dexjoco-upstream/xmls/arena_arm_hand_plant.xml --frames 50")]
pub struct BenchRenderArgs {
    /// Scenes to measure (repeatable; default: the built-in tabletop scene and, when
    /// present, the DexJoCo reference plant scene in ../shared/dexjoco-upstream).
    #[arg(long = "scene")]
    pub scenes: Vec<PathBuf>,
    /// Timed frames per row (after 3 warm-up frames).
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Square resolutions to measure.
    #[arg(long, value_delimiter = ',', default_value = "224,640")]
    pub sizes: Vec<u32>,
    /// Presets to measure (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub presets: Vec<QualityArg>,
    /// Camera to render (default: `front` when the scene has it, else the first camera).
    #[arg(long)]
    pub camera: Option<String>,
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
  dexjoco-data stats --dataset raw_demos/               # any folder of DexJoCo raw episodes
  dexjoco-data stats --dataset dexjoco-work/augment     # augment output: + replay success rates

Language evaluation input: a folder <config>/<task>_seed<s>/episode_XX_{success|failure}_{<digits>|no_password_input}/
as the DexJoCo evaluator writes it (instructions.csv at its root names each config's instruction
and expected answer), or a tidy .csv/.json with instruction, expected, seed, episode, output.
Writes <out>/language-eval/ (summary.md, language_eval.json, CSVs, heatmap.png/.svg) and
<out>/success-table/ (success_table.md/.tex/.csv/.json) and <out>/dataset/ (dataset_stats.json,
summary.md, norm_stats.json, plots; replay_success.md/.json when the folder holds an
augment_report.json); the summary goes to stdout.")]
pub struct StatsArgs {
    /// Language-generalization analysis (DexJoCo paper, appendix A) of an evaluation
    /// folder or a tidy .csv/.json file. Without a value: the example input shipped in
    /// datasets/examples/language-eval (made up, not results).
    #[arg(long, value_name = "INPUT", num_args = 0..=1)]
    pub language_eval: Option<Option<PathBuf>>,
    /// Success-rate table (mean ± std over seeds per task x regime x policy) of the
    /// evaluation runs under DIR. Without a value: the example runs shipped in
    /// datasets/examples/success-table (made up, not results).
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
}

/// `ingest` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data ingest recordings/                      # raw folders and *.mcap, recursively
  dexjoco-data ingest teleop.mcap ../raw/click_mouse/episode_000003
  dexjoco-data ingest old_demos/ --task pick_bucket    # folders whose path names no task
  dexjoco-data ingest recordings/ --force              # redo inputs already in the store

Good episodes land in the store (<work-dir>/ingest by default) in the DexJoCo raw layout,
<task>/episode_NNNNNN/{replay.zarr, videos/}; rejected inputs are copied under
quarantine/<id>/ with reason.json. manifest.json lists both, with every problem's file,
episode, field and frame. Re-running skips inputs already stored (ids are content
hashes). Exit code 3 when any input was rejected.")]
pub struct IngestArgs {
    /// MCAP files and folders; folders are searched recursively for DexJoCo raw episode
    /// folders (holding replay.zarr) and *.mcap files.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The episode store to add to (default: <work-dir>/ingest).
    #[arg(long, env = "DEXJOCO_STORE")]
    pub store: Option<PathBuf>,
    /// Re-read and rewrite inputs already in the store (they keep their folders and ids).
    #[arg(long)]
    pub force: bool,
    /// Task of raw folders whose path does not name one (<task>/episode_N or <task>_demo_...).
    #[arg(long)]
    pub task: Option<String>,
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
  dexjoco-data export --to mcap store/click_mouse/episode_000002 --out logs/")]
pub struct ExportArgs {
    /// Output container.
    #[arg(long, value_enum)]
    pub to: ExportFormat,
    /// Episode folders, or stores (every landed episode) (default: <work-dir>/ingest).
    pub episodes: Vec<PathBuf>,
    /// Output folder (default: <work-dir>/export).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
}

/// `bench ingest` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench ingest
  dexjoco-data bench ingest --episodes 20 --frames 300")]
pub struct BenchIngestArgs {
    /// Generated episodes per input format (tasks cycle through all 11).
    #[arg(long, default_value_t = 100)]
    pub episodes: usize,
    /// Frames per episode.
    #[arg(long, default_value_t = 600)]
    pub frames: usize,
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
  dexjoco-data convert --input dexjoco-work/ingest --out datasets/click_mouse
  dexjoco-data convert --input raw/ --config ../shared/dexjoco-upstream/converter-configs/multi_task
  dexjoco-data convert --input raw/ --config selection.toml --reencode --video-codec h264
  dexjoco-data convert --input raw/ --overwrite --no-skip-static
  dexjoco-data convert --input raw/ --format diffusion-policy --videos --norm-stats

Input: an episode store (a folder with manifest.json, as `ingest` writes it: its landed
episodes) or any folder of DexJoCo raw episode folders (replay.zarr + videos/<camera>.mp4),
searched recursively. Without --input: <work-dir>/augment.

Videos are joined per camera by stream copy when the source codec fits (H.264, HEVC,
AV1 in yuv420p at the dataset's rate): no re-encode, and static leading frames are
skipped through the episodes' from_timestamp. Otherwise, or with --reencode, they are
encoded (AV1 by default).

--format diffusion-policy writes <out>/replay_buffer.zarr (data/action, data/state,
data/timestamp as float64, data/<camera> as uint8 frames, meta/episode_ends); --videos
also keeps <out>/videos/<episode>/<camera>.mp4 with videos/name_map.json.
--norm-stats writes openpi's <out>/norm_stats.json (state, actions: mean, std, q01, q99).

An episode that cannot be read, lacks what the selection asks for or does not fit the
dataset's layout is left out and named with its reason; the rest is written and the exit
code is 3. The dataset appears in <out> only when complete.")]
pub struct ConvertArgs {
    /// Episode store or folder of DexJoCo raw episodes (default: <work-dir>/augment).
    #[arg(short, long, env = "DEXJOCO_CONVERT_INPUT")]
    pub input: Option<PathBuf>,
    /// Output dataset folder (default: <work-dir>/convert/<format>).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ConvertFormatArg::LerobotV3)]
    pub format: ConvertFormatArg,
    /// Selection config: a TOML/YAML file, or a DexJoCo reference converter config
    /// folder (selected_data.yaml, slice_config.yaml, language_instructions.yaml).
    #[arg(short, long, env = "DEXJOCO_CONVERT_CONFIG")]
    pub config: Option<PathBuf>,
    /// Replace a non-empty output folder.
    #[arg(long)]
    pub overwrite: bool,
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
    /// Also write openpi's norm_stats.json into the dataset folder.
    #[arg(long)]
    pub norm_stats: bool,
    /// Action chunk length for --norm-stats (openpi's action_horizon).
    #[arg(long, default_value_t = 50, value_name = "FRAMES")]
    pub norm_stats_horizon: usize,
}

/// `augment` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data augment --replays 10                      # the sample demos, built-in scenes
  dexjoco-data augment --replays 10 --scene-dir ../shared/dexjoco-upstream/xmls
  dexjoco-data augment recordings/ --replays 5 --size 224 --quality fast
  dexjoco-data augment --replays 2 --camera handcam_rgb --keep-failed --out aug/
  dexjoco-data augment --replays 2 --camera front --depth --size 224  # + <camera>_depth.npz
  dexjoco-data augment --replays 10 --dynamics           # + mass/friction/stiffness per replay

Output: one DexJoCo raw folder per replay, <out>/<task>/<episode>__rNN/ (replay.zarr with
the recorded actions, recomputed state and action_rotvec; videos/third_person.mp4 plus one
video per --camera; with --depth videos/<camera>_depth.npz), augment_report.json / .md and
contact_sheet.png. A killed run resumes
where it stopped when run again; the same --seed gives the same output whatever --jobs is.
Inputs that cannot be replayed (unreadable, unknown task, missing field) are skipped and
listed; the rest of the batch goes on.
Exit code 3: some episodes were skipped or did not replay to success.")]
pub struct AugmentArgs {
    /// Raw episode folders, episode stores or MCAP files (default: the sample data in
    /// datasets/demos).
    pub inputs: Vec<PathBuf>,
    /// Randomized replays per episode.
    #[arg(long, default_value_t = 10)]
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
    /// Image width and height in pixels (224 is the small preset).
    #[arg(long, default_value_t = 640)]
    pub size: u32,
    /// Quality preset (paper = the reference's 8x multisampling).
    #[arg(long, value_enum, default_value_t = QualityArg::Paper)]
    pub quality: QualityArg,
    /// Keep replays whose task failed (flagged in the report).
    #[arg(long)]
    pub keep_failed: bool,
    /// A folder of task specs (`<task_id>.toml`) replacing the built-in ones of the same
    /// id, e.g. other --dynamics ranges or success thresholds.
    #[arg(long)]
    pub tasks_dir: Option<PathBuf>,
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
    /// Only the first N frames of each episode (a quick look; success needs the whole).
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// Output folder (default: <work-dir>/augment).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
}

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
    #[arg(long, default_value_t = 50)]
    pub count: usize,
    /// Poses sampled and scored.
    #[arg(long, default_value_t = 2000)]
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
}
