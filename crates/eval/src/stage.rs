//! What every episode of a run shares in one process: the task spec (with the config's
//! iPad password), the scene, the randomization's camera pool and table looks, and the
//! renderer with the cameras the policy and the videos see.

use std::path::Path;

use dexjoco_core::{Node, TaskSpec};
use dexjoco_render::randomize::{CameraPool, TABLE_GEOM, TableLibrary, VisualSample};
use dexjoco_render::{RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::dynamics::{DynamicsValue, dynamics_seed, sample_dynamics};
use dexjoco_sim::{Scene, SceneSource, load_task_scene};
use dexjoco_video::{Codec, VideoError, VideoSpec, VideoWriter};
use sha2::{Digest, Sha256};

use crate::config::{EvalConfig, RANDOM_CAMERA};
use crate::error::{EvalError, sim_err};

/// Where an env image key's camera is.
#[derive(Debug, Clone, Copy)]
pub(crate) enum View {
    /// A camera of the scene, by id.
    Fixed(usize),
    /// The randomized third-person camera of the episode's draw.
    Random,
}

/// The task's spec for a run: the built-in or `--tasks-dir` spec, with the config's
/// password in its keypad and `--step-cap`'s cap.
pub fn run_spec(config: &EvalConfig) -> Result<TaskSpec, EvalError> {
    let tasks = dexjoco_core::TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| EvalError::Usage(format!("--tasks-dir: {e}")))?;
    let mut spec = tasks
        .get(&config.task.task)
        .ok_or_else(|| {
            EvalError::Usage(format!(
                "unknown task '{}' (known: {}); --tasks-dir adds tasks",
                config.task.task,
                tasks.ids().join(", ")
            ))
        })?
        .clone();
    if let Some(cap) = config.options.step_cap {
        spec.step_cap = cap;
    }
    if let Some(p) = &config.task.password {
        let mut found = false;
        for node in spec.nodes.values_mut() {
            if let Node::Keypad { password, .. } = node {
                password.clone_from(p);
                found = true;
            }
        }
        if !found {
            tracing::warn!(
                "the config gives a password, but task '{}' has no keypad: ignored",
                spec.id
            );
        }
    }
    Ok(spec)
}

/// Steps of click_mouse's warm-up before the first observation (the reference client).
pub(crate) const WARMUP_STEPS: usize = 30;

/// The episode's own draws (with `--rand-full`, `--randomize-dynamics`).
pub(crate) struct Draws {
    pub(crate) visuals: Option<VisualSample>,
    pub(crate) dynamics: Option<Vec<DynamicsValue>>,
}

/// The codec of the episode videos (H.264 as the DexJoCo recorder).
pub(crate) fn video_spec(width: u32, height: u32) -> VideoSpec {
    VideoSpec {
        width,
        height,
        fps: 30,
        codec: Codec::DEXJOCO,
    }
}

/// The seed of episode `k`'s own draws (visual and dynamics randomization): the first 8
/// bytes of SHA-256 over (run seed, episode), so an episode's draw never depends on which
/// others run, nor on the worker count.
pub fn episode_seed(seed: u64, k: usize) -> u64 {
    let mut h = Sha256::new();
    h.update(b"dexjoco-eval/v1");
    h.update(seed.to_le_bytes());
    h.update((k as u64).to_le_bytes());
    let d = h.finalize();
    u64::from_le_bytes(d[..8].try_into().expect("8 bytes"))
}

/// A run's shared state in one process.
pub(crate) struct Stage {
    pub(crate) config: EvalConfig,
    pub(crate) spec: TaskSpec,
    pub(crate) scene: Scene,
    pub(crate) pool: Option<CameraPool>,
    pub(crate) table: Option<TableLibrary>,
    /// The renderer; `None` when nothing is drawn (the policy takes no camera): the
    /// episodes then run at the simulator's speed.
    pub(crate) renderer: Option<Renderer>,
    views: Vec<(String, View)>,
    /// Frames drawn so far (the warm-up included).
    pub(crate) frames_rendered: u64,
}

