//! Settings of `eval`.

use super::*;
use crate::cli::EvalArgs;
use dexjoco_eval::{EvalConfig, EvalOptions, EvalTask, WorkerProcesses};

/// `eval`.
pub struct EvalSettings {
    /// The run.
    pub config: EvalConfig,
    /// Its worker processes (`-j N`, N > 1; the program and its arguments are the
    /// command's to fill in), or `None` to run the episodes in this process.
    pub executor: Option<WorkerProcesses>,
}

impl EvalSettings {
    /// Resolves `eval`'s arguments.
    pub fn resolve(args: EvalArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let EvalArgs {
            config,
            task,
            prompt,
            episodes,
            rand_full,
            randomize_dynamics,
            host,
            port,
            replan_ratio,
            pad_state_dim46,
            record_pressed_digits,
            latency_steps,
            real_time,
            output,
            scene_dir,
            resets_from,
            render_size,
            quality,
            no_videos,
            privileged_keys,
            environment_state,
            no_cameras,
            deadline,
            server_wait,
            step_cap,
            tasks,
            workers:
                WorkerArgs {
                    egl_devices,
                    deadline: first_frame,
                },
        } = args;
        let tasks_dir = tasks.tasks_dir.clone();
        let known = task_set(&tasks)?;
        let eval_task = eval_task_of(
            config.as_deref(),
            task.as_deref(),
            prompt,
            &known,
            rand_full,
            no_cameras,
        )?;
        check_numbers(replan_ratio)?;
        let out = output.unwrap_or_else(|| default_out(global, &eval_task.task, rand_full));
        let read = reads(
            &[],
            &[
                config.as_deref(),
                scene_dir.as_deref(),
                tasks_dir.as_deref(),
                resets_from.as_deref(),
            ],
        );
        outputs_apart(&[&out], &read)?;
        let initial_states = resets_from
            .as_deref()
            .map(|p| initial_states_from(p, &known))
            .transpose()?;
        let record_pressed_digits =
            record_pressed_digits.unwrap_or(eval_task.task == "bimanual_unlock_ipad");
        let options = EvalOptions {
            seed: global.seed,
            episodes,
            rand_full,
            randomize_dynamics,
            replan_ratio,
            horizon: dexjoco_eval::ACTION_HORIZON,
            pad_state_dim46,
            record_pressed_digits,
            latency_steps,
            real_time,
            render_size,
            quality: quality.name().to_owned(),
            videos: !no_videos,
            privileged_keys,
            environment_state,
            deadline_secs: deadline,
            server_wait_secs: server_wait,
            step_cap: step_cap.map(|n| n as usize),
        };
        check_egl_choice(&egl_devices)?;
        let executor = workers(
            global.jobs.unwrap_or(1),
            egl_devices,
            first_frame.duration(),
            &options,
        );
        Ok(Self {
            config: EvalConfig {
                task: eval_task,
                options,
                uri: dexjoco_eval::protocol::uri(&host, Some(port)),
                scene_dir,
                tasks_dir,
                out,
                initial_states,
            },
            executor,
        })
    }
}

/// `<work-dir>/eval/<task>[_rand_full]_seed<seed>`, the reference's folder name.
fn default_out(global: &GlobalArgs, task: &str, rand_full: bool) -> PathBuf {
    let full = if rand_full { "_rand_full" } else { "" };
    global
        .work_dir
        .join("eval")
        .join(format!("{task}{full}_seed{}", global.seed))
}

/// `-j N` environments (N > 1): worker processes (`eval-worker`), each with its renderer
/// and connection, dealt over the node's GPUs as augment's are. A worker may stay silent
/// while it connects and waits for answers: its silence deadline covers the server's
/// waits (--server-wait and four --deadline) as well as ten first-frame deadlines.
fn workers(
    jobs: usize,
    egl_devices: Vec<usize>,
    first_frame: std::time::Duration,
    options: &EvalOptions,
) -> Option<WorkerProcesses> {
    if jobs <= 1 {
        return None;
    }
    let (_, egl_devices) = render_workers(Some(jobs), egl_devices);
    let mut w = WorkerProcesses::new(PathBuf::new(), Vec::new(), jobs)
        .with_egl_devices(egl_devices)
        .with_first_frame_timeout(first_frame);
    let server = std::time::Duration::from_secs_f64(
        options.server_wait_secs + 4.0 * options.deadline_secs + 60.0,
    );
    w.silence_timeout = w.silence_timeout.max(server);
    Some(w)
}

