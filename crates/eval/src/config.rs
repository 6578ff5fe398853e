//! What one evaluation run is: the task and how the policy sees it (the DexJoCo
//! evaluation config: `env_name`, `camera_mapping`, `prompt`, `robot_type`, `password`,
//! as `../task-configs/{rand_obj,rand_full,ipad_reasoning,multi_task}/*.yaml` of the
//! reference give it), and the run's options.

use std::path::{Path, PathBuf};

use dexjoco_core::{ArmSetup, TaskSpec};
use serde::{Deserialize, Serialize};

use crate::error::EvalError;

/// The env image key of the randomized third-person camera (`--rand-full`): the task's
/// first camera (`front`, or `ego` for two arms) moved to a pose drawn from the pool.
pub const RANDOM_CAMERA: &str = "random_camera";

/// Steps of the action horizon a policy is trained on (the reference client's fixed 30).
pub const ACTION_HORIZON: usize = 30;

/// The size the reference environments render their cameras at (`GymRenderingSpec`:
/// 640x640, which they also set as the model's offscreen size).
pub const REFERENCE_RENDER_SIZE: (u32, u32) = (640, 640);

/// The side of the square images a policy receives (openpi's `resize_with_pad` to 224).
pub const POLICY_IMAGE: u32 = 224;

/// How the policy sees one task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalTask {
    /// The task id (`env_name`).
    pub task: String,
    /// Policy image key -> env image key (`random_camera` or a task camera key), in the
    /// config's order: the observation's keys come in this order.
    pub camera_mapping: Vec<(String, String)>,
    /// The language prompt sent with every observation.
    pub prompt: String,
    /// The iPad password the run asks for (`password`), replacing the task spec's.
    pub password: Option<Vec<u8>>,
    /// Where it came from (a config file, or `--task`).
    pub source: String,
    /// The config's `robot_type` is `dual_arm` (`None` for `--task`).
    pub dual_arm: Option<bool>,
}

/// The fields of a DexJoCo evaluation config file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    env_name: String,
    camera_mapping: serde_norway::Mapping,
    prompt: String,
    robot_type: String,
    #[serde(default)]
    password: Option<Vec<u8>>,
}

impl EvalTask {
    /// Reads an evaluation config (YAML, as the reference's `task-configs/`).
    pub fn load(path: &Path) -> Result<Self, EvalError> {
        let bad = |message: String| EvalError::Config {
            path: path.to_path_buf(),
            message,
        };
        let text = fs_err::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let file: ConfigFile = serde_norway::from_str(&text).map_err(|e| bad(e.to_string()))?;
        let mut camera_mapping = Vec::new();
        for (k, v) in &file.camera_mapping {
            match (k.as_str(), v.as_str()) {
                (Some(k), Some(v)) => camera_mapping.push((k.to_owned(), v.to_owned())),
                _ => {
                    return Err(bad(format!(
                        "camera_mapping: '{k:?}: {v:?}' is not policy_key: env_image_key"
                    )));
                }
            }
        }
        if !matches!(file.robot_type.as_str(), "single_arm" | "dual_arm") {
            return Err(bad(format!(
                "robot_type '{}' is neither single_arm nor dual_arm",
                file.robot_type
            )));
        }
        Ok(Self {
            task: file.env_name,
            camera_mapping,
            prompt: file.prompt,
            password: file.password,
            source: path.display().to_string(),
            dual_arm: Some(file.robot_type == "dual_arm"),
        })
    }

    /// The task as `--task` gives it: the policy sees the task's first camera as `base`
    /// (`random_camera` with `--rand-full`) and its wrist cameras (`wrist`, or
    /// `wrist_left` and `wrist_right`), with the task spec's prompt.
    pub fn of_spec(spec: &TaskSpec, rand_full: bool) -> Self {
        let base = if rand_full {
            RANDOM_CAMERA.to_owned()
        } else {
            spec.cameras[0].key.clone()
        };
        let mut camera_mapping = vec![("base".to_owned(), base)];
        for c in spec.cameras.iter().skip(1) {
            if c.key.starts_with("wrist") {
                camera_mapping.push((c.key.clone(), c.key.clone()));
            }
        }
        Self {
            task: spec.id.clone(),
            camera_mapping,
            prompt: spec.prompt.clone(),
            password: None,
            source: "--task".into(),
            dual_arm: None,
        }
    }