impl Stage {
    /// Loads the scene and the randomization's assets, opens the renderer.
    pub(crate) fn new(config: &EvalConfig) -> Result<Self, EvalError> {
        let spec = run_spec(config)?;
        let what = spec.id.clone();
        let source = SceneSource::from_option(config.scene_dir.clone());
        let scene = load_task_scene(&source, &spec).map_err(sim_err(&what))?;
        let (pool, table) = if config.options.rand_full {
            (
                Some(CameraPool::for_task(None, &source, spec.setup).map_err(sim_err(&what))?),
                Some(TableLibrary::of_model(&scene.model, TABLE_GEOM).map_err(sim_err(&what))?),
            )
        } else {
            (None, None)
        };
        let mut views = Vec::new();
        for key in config.task.env_keys() {
            let view = if key == RANDOM_CAMERA {
                View::Random
            } else {
                let cam = spec
                    .cameras
                    .iter()
                    .find(|c| c.key == key)
                    .expect("checked against the spec");
                View::Fixed(scene.camera_id(&cam.camera).map_err(sim_err(&what))?)
            };
            views.push((key, view));
        }
        let (width, height) = config
            .options
            .render_size
            .unwrap_or(crate::config::REFERENCE_RENDER_SIZE);
        let quality = RenderQuality::from_name(&config.options.quality).ok_or_else(|| {
            EvalError::Usage(format!("unknown quality '{}'", config.options.quality))
        })?;
        let settings = RenderSettings {
            width,
            height,
            quality,
            ..RenderSettings::default()
        };
        // Videos and observations draw the mapped cameras only: none, no renderer.
        let renderer = if views.is_empty() {
            None
        } else {
            Some(Renderer::new(&scene.model, settings).map_err(sim_err(&what))?)
        };
        Ok(Self {
            config: config.clone(),
            spec,
            scene,
            pool,
            table,
            renderer,
            views,
            frames_rendered: 0,
        })
    }

    /// The renderer's device in words, for the parent (`no renderer` without one).
    pub(crate) fn device_words(&self) -> String {
        match &self.renderer {
            Some(r) => {
                let device = r.device();
                format!("EGL device {} ({})", device.index, device.label())
            }
            None => "no renderer (the policy takes no camera)".to_owned(),
        }
    }

    /// Draws one frame of the scene as it loads, from its first camera (a worker tells
    /// its parent that the renderer works once this returns).
    pub(crate) fn warm_up(&mut self) -> Result<(), EvalError> {
        let Some(renderer) = self.renderer.as_mut() else {
            return Ok(());
        };
        let mut data = dexjoco_sim::mujoco_rs::prelude::MjData::new(self.scene.model.clone());
        data.forward();
        let camera = self
            .views
            .iter()
            .find_map(|(_, v)| match v {
                View::Fixed(id) => Some(*id),
                View::Random => None,
            })
            .unwrap_or(0);
        renderer.update_scene(&mut data, dexjoco_render::CameraView::Fixed(camera));
        renderer.draw().map_err(sim_err(&self.spec.id))?;
        self.frames_rendered += 1;
        Ok(())
    }

    /// The camera of an env image key.
    pub(crate) fn view(&self, key: &str) -> View {
        self.views
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| *v)
            .expect("a mapped env image key")
    }

    /// Steps of click_mouse's warm-up (0 for other tasks).
    pub(crate) fn warmup_steps(&self) -> usize {
        if self.spec.id == "click_mouse" {
            WARMUP_STEPS
        } else {
            0
        }
    }

    /// The episode's randomization draws from its seed.
    pub(crate) fn draws(&self, seed: u64) -> Result<Draws, EvalError> {
        let visuals = match (&self.pool, &self.table) {
            (Some(pool), Some(table)) => Some(VisualSample::sample(
                seed,
                pool,
                table,
                self.scene.model.ffi().nlight as usize,
            )),
            _ => None,
        };
        let dynamics = if self.config.options.randomize_dynamics {
            Some(
                sample_dynamics(&self.spec, &self.scene.model, dynamics_seed(seed))
                    .map_err(sim_err(&self.spec.id))?,
            )
        } else {
            None
        };
        Ok(Draws { visuals, dynamics })
    }

    /// A video writer per env image key, in the episode's folder (`<key>.mp4`).
    pub(crate) fn video_writers(
        &self,
        dir: &Path,
    ) -> Result<Vec<(String, VideoWriter)>, VideoError> {
        let Some(renderer) = &self.renderer else {
            return Ok(Vec::new());
        };
        let s = renderer.settings();
        self.views
            .iter()
            .map(|(k, _)| {
                VideoWriter::create(dir.join(format!("{k}.mp4")), video_spec(s.width, s.height))
                    .map(|w| (k.clone(), w))
            })
            .collect()
    }
}
