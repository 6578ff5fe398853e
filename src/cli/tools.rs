//! Arguments of the tools around the pipeline: doctor, render, bench.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use super::{FirstFrameArgs, GeometryArg, QualityArg, RendererArgs, TasksDirArgs};

/// `doctor` options.
#[derive(Debug, Args)]
pub struct DoctorArgs {
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
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
    #[arg(long, default_value_t = 640, value_parser = image_side())]
    pub size: u32,
    /// Image width (overrides --size).
    #[arg(long, value_parser = image_side())]
    pub width: Option<u32>,
    /// Image height (overrides --size).
    #[arg(long, value_parser = image_side())]
    pub height: Option<u32>,
    /// Quality preset.
    #[arg(long, value_enum, default_value_t = QualityArg::Paper)]
    pub quality: QualityArg,
    /// The renderer's meshes: full, or light (simplified to half a pixel's error).
    #[arg(long, value_enum, default_value_t = GeometryArg::Full)]
    pub geometry: GeometryArg,
    /// Also write depth (16-bit PNG preview, near = dark) and report its range in metres.
    #[arg(long)]
    pub depth: bool,
    /// Simulate this many physics steps from the initial state before rendering (with
    /// --video: the length of the clip; default 1000 steps = 2 s).
    #[arg(long, default_value_t = 0)]
    pub steps: usize,
    /// Write an H.264 video per camera (through ffmpeg) of the simulation over --steps,
    /// instead of still images.
    #[arg(long, conflicts_with = "task")]
    pub video: bool,
    /// Frames per second of --video (one frame per 1/fps of simulated time; default 30).
    #[arg(long, value_parser = frame_rate(), requires = "video", conflicts_with = "task")]
    pub fps: Option<u32>,
    /// Output folder (default: <work-dir>/render).
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Replace files of the same names already in the output folder.
    #[arg(long)]
    pub overwrite: bool,
    /// Render a task's scene at its reset (robot at home) from the task's cameras; `all`:
    /// every task, its built-in scene next to the reference scene (when found) from the
    /// same camera, on one contact sheet (a task that fails to render is a marked tile,
    /// named on stderr, and the exit code is 3).
    #[arg(long, conflicts_with = "scene")]
    pub task: Option<String>,
    /// With --task: a scene pack folder (e.g. the DexJoCo reference `xmls/`) instead of
    /// the built-in scenes; with --task all: the reference scenes to compare with
    /// (default: ../shared/dexjoco-upstream/xmls when present).
    #[arg(long, requires = "task")]
    pub scene_dir: Option<PathBuf>,
    /// The known tasks (with --task).
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}

/// `bench` subcommands.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Frames/s of offscreen rendering per scene, resolution and quality preset.
    Render(BenchRenderArgs),
    /// Episodes/s and MB/s of `ingest` on generated raw folders and MCAP files.
    Ingest(BenchIngestArgs),
    /// Frames/s of `augment` on this machine with 1 and N worker processes (to choose -j,
    /// the size and the preset), beside the reference approach (re-simulate and render
    /// every replay in one process) and the render-only limit of N processes.
    Augment(BenchAugmentArgs),
    /// One process of `bench augment`'s render-only limit (started by it).
    #[command(hide = true)]
    RenderLimit(BenchRenderLimitArgs),
}

/// `bench augment` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench augment
  dexjoco-data -j 2 bench augment hammer.raw/ --scene-dir ../shared/dexjoco-upstream/xmls \\
      --replays 4 --size 224 --quality no-msaa-no-shadows
  dexjoco-data -j 16 bench augment data/ --size 224,640 --quality fast,paper --max-frames 300
  dexjoco-data bench augment --workers 1,4,8,16 --no-reference --limit-frames 0 --max-frames 0

Each configuration (size x quality) runs, on the same episodes and seed:
  reference        re-simulate and render every replay, one after another, in one process
                   (what the DexJoCo replay script does)
  ours, 1 worker   one worker process: each episode simulated once, every replay rendered
                   from it, streamed to ffmpeg
  ours, N workers  the same with -j N worker processes (default: all cores; --workers
                   gives several counts)
  render-only      N processes drawing the same views with no physics and no encoding,
                   started together: the limit augment can approach on this machine
