//! A task's assets for augmenting it: its scene, the camera pool and table looks that
//! randomization draws from, loaded once and shared by every unit that renders the task.

use dexjoco_core::TaskSpec;
use dexjoco_render::warp::SceneXml;
use dexjoco_sim::{Scene, SceneSource, load_task_scene};

use crate::config::AugmentConfig;
use crate::error::{AugmentError, sim_err};
use dexjoco_render::randomize::{CameraPool, TABLE_GEOM, TableLibrary};

/// A task's scene and what randomization needs of it, shared by every worker thread.
pub(crate) struct TaskAssets {
    pub(crate) scene: Scene,
    /// The scene as the Warp renderer's worker compiles it.
    pub(crate) xml: SceneXml,
    pub(crate) pool: CameraPool,
    pub(crate) table: TableLibrary,
    pub(crate) nlight: usize,
    pub(crate) key: String,
}

impl TaskAssets {
    /// The scene ids of the fixed cameras a replay renders besides its third-person view.
    pub(crate) fn fixed_cameras(
        &self,
        names: &[String],
        episode: &str,
    ) -> Result<Vec<usize>, AugmentError> {
        names
            .iter()
            .map(|c| self.scene.camera_id(c).map_err(sim_err(episode)))
            .collect()
    }

    /// Checks that the scene has every camera `names` asks for (`--camera`): a usage
    /// error naming the task, the camera and the cameras the scene has.
    pub(crate) fn check_cameras(&self, names: &[String], task: &str) -> Result<(), AugmentError> {
        match names.iter().find(|c| self.scene.camera_id(c).is_err()) {
            None => Ok(()),
            Some(c) => Err(AugmentError::Usage(format!(
                "--camera '{c}': the scene of task '{task}' ({}) has no camera of that name; its cameras: {}",
                self.scene.path.display(),
                self.scene.camera_names().join(", ")
            ))),
        }
    }

    /// The randomization of replay `r` of the episode `key` (`<task>/<episode>`).
    pub(crate) fn sample(
        &self,
        seed: u64,
        key: &str,
        r: usize,
    ) -> dexjoco_render::randomize::VisualSample {
        dexjoco_render::randomize::VisualSample::sample(
            dexjoco_render::randomize::replay_seed(seed, key, r),
            &self.pool,
            &self.table,
            self.nlight,
        )
    }
}

fn pool_for(config: &AugmentConfig, spec: &TaskSpec) -> Result<CameraPool, AugmentError> {
    Ok(CameraPool::for_task(
        config.camera_pool.as_deref(),
        &config.scene,
        spec.setup,
    )?)
}

/// Loads a task's scene, camera pool and table looks.
pub(crate) fn load_assets(
    config: &AugmentConfig,
    spec: &TaskSpec,
) -> Result<TaskAssets, AugmentError> {
    let scene = load_task_scene(&config.scene, spec).map_err(sim_err(&spec.id))?;
    let xml = match &config.scene {
        SceneSource::BuiltIn => {
            SceneXml::Text(dexjoco_sim::builtin::scene_xml(spec).map_err(sim_err(&spec.id))?)
        }
        SceneSource::Dir(_) => SceneXml::Path(scene.path.clone()),
    };
    let table = TableLibrary::of_model(&scene.model, TABLE_GEOM)?;
    let pool = pool_for(config, spec)?;
    let nlight = scene.model.ffi().nlight as usize;
    let key = format!("{}:{}", spec.id, scene.path.display());
    Ok(TaskAssets {
        scene,
        xml,
        pool,
        table,
        nlight,
        key,
    })
}
