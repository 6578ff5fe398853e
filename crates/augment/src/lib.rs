//! Randomized, validated replays of demonstrations in MuJoCo.
//!
//! Each episode is restored from its recorded `state[0]` and every recorded action is
//! stepped with the DexJoCo controller. Visual randomization (third-person camera from a
//! pose pool, lights and headlight, table material) does not change physics, so the
//! episode is simulated once and every replay's views are rendered from that one
//! trajectory, each replay streaming its frames to its own encoder. Each replay gets its
//! own seed derived from (global seed, episode id, replay index).
//!
//! Modules by job: `inputs` (episodes and their specs, the unreadable ones skipped),
//! `assets` (a task's scene, camera pool and table looks), `fingerprint` (the settings
//! that decide an output's bytes), `physics` (the replay simulated once: success,
//! deviation, `--extend-steps`), `plan` (shards, resume, units), `render` (a unit of
//! replays drawn from one simulation), `profile` (where a frame's time goes), `worker`
//! (units on threads or worker processes, first-frame deadlines), `staging` (replay
//! folders staged and renamed whole; the records of dropped replays), `checks` (the render
//! checks of every frame and stored array, and their test hook), `report` (report and
//! contact sheet), `run` (the orchestration), `compare` (light against full geometry);
//! `camera_pool` builds camera pools; the randomization itself (`randomize`,
//! `dynamics`) lives in `dexjoco-sim`, shared with `eval`.

mod assets;
mod camera_pool;
mod checks;
mod config;
mod dry_run;
mod error;
mod fingerprint;
mod geometry_difference;
mod inputs;
mod physics;
mod plan;
mod profile;
mod provenance;
mod render;
mod report;
mod run;
mod staging;
mod warp;
mod worker;

pub use camera_pool::{BuiltPool, PoolOptions, ScoredPose, build_pool, occlusion};
pub use checks::inject::RENDER_DEFECT_ENV;
pub use checks::{BLANK_SHARE, BLANK_TOLERANCE, FROZEN_HAND_RAD, FROZEN_MIN_FRAMES, FROZEN_TCP_M};
pub use config::{
    AugmentConfig, CONTACT_SHEET, DEFAULT_EXTEND_STEPS, DEFAULT_REPLAYS, REPORT_JSON, REPORT_MD,
    SETTINGS_FILE, Shard, THIRD_PERSON, VideoEncoding, replay_name,
};
pub use dexjoco_render::randomize::{
    CameraPool, CameraPose, LightSample, TableLibrary, VisualSample, apply_visuals, builtin_pool,
    replay_seed,
};
pub use dexjoco_sim::dynamics::{
    DynamicsValue, apply_dynamics, dynamics_seed, read_dynamics, sample_dynamics,
};
pub use dry_run::{DryRun, PlannedTask, dry_run, render_only};
pub use error::AugmentError;
pub use fingerprint::{OutputSettings, TaskInputs};
pub use geometry_difference::{GeometryDifference, geometry_difference};
pub use inputs::SkippedInput;
pub use profile::StageTimes;
pub use provenance::{Provenance, ToolVersions, current_versions, this_machine};
pub use report::{
    AugmentReport, AugmentRun, EpisodeOutcome, FailedUnit, FlaggedReplay, MadeOn, ReplayRecord,
};
pub use run::{augment, augment_with};
pub use worker::{
    DEFAULT_FIRST_FRAME_TIMEOUT, Executor, FAULT_ENV, STALL_ENV, WorkerProcesses, serve_worker,
    share_llvmpipe_threads,
};
