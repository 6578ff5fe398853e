//! The `dexjoco-dev` command line: the comparisons against other tools and the sweeps
//! that developers run (the user binary keeps `bench render`, `bench ingest` and `bench
//! augment`, which size a user's own machine).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use dexjoco_cli::cli::{GlobalArgs, QualityArg, WarpArgs, image_side};

const AFTER_HELP: &str = "\
Examples:
  dexjoco-dev bench convert                 # ours vs lerobot's writer and the reference converter
  dexjoco-dev bench generate                # attempts/s vs the same loop in Python
  dexjoco-dev bench fidelity --warp-device cpu   # Warp vs OpenGL images per task and camera

Each writes its table to stdout and <work-dir>/bench/<name>.json; docs/contributing.md says
what each measures and docs/performance.md holds the results.";

/// Developer tools of dexjoco-data: benchmarks against other tools and renderer sweeps.
#[derive(Debug, Parser)]
#[command(
    name = "dexjoco-dev",
    version,
    after_help = AFTER_HELP,
    propagate_version = true,
    args_override_self = true
)]
pub struct DevCli {
    /// Options every subcommand takes (as `dexjoco-data`'s).
    #[command(flatten)]
    pub global: GlobalArgs,
    /// The subcommand.
    #[command(subcommand)]
    pub command: DevCommand,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum DevCommand {
    /// Measurements against other tools.
    #[command(subcommand)]
    Bench(DevBenchCommand),
}

/// `bench` subcommands.
#[derive(Debug, Subcommand)]
pub enum DevBenchCommand {
    /// `convert` against lerobot's own dataset writer and the DexJoCo reference converter
    /// on the same episodes, and our peak memory for few vs many short episodes.
    Convert(BenchConvertArgs),
    /// Generation attempts per second on one core, against the same loop in Python on the
    /// DexJoCo reference environments.
    Generate(BenchGenerateArgs),
    /// The Warp batch renderer against MuJoCo's OpenGL one on each task's scene: PSNR and
    /// SSIM per task and camera, side-by-side pictures.
    Fidelity(BenchFidelityArgs),
}

/// `bench convert` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-dev bench convert
  dexjoco-dev bench convert --episodes 50 --frames 120 --memory-episodes 100,1000

Needs the test venv (`scripts/setup.sh --python`, or DEXJOCO_PYTHON) for lerobot's writer
and /usr/bin/time for peak memory (maximum resident set size of each child process: for
the reference converter, the largest of its processes).

The DexJoCo reference converter (dexjoco-dc-single-lerobot and dexjoco-dc-single-zarr)
runs from its code in place: $DEXJOCO_THIRD_PARTY, else ../shared/third_party beside the
checkout, with Diffusion Policy from $DEXJOCO_DIFFUSION_POLICY or the checkout's .deps;
beside it, our --format diffusion-policy --videos. When that code is absent the output
says so and those rows are skipped.")]
pub struct BenchConvertArgs {
    /// Generated click_mouse episodes converted by both tools.
    #[arg(long, default_value_t = 50)]
    pub episodes: usize,
    /// Frames per episode.
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Camera frame size (square; at least 64 for lerobot's AV1 encoder).
    #[arg(long, default_value_t = 96, value_parser = image_side())]
    pub size: u32,
    /// Episode counts for our peak-memory runs (short episodes).
    #[arg(long, value_delimiter = ',', default_values_t = [100, 1000])]
    pub memory_episodes: Vec<usize>,
    /// Frames per episode in the peak-memory runs.
    #[arg(long, default_value_t = 10)]
    pub memory_frames: usize,
    /// Skip lerobot's writer.
    #[arg(long)]
    pub no_lerobot: bool,
    /// Skip the DexJoCo reference converter.
    #[arg(long)]
    pub no_reference: bool,
    /// Random items read (lerobot 0.6.1's LeRobotDataset, torchcodec and pyav) from our
    /// LeRobot v3.0 dataset and the reference converter's, timed one by one as a training
    /// data loader reads them; 0 skips the read timing.
    #[arg(long, default_value_t = 100, value_name = "N")]
    pub read_items: usize,
}

/// `bench generate` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-dev bench generate
  dexjoco-dev bench generate --task hammer_nail --attempts 20 --sources 5

Per task, on the DexJoCo reference scenes: scripted plans (`scripted --seed 1000`'s first
resets) are the sources; attempts from --seed's resets run one after another on one core,
ours in this process; then the same attempts, with the same source segment per subtask,
in Python on the reference environments (tests/python/generate_loop.py: MuJoCo's Python
bindings, the reference controller and task logic; it does not check the subtasks' ends,
so it never waits for one). Both report attempts, steps and successes; the ratio is of
seconds per step. Single-arm tasks only (the Python loop runs the arm's subtasks in
order).

Needs the reference venv (scripts/setup.sh --python; $DEXJOCO_REFERENCE_PYTHON or the
checkout's .deps/reference-python-path) and the reference code ($DEXJOCO_THIRD_PARTY,
else ../shared/third_party beside the checkout); without them the Python rows are
skipped and the output says why. The table goes to stdout and
<work-dir>/bench/generate.json.")]
pub struct BenchGenerateArgs {
    /// Tasks (single-arm), e.g. click_mouse,pick_bucket.
    #[arg(long = "task", value_delimiter = ',', default_values_t = ["click_mouse".to_owned(), "pick_bucket".to_owned()])]
    pub tasks: Vec<String>,
    /// Attempts per task.
    #[arg(long, default_value_t = 10,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000))]
    pub attempts: usize,
    /// Scripted source plans per task.
    #[arg(long, default_value_t = 3,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
    pub sources: usize,
    /// Skip the Python loop.
    #[arg(long)]
    pub no_reference: bool,
}

/// `bench fidelity` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-dev bench fidelity                                 # the 11 reference scenes (or built-in)
  dexjoco-dev bench fidelity --task hammer_nail --views 8 --size 640 --quality paper
  dexjoco-dev bench fidelity --warp-supersample 2            # anti-aliased Warp images

Each task's scene at its reset, seen from --views randomized third-person views (camera
pose, lights, table look as augment samples them) and from the task's cameras, is rendered
by MuJoCo's OpenGL renderer and by the Warp ray tracer. The table gives PSNR (dB, over RGB)
and SSIM (luma, 11x11 Gaussian window) per task and camera; <work-dir>/bench/fidelity/ holds
fidelity.json, <task>.png (OpenGL | Warp | difference x4 per view) and sheet.png.")]
pub struct BenchFidelityArgs {
    /// Tasks (repeatable; default: all 11).
    #[arg(long = "task")]
    pub tasks: Vec<String>,
    /// Scene pack folder (default: the DexJoCo reference scenes when found, else the
    /// built-in scenes).
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Image size (square).
    #[arg(long, default_value_t = 224, value_parser = image_side())]
    pub size: u32,
    /// Quality preset (shadows, multisampling).
    #[arg(long, value_enum, default_value_t = QualityArg::Fast)]
    pub quality: QualityArg,
    /// Randomized third-person views per task.
    #[arg(long, default_value_t = 4,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub views: usize,
    /// The Warp renderer's options.
    #[command(flatten)]
    pub warp: WarpArgs,
}
