//! Settings of the commands around the pipeline: render, bench, doctor, scripted,
//! cameras.

use super::*;

/// `render`.
pub struct RenderCommandSettings {
    /// The scene file (None: the built-in tabletop scene).
    pub scene: Option<PathBuf>,
    /// A task id or `all` (`--task`): its scene at its reset instead of `scene`.
    pub task: Option<String>,
    /// The known tasks (`--tasks-dir` with `--task`).
    pub tasks: TaskSet,
    /// A scene pack folder for `task`.
    pub scene_dir: Option<PathBuf>,
    /// Cameras to render (empty: the scene's or the task's).
    pub cameras: Vec<String>,
    /// Size, quality, depth and meshes of the renderer.
    pub render: RenderSettings,
    /// Physics steps simulated before the stills (the clip's length with `--video`).
    pub steps: usize,
    /// With `--video`: the clips' frames per second.
    pub video_fps: Option<u32>,
    /// Output folder.
    pub out: PathBuf,
    /// Replace files of the same names in `out`.
    pub overwrite: bool,
    /// No progress bars.
    pub quiet: bool,
}

/// Frames per second of `render --video` without `--fps`.
const DEFAULT_VIDEO_FPS: u32 = 30;

impl RenderCommandSettings {
    /// Resolves `render`'s arguments.
    pub fn resolve(args: &RenderArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        check_egl_choice(&[])?;
        let RenderArgs {
            scene,
            cameras,
            size,
            width,
            height,
            quality,
            geometry,
            depth,
            steps,
            video,
            fps,
            out,
            overwrite,
            task,
            scene_dir,
            tasks,
        } = args;
        if task.is_none() && tasks.tasks_dir.is_some() {
            return Err(usage(
                "--tasks-dir applies to --task only".into(),
                "add --task <id> to render a task of the folder, or leave --tasks-dir out",
            ));
        }
        let out = out
            .clone()
            .unwrap_or_else(|| global.work_dir.join("render"));
        let read: Vec<&Path> = [
            scene.as_deref(),
            scene_dir.as_deref(),
            tasks.tasks_dir.as_deref(),
        ]
        .into_iter()
        .flatten()
        .collect();
        outputs_apart(&[&out], &read)?;
        Ok(Self {
            scene: scene.clone(),
            task: task.clone(),
            tasks: task_set(tasks)?,
            scene_dir: scene_dir.clone(),
            cameras: cameras.clone(),
            render: RenderSettings {
                width: width.unwrap_or(*size),
                height: height.unwrap_or(*size),
                depth: *depth,
                geometry: geometry.geometry(),
                ..render_settings(*size, *quality)
            },
            steps: *steps,
            video_fps: video.then(|| fps.unwrap_or(DEFAULT_VIDEO_FPS)),
            out,
            overwrite: *overwrite,
            quiet: global.quiet,
        })
    }
}

/// `bench render`.
pub struct BenchRenderSettings {
    /// Scenes given (empty: the built-in one and, when found, a reference scene).
    pub scenes: Vec<PathBuf>,
    /// Timed frames per row.
    pub frames: usize,
    /// Square sizes.
    pub sizes: Vec<u32>,
    /// Presets (every one when none was given).
    pub presets: Vec<QualityArg>,
    /// Camera (None: `front` when the scene has it, else the first).
    pub camera: Option<String>,
    /// The renderer's meshes.
    pub geometries: Vec<dexjoco_render::Geometry>,
    /// Folder of the JSON results.
    pub out: PathBuf,
    /// No progress bar.
    pub quiet: bool,
}

impl BenchRenderSettings {
    /// Resolves `bench render`'s arguments.
    pub fn resolve(args: &BenchRenderArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        check_egl_choice(&[])?;
        let BenchRenderArgs {
            scenes,
            frames,
            sizes,
            presets,
            camera,
            geometry,
        } = args;
        let presets = if presets.is_empty() {
            vec![
                QualityArg::Paper,
                QualityArg::NoMsaa,
                QualityArg::NoMsaaNoShadows,
                QualityArg::Fast,
            ]
        } else {
            presets.clone()
        };
        let out = global.work_dir.join("bench");
        outputs_apart(&[&out], &reads(scenes, &[]))?;
        Ok(Self {
            scenes: scenes.clone(),
            frames: *frames,
            sizes: sizes.clone(),
            presets,
            camera: camera.clone(),
            geometries: geometry.iter().map(|g| g.geometry()).collect(),
            out,
            quiet: global.quiet,
        })
    }
}