A second table says where a frame's time goes in each run: physics, scene update,
rasterization (until glFinish), pixel read-back, x264 encoding (CPU seconds of the
encoder processes) and the wait to hand frames to them, in milliseconds per frame and as
shares, so the bottleneck of this machine is plain. Outputs are written to a temporary
folder and removed; the tables go to stdout and <work-dir>/bench/augment.json.")]
pub struct BenchAugmentArgs {
    /// Episodes to replay (default: the sample demos in datasets/demos).
    pub inputs: Vec<PathBuf>,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Replays per episode.
    #[arg(long, default_value_t = 4,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000))]
    pub replays: usize,
    /// Only the first N frames of each episode (0: whole episodes).
    #[arg(long, default_value_t = 120)]
    pub max_frames: usize,
    /// Image sizes (square), comma-separated.
    #[arg(long = "size", alias = "sizes", value_delimiter = ',', default_values_t = [224],
          value_parser = image_side())]
    pub sizes: Vec<u32>,
    /// Quality presets, comma-separated.
    #[arg(long = "quality", alias = "preset", value_enum, value_delimiter = ',',
          default_values_t = [QualityArg::NoMsaaNoShadows])]
    pub qualities: Vec<QualityArg>,
    /// Skip the reference approach.
    #[arg(long)]
    pub no_reference: bool,
    /// Frames per process of the render-only limit (0 skips it).
    #[arg(long, default_value_t = 300)]
    pub limit_frames: usize,
    /// Worker-process counts of our runs, comma-separated (default: 1 and -j), e.g.
    /// 1,4,8,16 on a GPU node.
    #[arg(long, value_delimiter = ',', value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub workers: Vec<usize>,
    /// The renderer's meshes, comma-separated: full, light. With both, the light runs
    /// also report their image difference to the full render (PSNR, SSIM over a replay).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [GeometryArg::Full])]
    pub geometry: Vec<GeometryArg>,
    /// Our runs use threads of this one process (each with its own EGL context) instead
    /// of worker processes, to compare the two.
    #[arg(long)]
    pub threads: bool,
    /// The workers' first-frame deadline (as `augment`'s).
    #[command(flatten)]
    pub deadline: FirstFrameArgs,
    /// The renderer of our runs (as `augment`'s; with warp the table adds its split).
    #[command(flatten)]
    pub renderer: RendererArgs,
}

/// `bench render-limit`: internal, one process of the render-only limit.
#[derive(Debug, Args)]
pub struct BenchRenderLimitArgs {
    /// Episode whose scene and views are drawn.
    pub input: PathBuf,
    /// Scene pack folder.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Image size (square).
    #[arg(long, value_parser = image_side())]
    pub size: u32,
    /// Quality preset.
    #[arg(long, value_enum)]
    pub quality: QualityArg,
    /// Timed frames.
    #[arg(long)]
    pub frames: usize,
    /// Replays whose sampled views are cycled.
    #[arg(long)]
    pub replays: usize,
    /// Only the first N frames of the episode's trajectory (0: all of it).
    #[arg(long, default_value_t = 0)]
    pub max_frames: usize,
    /// The renderer's meshes.
    #[arg(long, value_enum, default_value_t = GeometryArg::Full)]
    pub geometry: GeometryArg,
}

/// `bench render` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench render
  dexjoco-data bench render --scene ../shared/dexjoco-upstream/xmls/arena_arm_hand_plant.xml --frames 50
  dexjoco-data bench render --size 224 --quality fast,paper --camera front")]
pub struct BenchRenderArgs {
    /// Scenes to measure (repeatable; default: the built-in tabletop scene and, when
    /// present, the DexJoCo reference plant scene in ../shared/dexjoco-upstream).
    #[arg(long = "scene")]
    pub scenes: Vec<PathBuf>,
    /// Timed frames per row (after 3 warm-up frames).
    #[arg(long, default_value_t = 30,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub frames: usize,
    /// Square resolutions to measure, comma-separated.
    #[arg(long = "size", alias = "sizes", value_delimiter = ',', default_value = "224,640",
          value_parser = image_side())]
    pub sizes: Vec<u32>,
    /// Presets to measure, comma-separated (default: all).
    #[arg(long = "quality", alias = "presets", value_enum, value_delimiter = ',')]
    pub presets: Vec<QualityArg>,
    /// Camera to render (default: `front` when the scene has it, else the first camera).
    #[arg(short, long)]
    pub camera: Option<String>,
    /// The renderer's meshes, comma-separated: full, light.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [GeometryArg::Full])]
    pub geometry: Vec<GeometryArg>,
}

/// `bench ingest` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data bench ingest
  dexjoco-data bench ingest --episodes 20 --frames 300")]
pub struct BenchIngestArgs {
    /// Generated episodes per input format (tasks cycle through all 11).
    #[arg(long, default_value_t = 100,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub episodes: usize,
    /// Frames per episode.
    #[arg(long, default_value_t = 600,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub frames: usize,
}

/// An image side in pixels: 1 to the renderer's largest ([`dexjoco_render::MAX_IMAGE_SIDE`]).
pub fn image_side() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new()
        .range(1..=u64::from(dexjoco_render::MAX_IMAGE_SIDE))
}

/// A frame rate ffmpeg takes: 1 to 2^31 - 1 frames per second.
pub fn frame_rate() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new().range(1..=i32::MAX as u64)
}
