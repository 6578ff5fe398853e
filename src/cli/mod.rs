//! Every clap definition of the `dexjoco-data` command line: this file holds the
//! top level (global options, subcommands, shared value types); `stages` the pipeline
//! commands (ingest, export, scripted, augment, cameras, convert, stats); `generate` the
//! demonstration generator; `dataset` the dataset management; `eval` the
//! policy evaluation; `tools` doctor, render and bench. Commands (`src/commands/`) turn these into settings
//! (`src/settings/`); neither is imported here, so the modules form no circle.

mod dataset;
mod eval;
mod generate;
mod stages;
mod tools;

pub use dataset::*;
pub use eval::*;
pub use generate::*;
pub use stages::*;
pub use tools::*;

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
  dexjoco-data scripted --task pinch_tongs --episodes 5 --out demos/
  dexjoco-data generate --task click_mouse --count 20   # new demos at new object poses
  dexjoco-data augment --replays 10           # randomized replays of the sample demos
  dexjoco-data convert                        # augment output -> LeRobot v3.0
  dexjoco-data convert dexjoco-work/ingest --out ds/ --overwrite
  dexjoco-data dataset filter --where 'success == true'   # keep the successful episodes
  dexjoco-data dataset split --splits train=0.9,val=0.1   # seeded, stratified per task
  dexjoco-data stats --language-eval
  dexjoco-data eval --task click_mouse --episodes 10 --port 8000   # a policy served by openpi

Stages chain through the work folder (default ./dexjoco-work, one subfolder per stage),
so `augment`, `convert` and `stats` need no paths; every path can be overridden.
The same words everywhere: inputs are positional, --out is the output folder,
--overwrite replaces what a command wrote before, -c/--camera a camera, --size and
--quality the rendering.

Exit codes (the same for the same error in every command):
  0  success
  1  the command failed: an input is missing or unreadable, the output is in use by
     another run or may not be replaced, writing failed, rendering is unavailable
  2  usage error: unknown flag, bad value (0 replays, a negative tolerance...), unknown task
  3  finished, but some inputs (episodes, replays, tasks) were left out; each is named";

/// Data pipeline for DexJoCo dexterous-manipulation demonstrations: ingest teleop
/// episodes, replay them in MuJoCo under randomization, convert to LeRobot / Diffusion
/// Policy datasets, and analyse results.
#[derive(Debug, Parser)]
#[command(
    name = "dexjoco-data",
    version,
    after_help = AFTER_HELP,
    propagate_version = true,
    args_override_self = true
)]
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
    /// Workers (default: all cores): threads, and for `augment` worker processes (default
    /// on a GPU node: at most 8 per GPU, spread over the GPUs); for `eval`, environments
    /// (default 1). Results do not depend on it.
    #[arg(short, long, global = true, env = "DEXJOCO_JOBS",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub jobs: Option<usize>,
    /// Seed of every random choice; the same seed and inputs give identical outputs.
    #[arg(long, global = true, env = "DEXJOCO_SEED", default_value_t = 0)]
    pub seed: u64,
    /// Work folder: each stage writes its own subfolder (ingest/, generate/, augment/,
    /// convert/, stats/, render/, bench/) and reads the previous stage's.
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
    /// Size this machine: rendering, ingest and augment throughput (comparisons with
    /// other tools are in the developer binary, `dexjoco-dev`).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Read raw teleop episodes (MCAP logs, DexJoCo raw folders), validate and store them.
    Ingest(IngestArgs),
    /// Write stored episodes in another container (MCAP teleop logs).
    Export(ExportArgs),
    /// Replay each episode under sampled camera/light/texture randomization; keep successes.
    Augment(AugmentArgs),
    /// A worker process of `augment` (started by it; speaks JSON lines on stdin/stdout).
    #[command(hide = true)]
    AugmentWorker(AugmentWorkerArgs),
    /// Plan scripted demonstrations of a task from random resets and write the
    /// successful ones in the DexJoCo raw layout.
    Scripted(ScriptedArgs),
    /// New demonstrations at new object poses from a few (MimicGen-style): source
    /// segments per subtask carried to each new reset's object poses, run in MuJoCo, kept
    /// when the task succeeds.
    Generate(GenerateArgs),
    /// Build a third-person camera pose pool for a task: sample poses on a sphere, keep the
    /// least occluded (the DexJoCo paper's way); `augment --camera-pool` reads it.
    Cameras(CamerasArgs),
    /// Convert episodes to LeRobot v3.0 / v2.1 or a Diffusion Policy Zarr replay buffer.
    Convert(ConvertArgs),
    /// Dataset statistics, success tables and the language-generalization analysis.
    Stats(StatsArgs),
    /// Evaluate a trained policy in the task environments through openpi's websocket
    /// policy server, as the DexJoCo reference client does (deterministic by default).
    Eval(EvalArgs),
    /// A worker process of `eval` (started by it).
    #[command(hide = true)]
    EvalWorker(EvalWorkerArgs),
    /// Manage any LeRobot v3.0 dataset: info, filter, split, merge, remove or rename
    /// features (each a new dataset; the source never changed), exact statistics, v2.1.
    #[command(subcommand)]
    Dataset(DatasetCommand),
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

/// Which renderer draws the frames (`augment`, `bench augment`).
#[derive(Debug, Clone, Args)]
pub struct RendererArgs {
    /// opengl: MuJoCo's own renderer through EGL (the reference's look); warp: MuJoCo
    /// Warp's batch ray tracer on a CUDA GPU (or Warp's CPU device), in a Python worker
    /// per render worker (`scripts/setup.sh --warp`, or `pip install 'dexjoco-data[warp]'`;
    /// `doctor` says whether it is usable).
    #[arg(long, value_enum, default_value_t = RendererArg::Opengl)]
    pub renderer: RendererArg,
    /// The Warp renderer's options.
    #[command(flatten)]
    pub warp: WarpArgs,
}