/// Usage errors for numbers out of range.
fn check_numbers(replan_ratio: f64) -> anyhow::Result<()> {
    if !(replan_ratio > 0.0 && replan_ratio <= 1.0) {
        return Err(usage(
            format!("--replan-ratio {replan_ratio} is not in (0, 1]"),
            "the reference's default is 0.8",
        ));
    }
    Ok(())
}

/// An evaluation error as a usage error (exit code 2).
fn eval_usage(e: dexjoco_eval::EvalError) -> anyhow::Error {
    usage(
        e.to_string(),
        "see `dexjoco-data eval --help`; the reference's configs are in task-configs/",
    )
}

/// The initial states of `--resets-from`: a JSON file `{"initial_states": [[...]]}`, or
/// each episode's `state[0]` in a folder of episodes, in discovery order.
fn initial_states_from(path: &Path, tasks: &TaskSet) -> anyhow::Result<Vec<Vec<f64>>> {
    if path.is_file() && path.extension().is_some_and(|e| e == "json") {
        #[derive(serde::Deserialize)]
        struct File {
            initial_states: Vec<Vec<f64>>,
        }
        let bytes = fs_err::read(path)?;
        let f: File = serde_json::from_slice(&bytes).map_err(|e| {
            usage(
                format!("--resets-from '{}': {e}", path.display()),
                "give {\"initial_states\": [[...], ...]} or a folder of episodes",
            )
        })?;
        return Ok(f.initial_states);
    }
    let mut states = Vec::new();
    for source in dexjoco_formats::discover(&[path.to_path_buf()], None)? {
        let ep = source.read(tasks)?.episode;
        let state = ep
            .array(dexjoco_core::Episode::STATE)
            .filter(|a| !a.is_empty())
            .ok_or_else(|| anyhow::anyhow!("'{}' has no state", source.path.display()))?;
        states.push(state.row(0).to_vec());
    }
    if states.is_empty() {
        return Err(usage(
            format!("--resets-from '{}' holds no episode", path.display()),
            "give a folder of episodes or a JSON file of initial states",
        ));
    }
    Ok(states)
}

/// The task as the policy sees it: the config file's or `--task`'s, with `--prompt`, checked
/// against the task; with `--no-cameras` no camera at all.
fn eval_task_of(
    config: Option<&Path>,
    task: Option<&str>,
    prompt: Option<String>,
    known: &dexjoco_core::TaskSet,
    rand_full: bool,
    no_cameras: bool,
) -> anyhow::Result<EvalTask> {
    let mut eval_task = match (config, task) {
        (Some(path), _) => EvalTask::load(path).map_err(eval_usage)?,
        (None, Some(id)) => EvalTask::of_spec(known_task(known, id)?, rand_full),
        (None, None) => unreachable!("clap requires one"),
    };
    let spec = known_task(known, &eval_task.task)?;
    if let Some(p) = prompt {
        eval_task.prompt = p;
    }
    if eval_task.camera_mapping.is_empty() && !no_cameras {
        return Err(usage(
            format!(
                "{} ({}): camera_mapping is empty: the policy would see no image",
                eval_task.task, eval_task.source
            ),
            "for a policy that takes no camera, pass --no-cameras",
        ));
    }
    eval_task.check(spec, rand_full).map_err(eval_usage)?;
    // The policy takes no camera: nothing is sent, nothing rendered.
    if no_cameras {
        eval_task.camera_mapping.clear();
    }
    Ok(eval_task)
}
