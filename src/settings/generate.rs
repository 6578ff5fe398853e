//! Settings of `generate`.

use super::*;
use crate::cli::{ChoiceArg, GenerateArgs};
use dexjoco_generate::{AttemptOptions, GenerateConfig, SegmentChoice};

/// `generate`.
pub struct GenerateSettings {
    /// The task.
    pub task: TaskSpec,
    /// The known tasks (sources are read against them).
    pub tasks: TaskSet,
    /// Source episodes (inputs as given; discovery runs in the command).
    pub inputs: Vec<PathBuf>,
    /// Where the scene comes from.
    pub scene: SceneSource,
    /// The run (its `out` is `<out>/<task>`).
    pub config: GenerateConfig,
    /// Pilot attempts for a dry run, or `None` to run.
    pub dry_run: Option<usize>,
    /// No per-attempt lines and no progress bar.
    pub quiet: bool,
}

impl GenerateSettings {
    /// Resolves `generate`'s arguments; `sample_data` gives the sample demonstrations'
    /// folder (the default source is its `<task>` folder).
    pub fn resolve(
        args: GenerateArgs,
        global: &GlobalArgs,
        sample_data: impl FnOnce() -> anyhow::Result<PathBuf>,
    ) -> anyhow::Result<Self> {
        let GenerateArgs {
            inputs,
            task,
            count,
            max_attempts,
            out,
            scene_dir,
            choice,
            per_subtask,
            grace_steps,
            extend_steps,
            keep_failed,
            dry_run,
            pilot,
            shard,
            overwrite,
            tasks,
        } = args;
        let shard = shard_of(shard.as_deref(), overwrite)?;
        let task_set = task_set(&tasks)?;
        let spec = known_task(&task_set, &task)?.clone();
        if spec.subtasks.is_empty() {
            return Err(usage(
                format!("task '{}' declares no subtasks", spec.id),
                "generate carries source segments subtask by subtask: give the task's spec \
                 [[subtasks]] (see docs/your-own-task.md)",
            ));
        }
        let inputs = if inputs.is_empty() {
            vec![sample_data()?.join(&spec.id)]
        } else {
            inputs
        };
        let out = out.unwrap_or_else(|| global.work_dir.join("generate"));
        let read = reads(&inputs, &[scene_dir.as_deref(), tasks.tasks_dir.as_deref()]);
        outputs_apart(&[&out], &read)?;
        let max_attempts = max_attempts.unwrap_or(count.saturating_mul(10));
        let scene = SceneSource::from_option(scene_dir);
        let options = AttemptOptions {
            choice: match choice {
                ChoiceArg::Random => SegmentChoice::Random,
                ChoiceArg::Nearest => SegmentChoice::Nearest,
            },
            per_subtask,
            grace_steps,
            ..AttemptOptions::default()
        };
        Ok(Self {
            config: GenerateConfig {
                out: out.join(&spec.id),
                seed: global.seed,
                count,
                max_attempts,
                workers: global.jobs.unwrap_or_else(rayon::current_num_threads),
                keep_failed,
                overwrite,
                shard,
                options,
                scene: scene.clone(),
                extend_steps,
            },
            task: spec,
            tasks: task_set,
            inputs,
            scene,
            dry_run: dry_run.then_some(pilot),
            quiet: global.quiet,
        })
    }
}
