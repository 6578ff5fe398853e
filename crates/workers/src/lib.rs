//! Worker processes for the stages that render (`augment`, `eval`): each with its own
//! MuJoCo model and EGL renderer, so work scales over cores and GPUs, started, watched
//! and ended in one place.
//!
//! - [`protocol`]: JSON lines over the workers' stdin/stdout: the parent sends a `hello`
//!   (the stage's configuration), then one `job` at a time; the worker says that its
//!   renderer is opening, on which EGL device, that it drew its first frame, how far the
//!   job has come, and how it ended (a failure says whether it stops the whole run);
//! - [`WorkerProcesses`]: how workers start (program, count, an EGL device each, round
//!   robin, and their share of llvmpipe's threads), the first-frame and silence
//!   deadlines, and a renderer probe that fails a machine that cannot render before any
//!   work is spent;
//! - [`WorkerPool`]: workers started ahead (they load while the parent prepares); every
//!   worker is killed and reaped when dropped, so no error path leaves one behind;
//! - [`run_jobs`]: the schedule: jobs heaviest first; a worker that dies mid-job is
//!   replaced and the job retried once (its leftovers cleared by the stage); a worker that
//!   cannot render retires its slot; a run-wide failure stops the run and kills the other
//!   workers;
//! - [`serve`]: the worker's side.

pub mod protocol;
pub mod serve;

mod error;
mod process;
mod schedule;
mod spec;

pub use error::PoolError;
pub use process::WorkerPool;
pub use protocol::{Failure, FromWorker, SLOT_ENV, ToWorker};
pub use schedule::{JobResult, JobSet, WARP_WORDS, run_jobs};
pub use spec::{DEFAULT_FIRST_FRAME_TIMEOUT, WorkerProcesses, probe_renderer};