/// `bench augment`.
pub struct BenchAugmentSettings {
    /// Episodes to replay (the sample demos when none were given).
    pub inputs: Vec<PathBuf>,
    /// Scene pack folder.
    pub scene_dir: Option<PathBuf>,
    /// Replays per episode.
    pub replays: usize,
    /// Only the first N frames of each episode (0: whole episodes).
    pub max_frames: usize,
    /// Square sizes.
    pub sizes: Vec<u32>,
    /// Quality presets.
    pub qualities: Vec<QualityArg>,
    /// The renderer's meshes.
    pub geometry: Vec<crate::cli::GeometryArg>,
    /// Skip the reference approach.
    pub no_reference: bool,
    /// Frames per process of the render-only limit (0 skips it).
    pub limit_frames: usize,
    /// Worker counts of our runs, ascending: those given, or 1 and `augment`'s default.
    pub workers: Vec<usize>,
    /// Threads of one process instead of worker processes.
    pub threads: bool,
    /// A worker's deadline for its first frame.
    pub first_frame_timeout: std::time::Duration,
    /// Seed of every run (`--seed`).
    pub seed: u64,
    /// No progress bar.
    pub quiet: bool,
    /// Folder of the JSON results.
    pub out: PathBuf,
    /// The renderer of our runs.
    pub renderer: dexjoco_render::RendererKind,
    /// The Warp worker's options.
    pub warp: dexjoco_render::warp::WarpOptions,
}

impl BenchAugmentSettings {
    /// Resolves `bench augment`'s arguments; `sample_data` gives the default input.
    pub fn resolve(
        args: &BenchAugmentArgs,
        global: &GlobalArgs,
        sample_data: impl FnOnce() -> anyhow::Result<PathBuf>,
    ) -> anyhow::Result<Self> {
        check_egl_choice(&[])?;
        let BenchAugmentArgs {
            inputs,
            scene_dir,
            replays,
            max_frames,
            sizes,
            qualities,
            no_reference,
            limit_frames,
            workers,
            geometry,
            threads,
            deadline,
            renderer,
        } = args;
        let (renderer, warp) = renderer.clone().resolve();
        let mut workers = if workers.is_empty() {
            vec![1, render_workers(global.jobs, Vec::new()).0]
        } else {
            workers.clone()
        };
        workers.sort_unstable();
        workers.dedup();
        let inputs = if inputs.is_empty() {
            vec![sample_data()?]
        } else {
            inputs.clone()
        };
        let out = global.work_dir.join("bench");
        outputs_apart(&[&out], &reads(&inputs, &[scene_dir.as_deref()]))?;
        Ok(Self {
            inputs,
            scene_dir: scene_dir.clone(),
            replays: *replays,
            max_frames: *max_frames,
            sizes: sizes.clone(),
            qualities: qualities.clone(),
            geometry: geometry.clone(),
            no_reference: *no_reference,
            limit_frames: *limit_frames,
            workers,
            threads: *threads,
            first_frame_timeout: deadline.duration(),
            seed: global.seed,
            quiet: global.quiet,
            out,
            renderer,
            warp,
        })
    }
}

/// `bench ingest`.
pub struct BenchIngestSettings {
    /// Generated episodes per input format.
    pub episodes: usize,
    /// Frames per episode.
    pub frames: usize,
    /// Threads of the worker pool (`-j`, default all cores).
    pub threads: usize,
    /// Folder of the JSON results.
    pub out: PathBuf,
    /// No progress bars.
    pub quiet: bool,
}

impl BenchIngestSettings {
    /// Resolves `bench ingest`'s arguments.
    pub fn resolve(args: &BenchIngestArgs, global: &GlobalArgs) -> Self {
        let BenchIngestArgs { episodes, frames } = args;
        Self {
            episodes: *episodes,
            frames: *frames,
            threads: global.jobs.unwrap_or_else(dexjoco_core::available_cores),
            out: global.work_dir.join("bench"),
            quiet: global.quiet,
        }
    }
}

/// `doctor`.
pub struct DoctorSettings {
    /// The report as JSON on stdout.
    pub json: bool,
}