    /// Checks the mapping against the task: every env image key is a camera of the
    /// task (or `random_camera` with `--rand-full`), and every key is a name, not a path
    /// (env keys name the episode's videos). `robot_type` must match the task's setup. An
    /// empty mapping is a policy that takes no camera (`--no-cameras`).
    pub fn check(&self, spec: &TaskSpec, rand_full: bool) -> Result<(), EvalError> {
        let usage = |m: String| EvalError::Usage(format!("{} ({}): {m}", self.task, self.source));
        for (policy, env) in &self.camera_mapping {
            for (what, name) in [("policy image key", policy), ("env image key", env)] {
                dexjoco_core::safe_name(what, name).map_err(|e| usage(e.to_string()))?;
            }
            if env == RANDOM_CAMERA {
                if !rand_full {
                    return Err(usage(format!(
                        "'{RANDOM_CAMERA}' exists only with --rand-full (the task's first camera, '{}', \
                         otherwise)",
                        spec.cameras[0].key
                    )));
                }
            } else if !spec.cameras.iter().any(|c| &c.key == env) {
                let keys: Vec<&str> = spec.cameras.iter().map(|c| c.key.as_str()).collect();
                return Err(usage(format!(
                    "env image key '{env}' is not a camera of the task (its cameras: {}{})",
                    keys.join(", "),
                    if rand_full {
                        format!(", {RANDOM_CAMERA}")
                    } else {
                        String::new()
                    }
                )));
            } else if rand_full && env == &spec.cameras[0].key {
                return Err(usage(format!(
                    "with --rand-full the task's first camera is '{RANDOM_CAMERA}', not '{env}'"
                )));
            }
        }
        if self
            .dual_arm
            .is_some_and(|dual| dual != (spec.setup == ArmSetup::Bimanual))
        {
            return Err(usage(format!(
                "robot_type does not match the task's setup ({:?})",
                spec.setup
            )));
        }
        Ok(())
    }

    /// The env image keys, each once, in mapping order (the videos an episode records).
    pub fn env_keys(&self) -> Vec<String> {
        let mut keys: Vec<String> = Vec::new();
        for (_, env) in &self.camera_mapping {
            if !keys.contains(env) {
                keys.push(env.clone());
            }
        }
        keys
    }
}

/// How an evaluation runs (the reference client's options, and ours).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalOptions {
    /// Seed of the resets and randomization draws (`--seed`).
    pub seed: u64,
    /// Episodes (`--episodes`, default 50).
    pub episodes: usize,
    /// Visual randomization: random camera, lights, table texture (`--rand-full`).
    pub rand_full: bool,
    /// Dynamics randomization from the task spec's `[[dynamics]]` (`--randomize-dynamics`).
    pub randomize_dynamics: bool,
    /// A new chunk is asked when fewer than `replan_ratio * horizon` actions remain.
    pub replan_ratio: f64,
    /// The action horizon the policy is trained on.
    pub horizon: usize,
    /// Pad a one-arm state to 46 values (`--pad-state-dim46`).
    pub pad_state_dim46: bool,
    /// Record the iPad's pressed digits in the episode folder names (default: for
    /// bimanual_unlock_ipad).
    pub record_pressed_digits: bool,
    /// Control steps between asking for a chunk and merging it (the modelled inference
    /// latency; deterministic).
    pub latency_steps: usize,
    /// Pace the loop to 30 Hz and merge chunks when they arrive, as the reference does
    /// (results then depend on the machine's and the server's speed).
    pub real_time: bool,
    /// The size cameras are rendered at, (width, height); `None`: 640x640, as the
    /// reference environments render.
    pub render_size: Option<(u32, u32)>,
    /// Rendering quality preset name (`paper`: as the reference).
    pub quality: String,
    /// Record each episode's videos (one per env image key).
    pub videos: bool,
    /// Add `dexjoco/initial_state`, `dexjoco/episode` and `dexjoco/step` to every
    /// observation (for oracle and privileged-information policies; real openpi policies
    /// drop keys they do not know).
    pub privileged_keys: bool,
    /// Add `environment_state` (the objects' poses now and dh, float64) to every
    /// observation, as datasets record it per frame (`--environment-state`).
    #[serde(default)]
    pub environment_state: bool,
    /// Seconds a server may take to answer.
    pub deadline_secs: f64,
    /// Seconds to keep retrying a refused connection at the start.
    pub server_wait_secs: f64,
    /// End an episode after at most this many steps instead of the task's step cap
    /// (`--step-cap`; for smoke tests and benchmarks, not for results to compare).
    #[serde(default)]
    pub step_cap: Option<usize>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            seed: 0,
            episodes: 50,
            rand_full: false,
            randomize_dynamics: false,
            replan_ratio: 0.8,
            horizon: ACTION_HORIZON,
            pad_state_dim46: false,
            record_pressed_digits: false,
            latency_steps: 0,
            real_time: false,
            render_size: None,
            quality: "paper".into(),
            videos: true,
            privileged_keys: false,
            environment_state: false,
            deadline_secs: 120.0,
            server_wait_secs: 10.0,
            step_cap: None,
        }
    }
}

/// Everything a run (and each of its worker processes) needs, serializable so workers
/// read it from the run's folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalConfig {
    /// The task as the policy sees it.
    pub task: EvalTask,
    /// Options.
    pub options: EvalOptions,
    /// The policy server's websocket address.
    pub uri: String,
    /// The scene folder (`--scene-dir`), or built-in scenes.
    pub scene_dir: Option<PathBuf>,
    /// A folder of task specs (`--tasks-dir`).
    pub tasks_dir: Option<PathBuf>,
    /// The output folder.
    pub out: PathBuf,
    /// Initial states to evaluate from instead of drawn resets (`--resets-from`), one per
    /// episode.
    pub initial_states: Option<Vec<Vec<f64>>>,
}
