//! `--privileged-state`: the privileged part of an episode's state (its task spec's
//! state columns after the proprioception: the objects' reset-time poses, then `dh`),
//! named after the spec's state layout (`mouse.pose[0]` ... `dh[0]`), from the
//! episode's first kept frame.

use dexjoco_core::{Episode, FrameArray, Location, TaskSet};
use dexjoco_formats::dataset::stats::column_stats;
use dexjoco_formats::dataset::{PRIVILEGED_KEY, PreparedEpisode};

use crate::error::ConvertError;
use crate::prepare::as_f32;

/// Fills `p.privileged` and `p.privileged_names` from the episode's whole `state`,
/// trimmed like the rest of `p`. Fails, naming the episode, when its task has no spec in
/// `tasks` or its state is not as wide as the spec's layout. (With `merge_bimanual` the
/// privileged columns stay as the task has them: episodes of tasks with other state
/// objects do not fit the dataset and are left out by the writer.)
pub(crate) fn add_privileged(
    p: &mut PreparedEpisode,
    input: &crate::InputEpisode,
    tasks: &TaskSet,
) -> Result<(), ConvertError> {
    let ep = &input.episode;
    let at = || {
        Location::episode(&ep.id)
            .field(Episode::STATE)
            .path(&input.dir)
    };
    let spec = tasks.get(&ep.task).ok_or_else(|| ConvertError::Episode {
        at: at().into(),
        message: format!(
            "--privileged-state: task '{}' has no task spec to name the privileged columns \
             (add its spec with --tasks-dir)",
            ep.task
        ),
    })?;
    let layout = spec.state_layout();
    let state = ep
        .array(Episode::STATE)
        .ok_or_else(|| ConvertError::Episode {
            at: at().into(),
            message: "array missing".into(),
        })?;
    if state.width() != layout.width() {
        return Err(ConvertError::Episode {
            at: at().into(),
            message: format!(
                "--privileged-state: the state has {} columns, task '{}''s spec lays out {}",
                state.width(),
                ep.task,
                layout.width()
            ),
        });
    }
    let columns = spec.setup.proprio_dim()..layout.width();
    let mut data = Vec::with_capacity((state.len() - p.skipped) * columns.len());
    for i in p.skipped..state.len() {
        data.extend_from_slice(&state.row(i)[columns.clone()]);
    }
    let privileged = FrameArray::new(columns.len(), data).expect("whole rows");
    // lerobot stores float32 and computes on what it stores.
    p.stats.insert(
        PRIVILEGED_KEY.to_owned(),
        column_stats(&as_f32(&privileged), privileged.width()),
    );
    p.privileged_names = columns.map(|c| layout.column_name(c)).collect();
    p.privileged = Some(privileged);
    Ok(())
}
