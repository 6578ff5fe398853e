//! `dexjoco-data eval`'s arguments: the DexJoCo reference client's options, and ours.

use std::path::PathBuf;

use clap::Args;

use super::{QualityArg, TasksDirArgs, WorkerArgs, positive_seconds, seconds_or_zero};

/// `eval`.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  # the reference's way: a task config, a seed, 50 episodes, a server on localhost:8000
  dexjoco-data eval --config task-configs/rand_obj/click_mouse.yaml --seed 0
  dexjoco-data eval --config task-configs/rand_full/hammer_nail.yaml --rand-full --seed 1
  dexjoco-data eval --config task-configs/ipad_reasoning/1+1.yaml --seed 0   # pressed digits
  # no config: the task's own cameras and prompt; 4 environments, each with its connection
  dexjoco-data eval --task pinch_tongs --episodes 20 -j 4 --host gpu-node --port 8000
  # fast on a CPU: small renders, no videos, a latency of 4 steps
  dexjoco-data eval --task hammer_nail --render-size 224x224 --no-videos --latency-steps 4
  dexjoco-data stats --success-table dexjoco-work/eval     # the table of the runs

Protocol: openpi's websocket policy server (the server sends its metadata first; each
observation {<policy image keys>: uint8 224x224x3, state: float64 (23 or 46), prompt} is
answered with {actions: (horizon, 22 or 44)}: per arm xyz, rotation vector, 16 hand joints).
Chunks are aligned to the step of the observation they answer, expired actions dropped,
overlaps blended (geodesic for rotations), the pose held when the buffer is empty, and a
new chunk asked when fewer than --replan-ratio x 30 actions remain.

Deterministic by default: the chunk asked at step t is merged at step t + --latency-steps,
so the same seed and policy give the same rollouts on any machine. --real-time paces the
loop to 30 Hz and merges chunks when they arrive, as the reference client does.

Output (read by `stats --success-table` and `stats --language-eval` as it is):
  <output>/episode_XX_{success|failure}[_<digits>|_no_password_input]/
      <env image key>.mp4, episode.json (the record), replay.zarr (the rollout)
  <output>/success_rate_<n>_<episodes>.txt, eval_run.json
