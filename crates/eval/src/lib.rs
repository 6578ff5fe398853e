//! The `eval` stage: evaluating a trained policy in the DexJoCo task environments through
//! openpi's websocket policy protocol, as the DexJoCo reference client
//! (`dexjoco_openpi_client/eval_dexjoco_openpi.py`) does, deterministic by default.
//!
//! - [`config`]: the task as the policy sees it (the reference's evaluation configs) and
//!   the run's options;
//! - [`wire`] and [`protocol`]: openpi's MessagePack-with-numpy messages over a websocket
//!   (tungstenite, rmpv), byte for byte as the reference client sends them, every wait
//!   for the server bounded by the deadline; [`decode`]: everything the server sends,
//!   decoded with bounds into validated chunks (the only reader of server bytes);
//! - [`observe`]: observations (images resized with padding as openpi does, proprio
//!   state, prompt); [`chunks`]: the reference's action-chunk buffer (alignment, expiry,
//!   blending with geodesic rotation interpolation) and the action conversions;
//! - `inference`: when a chunk is merged (a latency modelled in steps, or real time);
//!   `episode`: one episode's loop; `stage`: what a process's episodes share;
//! - [`run`]: a whole run (resets, resume, worker processes from `dexjoco-workers`,
//!   marker); `worker`: a worker process's side; [`output`]: the reference's output
//!   layout that `stats` reads, plus one record per episode.

pub mod chunks;
pub mod config;
pub mod decode;
mod episode;
mod error;
mod inference;
pub mod observe;
pub mod output;
pub mod protocol;
pub mod run;
mod stage;
pub mod wire;
mod worker;

pub use config::{ACTION_HORIZON, EvalConfig, EvalOptions, EvalTask, RANDOM_CAMERA};
pub use dexjoco_workers::WorkerProcesses;
pub use error::{EvalError, one_line};
pub use output::EpisodeRecord;
pub use run::{EvalSummary, Executor, evaluate, initial_states};
pub use stage::episode_seed;
pub use stage::run_spec;
pub use worker::serve_worker;
