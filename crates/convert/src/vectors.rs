//! The state features beyond the proprioception, named after the task spec's state layout
//! (`mouse.pose[0]` ... `dh[0]`):
//!
//! - `--environment-state` (`observation.environment_state`): the objects' state at every
//!   frame (each state object's pose or position now, then `dh`), as the stage that made
//!   the episode recorded it from the simulator (its `environment_state` array);
//! - `--privileged-state` (`privileged.state`): the privileged part of `state` (the
//!   objects' reset-time poses, `dh`), outside `observation.*`.
//!
//! Both are trimmed like the rest of the episode and carry their statistics (of the
//! float32 values lerobot stores).

use dexjoco_core::{Episode, FrameArray, Location, TaskSet, TaskSpec};
use dexjoco_formats::dataset::stats::column_stats;
use dexjoco_formats::dataset::{
    ENVIRONMENT_STATE_KEY, PRIVILEGED_KEY, PreparedEpisode, VectorFeature,
};

use crate::error::ConvertError;
use crate::prepare::as_f32;

/// Which state features to export, and the specs that name their columns.
#[derive(Debug, Clone)]
pub struct StateFeatures {
    /// The task specs (the built-in ones and `--tasks-dir`'s).
    pub tasks: TaskSet,
    /// `--environment-state`.
    pub environment: bool,
    /// `--privileged-state`.
    pub privileged: bool,
}

/// Adds the asked state features to `p` from the episode's arrays. Fails, naming the
/// episode and field, when its task has no spec in `tasks`, when it has no environment
/// state (an episode no simulating stage made), or when a width is not the spec's. (With
/// `merge_bimanual` the columns stay as the task has them: episodes of tasks with other
/// state objects do not fit the dataset and are left out by the writer.)
pub(crate) fn add_state_features(
    p: &mut PreparedEpisode,
    input: &crate::InputEpisode,
    features: &StateFeatures,
) -> Result<(), ConvertError> {
    let ep = &input.episode;
    let fail = |field: &str, message: String| ConvertError::Episode {
        at: Location::episode(&ep.id)
            .field(field)
            .path(&input.dir)
            .into(),
        message,
    };
    let spec = features.tasks.get(&ep.task).ok_or_else(|| {
        fail(
            Episode::STATE,
            format!(
                "task '{}' has no task spec to name the state's columns (add its spec with \
                 --tasks-dir)",
                ep.task
            ),
        )
    })?;
    // The state's own width first: an episode of another layout is named for it.
    let privileged = features
        .privileged
        .then(|| privileged(ep, spec).map_err(|m| fail(Episode::STATE, m)))
        .transpose()?;
    if features.environment {
        let values = environment(ep, spec).map_err(|m| fail(Episode::ENVIRONMENT_STATE, m))?;
        let names = spec.environment_state_names();
        push(p, ENVIRONMENT_STATE_KEY, names, values);
    }
    if let Some(values) = privileged {
        push(p, PRIVILEGED_KEY, spec.privileged_names(), &values);
    }
    Ok(())
}

/// Appends the rows of `values` from the first kept frame as the feature `key`, with its
/// statistics.
fn push(p: &mut PreparedEpisode, key: &str, names: Vec<String>, values: &FrameArray) {
    let width = values.width();
    let mut data = Vec::with_capacity((values.len() - p.skipped) * width);
    for i in p.skipped..values.len() {
        data.extend_from_slice(values.row(i));
    }
    let kept = FrameArray::new(width, data).expect("whole rows");
    // lerobot stores float32 and computes on what it stores.
    p.stats
        .insert(key.to_owned(), column_stats(&as_f32(&kept), width));
    p.vectors.push(VectorFeature {
        key: key.to_owned(),
        names,
        values: kept,
    });
}

/// The episode's environment state, checked against its spec and length.
fn environment<'a>(ep: &'a Episode, spec: &TaskSpec) -> Result<&'a FrameArray, String> {
    let a = ep.array(Episode::ENVIRONMENT_STATE).ok_or_else(|| {
        "--environment-state: the episode has no per-frame environment state (augment, \
         generate, scripted and eval record it; replay a recording with augment first)"
            .to_owned()
    })?;
    let width = spec.environment_state_names().len();
    if a.width() != width || a.len() != ep.len() {
        return Err(format!(
            "--environment-state: {} rows of {} values, task '{}''s spec lays out {width} \
             values for each of the episode's {} frames",
            a.len(),
            a.width(),
            spec.id,
            ep.len()
        ));
    }
    Ok(a)
}

/// The privileged columns of the episode's state, checked against its spec.
fn privileged(ep: &Episode, spec: &TaskSpec) -> Result<FrameArray, String> {
    let layout = spec.state_layout();
    let state = ep
        .array(Episode::STATE)
        .ok_or_else(|| "array missing".to_owned())?;
    if state.width() != layout.width() {
        return Err(format!(
            "--privileged-state: the state has {} columns, task '{}''s spec lays out {}",
            state.width(),
            ep.task,
            layout.width()
        ));
    }
    let columns = spec.setup.proprio_dim()..layout.width();
    let mut data = Vec::with_capacity(state.len() * columns.len());
    for row in state.rows() {
        data.extend_from_slice(&row[columns.clone()]);
    }
    Ok(FrameArray::new(columns.len(), data).expect("whole rows"))
}