impl DoctorSettings {
    /// Resolves `doctor`'s arguments (no global option changes what it checks).
    pub fn resolve(args: &DoctorArgs, _global: &GlobalArgs) -> Self {
        let DoctorArgs { json } = args;
        Self { json: *json }
    }
}

/// `scripted`.
pub struct ScriptedSettings {
    /// The task (one with a scripted planner).
    pub task: TaskSpec,
    /// Random resets to plan from.
    pub episodes: usize,
    /// Where the scene comes from.
    pub scene: SceneSource,
    /// The folder episodes are written to: `<out>/<task>`.
    pub task_dir: PathBuf,
    /// Replace `task_dir` when an earlier run wrote it.
    pub overwrite: bool,
    /// Seed of the random resets (`--seed`).
    pub seed: u64,
    /// No per-reset lines and no progress bar (`--quiet`).
    pub quiet: bool,
}

impl ScriptedSettings {
    /// Resolves `scripted`'s arguments.
    pub fn resolve(args: &ScriptedArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let ScriptedArgs {
            task,
            episodes,
            scene_dir,
            out,
            overwrite,
            tasks,
        } = args;
        let read: Vec<&Path> = [scene_dir.as_deref(), tasks.tasks_dir.as_deref()]
            .into_iter()
            .flatten()
            .collect();
        outputs_apart(&[out], &read)?;
        // An unknown task is a usage error (exit 2), as in every command.
        let tasks = task_set(tasks)?;
        let spec = known_task(&tasks, task)?.clone();
        if !dexjoco_scripted::PLANNED_TASKS.contains(&spec.id.as_str()) {
            return Err(CliError {
                message: format!("no scripted planner for '{}'", spec.id),
                hint: Some(format!(
                    "tasks with a planner: {}",
                    dexjoco_scripted::PLANNED_TASKS.join(", ")
                )),
                status: ExitStatus::Failure,
            }
            .into());
        }
        Ok(Self {
            task_dir: out.join(&spec.id),
            task: spec,
            episodes: *episodes,
            scene: SceneSource::from_option(scene_dir.clone()),
            overwrite: *overwrite,
            seed: global.seed,
            quiet: global.quiet,
        })
    }
}

/// `cameras`.
pub struct CamerasSettings {
    /// The task's spec.
    pub task: TaskSpec,
    /// Where the scene comes from.
    pub scene: SceneSource,
    /// Pool options.
    pub options: dexjoco_augment::PoolOptions,
    /// Pool file.
    pub out: PathBuf,
    /// Also a preview sheet.
    pub preview: bool,
    /// Replace the pool file (and preview) an earlier run wrote.
    pub overwrite: bool,
}

impl CamerasSettings {
    /// Resolves `cameras`' arguments.
    pub fn resolve(args: CamerasArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        check_egl_choice(&[])?;
        let CamerasArgs {
            task,
            scene_dir,
            count,
            candidates,
            distance,
            elevation,
            azimuth,
            out,
            preview,
            overwrite,
            tasks,
        } = args;
        let spec = known_task(&task_set(&tasks)?, &task)?.clone();
        if candidates < count {
            return Err(usage(
                format!("--candidates {candidates} is fewer than --count {count}"),
                "sample at least as many poses as are kept",
            ));
        }
        if let Some(d) = distance.filter(|d| !(d.is_finite() && *d > 0.0)) {
            return Err(usage(
                format!("--distance {d} must be a positive number of metres"),
                "for example --distance 1.4",
            ));
        }
        let mut options = dexjoco_augment::PoolOptions::for_setup(spec.setup);
        options.count = count;
        options.candidates = candidates;
        options.seed = global.seed;
        if let Some(d) = distance {
            options.distance = d;
        }
        if let Some(e) = elevation {
            options.elevation = (e[0], e[1]);
        }
        if let Some(a) = azimuth {
            options.azimuth = (a[0], a[1]);
        }
        let out = out.unwrap_or_else(|| {
            global
                .work_dir
                .join("cameras")
                .join(format!("{}.json", spec.id))
        });
        let read: Vec<&Path> = [scene_dir.as_deref(), tasks.tasks_dir.as_deref()]
            .into_iter()
            .flatten()
            .collect();
        outputs_apart(&[&out], &read)?;
        Ok(Self {
            out,
            task: spec,
            scene: SceneSource::from_option(scene_dir),
            options,
            preview,
            overwrite,
        })
    }
}