A killed run evaluates only the episodes missing when run again.
Exit codes: 1 when the server cannot be reached, stops answering or answers badly (the
episodes done are kept); 2 for bad options.")]
pub struct EvalArgs {
    /// A DexJoCo evaluation config (`env_name`, `camera_mapping`, `prompt`, `robot_type`,
    /// `password`), as the reference's task-configs/ give them.
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with = "task",
        required_unless_present = "task"
    )]
    pub config: Option<PathBuf>,
    /// A task id instead of a config: the policy sees the task's first camera as `base`
    /// (`random_camera` with --rand-full) and its wrist cameras, with the task's prompt.
    #[arg(long)]
    pub task: Option<String>,
    /// The prompt sent with every observation (default: the config's or the task's).
    #[arg(long)]
    pub prompt: Option<String>,
    /// Episodes to evaluate (at most 100000).
    #[arg(long, default_value_t = 50, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100_000))]
    pub episodes: usize,
    /// Visual randomization per episode: the first camera moved to a pose of the camera
    /// pool (`random_camera`), lights and the table texture (the paper's rand-full).
    #[arg(long)]
    pub rand_full: bool,
    /// Dynamics randomization per episode from the task spec (masses, friction, stiffness).
    #[arg(long)]
    pub randomize_dynamics: bool,
    /// The policy server's host (or a ws:// address).
    #[arg(long, default_value = "0.0.0.0")]
    pub host: String,
    /// The policy server's port.
    #[arg(long, default_value_t = 8000)]
    pub port: u16,
    /// Ask for a new chunk when fewer than this share of the 30-step horizon remains.
    #[arg(long, default_value_t = 0.8)]
    pub replan_ratio: f64,
    /// Pad a one-arm state to 46 values (for a policy trained on the multi-task merge).
    #[arg(long = "pad-state-dim46")]
    pub pad_state_dim46: bool,
    /// Name episode folders with the pressed iPad digits (default: for
    /// bimanual_unlock_ipad; `--record-pressed-digits false` turns it off).
    #[arg(long, value_name = "BOOL")]
    pub record_pressed_digits: Option<bool>,
    /// Steps between asking for a chunk and merging it: the modelled inference latency.
    #[arg(long, default_value_t = 0)]
    pub latency_steps: usize,
    /// Pace to 30 Hz and merge chunks when they arrive, as the reference client does
    /// (results then depend on the machine's and the server's speed).
    #[arg(long, conflicts_with = "latency_steps")]
    pub real_time: bool,
    /// End each episode after at most N steps instead of the task's cap (1000 to 1500):
    /// for smoke tests and benchmarks; success rates then differ from the reference's.
    /// Steps are counted as the task's own cap counts them, click_mouse's 30 warm-up steps
    /// included.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub step_cap: Option<u64>,
    /// Output folder (default: <work-dir>/eval/<task>[_rand_full]_seed<seed>, the
    /// reference's folder name).
    #[arg(long, alias = "out")]
    pub output: Option<PathBuf>,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Evaluate from these initial states instead of resets drawn from --seed: a folder
    /// of episodes (each one's state[0], in discovery order) or a JSON file
    /// {"initial_states": [[...], ...]}.
    #[arg(long, value_name = "PATH")]
    pub resets_from: Option<PathBuf>,
    /// Render cameras at WxH (default: 640x640, as the reference environments render);
    /// the policy receives them resized with padding to 224x224 either way.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub render_size: Option<(u32, u32)>,
    /// Rendering quality (paper: as the reference).
    #[arg(long, value_enum, default_value = "paper")]
    pub quality: QualityArg,
    /// Record no videos (cameras are then rendered only for observations).
    #[arg(long)]
    pub no_videos: bool,
    /// Add `dexjoco/initial_state`, `dexjoco/episode` and `dexjoco/step` to every
    /// observation, for oracle and privileged-information policies (real openpi policies
    /// drop keys they do not know).
    #[arg(long)]
    pub privileged_keys: bool,
    /// Add `environment_state` (float64) to every observation: each of the task's state
    /// objects' pose now, the targets its success derives from the reset, then the table
    /// offset dh, as `convert --environment-state`
    /// exports it (`observation.environment_state`) for state-based policies.
    #[arg(long)]
    pub environment_state: bool,
    /// The policy takes no camera: no image is sent and, with --no-videos, nothing is
    /// rendered (the episode runs at the simulator's speed).
    #[arg(long)]
    pub no_cameras: bool,
    /// Seconds each wait for the server may last, in wall-clock time whatever the server
    /// sends meanwhile: the connection, the websocket handshake, its metadata, and each
    /// answer (sending the observation included). Past it: exit 1 naming the wait.
    #[arg(long, default_value_t = 120.0, value_name = "SECONDS", value_parser = positive_seconds)]
    pub deadline: f64,
    /// Seconds to keep retrying a refused connection at the start (0: once).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS", value_parser = seconds_or_zero)]
    pub server_wait: f64,
    /// The folder of task specs.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
    /// Where the -j worker processes render.
    #[command(flatten)]
    pub workers: WorkerArgs,
}

/// `WxH`, both even, positive and at most the renderer's largest side (H.264 video).
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WxH (e.g. 224x224)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| *v > 0 && v % 2 == 0 && *v <= dexjoco_render::MAX_IMAGE_SIDE)
            .ok_or_else(|| {
                format!(
                    "'{v}' in '{s}' is not an even number of pixels from 2 to {}",
                    dexjoco_render::MAX_IMAGE_SIDE
                )
            })
    };
    Ok((parse(w)?, parse(h)?))
}

/// `eval-worker`: internal, started by `eval -j N` (JSON lines on stdin/stdout).
#[derive(Debug, Args)]
pub struct EvalWorkerArgs {}