/// How the Warp renderer's worker runs (`--renderer warp`, `bench fidelity`).
#[derive(Debug, Clone, Args)]
pub struct WarpArgs {
    /// The Warp device: auto (the first CUDA GPU, else the CPU), cpu or cuda:N.
    #[arg(long, default_value = "auto", value_name = "DEVICE")]
    pub warp_device: String,
    /// Images the Warp renderer draws per call (frames x replays; default 2048 on a GPU,
    /// 16 on the CPU). The bytes do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub warp_batch: Option<usize>,
    /// Rays per pixel and axis of the Warp renderer (anti-aliasing: 2 = 4 rays per pixel;
    /// default: 2 with --quality paper, which multisamples, else 1).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4))]
    pub warp_supersample: Option<u32>,
    /// The Python of the Warp renderer's worker (default: $DEXJOCO_WARP_PYTHON, else the
    /// first with MuJoCo Warp of: the Python beside this program, $VIRTUAL_ENV's,
    /// setup.sh --warp's venv).
    #[arg(long, value_name = "PYTHON")]
    pub warp_python: Option<PathBuf>,
}

impl WarpArgs {
    /// The worker's options.
    pub fn options(self) -> dexjoco_render::warp::WarpOptions {
        let Self {
            warp_device,
            warp_batch,
            warp_supersample,
            warp_python,
        } = self;
        dexjoco_render::warp::WarpOptions {
            python: warp_python,
            device: warp_device,
            worlds: warp_batch,
            supersample: warp_supersample,
        }
    }
}

/// `--renderer`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RendererArg {
    /// MuJoCo's OpenGL renderer (EGL).
    Opengl,
    /// MuJoCo Warp's batch ray tracer.
    Warp,
}

impl RendererArgs {
    /// The renderer and the Warp worker's options.
    pub fn resolve(
        self,
    ) -> (
        dexjoco_render::RendererKind,
        dexjoco_render::warp::WarpOptions,
    ) {
        let Self { renderer, warp } = self;
        let kind = match renderer {
            RendererArg::Opengl => dexjoco_render::RendererKind::Opengl,
            RendererArg::Warp => dexjoco_render::RendererKind::Warp,
        };
        (kind, warp.options())
    }
}

/// Where worker processes render (`augment`, `eval -j N`): an EGL device each, and the
/// first-frame deadline.
#[derive(Debug, Clone, Args)]
pub struct WorkerArgs {
    /// EGL devices (indices as `doctor` lists them) assigned to worker processes
    /// round-robin, e.g. 0,1,2,3 on a node with four GPUs (default there: all of them).
    #[arg(
        long,
        value_delimiter = ',',
        env = "DEXJOCO_EGL_DEVICES",
        value_name = "LIST"
    )]
    pub egl_devices: Vec<usize>,
    /// The workers' first-frame deadline.
    #[command(flatten)]
    pub deadline: FirstFrameArgs,
}

/// The worker processes' first-frame deadline (`augment`, `eval`, `bench augment`).
#[derive(Debug, Clone, Args)]
pub struct FirstFrameArgs {
    /// Seconds a worker process may take to draw the first frame of each renderer it
    /// opens; one that has drawn nothing by then (a hung EGL driver) is killed and named,
    /// and its work goes to the other workers.
    #[arg(
        long,
        default_value_t = dexjoco_augment::DEFAULT_FIRST_FRAME_TIMEOUT.as_secs_f64(),
        env = "DEXJOCO_FIRST_FRAME_TIMEOUT",
        value_name = "SECONDS",
        value_parser = positive_seconds
    )]
    pub first_frame_timeout: f64,
}

impl FirstFrameArgs {
    /// The deadline.
    pub fn duration(&self) -> std::time::Duration {
        std::time::Duration::from_secs_f64(self.first_frame_timeout)
    }
}

/// The tasks a command knows, the same option for every command that reads tasks.
#[derive(Debug, Clone, Default, Args)]
pub struct TasksDirArgs {
    /// A folder of task specs (`<task_id>.toml`, as in schemas/tasks/) that replace the
    /// built-in ones of the same id or add tasks; give it to every command that reads
    /// episodes of those tasks.
    #[arg(long, value_name = "DIR")]
    pub tasks_dir: Option<PathBuf>,
}

/// A positive, finite number of seconds.
fn positive_seconds(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0 && *v <= MAX_SECONDS)
        .ok_or_else(|| format!("'{s}' is not a number of seconds above 0 and at most a year"))
}

/// A number of seconds from 0 to a year.
fn seconds_or_zero(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| (0.0..=MAX_SECONDS).contains(v))
        .ok_or_else(|| format!("'{s}' is not a number of seconds from 0 to a year"))
}

/// The longest time a flag may give (a year): longer ones would overflow a clock.
pub const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;

/// The renderer's meshes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GeometryArg {
    /// The meshes as the scene has them (the reference look).
    Full,
    /// Meshes simplified until a surface moves by at most half a pixel (seen from 1 m):
    /// far fewer triangles for a CPU rasterizer; physics and collision meshes untouched.
    Light,
}

impl GeometryArg {
    /// The renderer's setting.
    pub fn geometry(self) -> dexjoco_render::Geometry {
        match self {
            Self::Full => dexjoco_render::Geometry::Full,
            Self::Light => dexjoco_render::Geometry::Light,
        }
    }
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
