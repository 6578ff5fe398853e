//! Settings of each pipeline command, resolved once from its arguments and the global
//! options (defaults from the work folder, checks of values), the way uv does it: every
//! `resolve` destructures the whole arguments struct, so a new flag that is not handled
//! here fails to compile.

use std::path::{Path, PathBuf};

use dexjoco_augment::{AugmentConfig, Shard};
use dexjoco_convert::{
    ConvertOptions, OutputFormat, Selection, V3Options, VideoCodec, VideoOptions,
};
use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_formats::EpisodeContainer;
use dexjoco_formats::mcap::McapLog;
use dexjoco_ingest::{IngestOptions, ValidationOptions};
use dexjoco_sim::{RenderQuality, RenderSettings, SceneSource};

use crate::cli::{
    AugmentArgs, BenchAugmentArgs, BenchIngestArgs, BenchRenderArgs, CamerasArgs, ConvertArgs,
    ConvertFormatArg, DoctorArgs, ExportArgs, ExportFormat, GlobalArgs, IngestArgs, JsBaseArg,
    QualityArg, RenderArgs, ScriptedArgs, StatsArgs, TasksDirArgs, VideoCodecArg,
};
use crate::exit::{CliError, ExitStatus};

/// A usage error (exit code 2) with a hint.
pub fn usage(message: String, hint: impl Into<String>) -> anyhow::Error {
    CliError {
        message,
        hint: Some(hint.into()),
        status: ExitStatus::Usage,
    }
    .into()
}

/// The spec of a known task, or a usage error naming the known ones and `--tasks-dir`.
pub fn known_task<'a>(tasks: &'a TaskSet, id: &str) -> anyhow::Result<&'a TaskSpec> {
    tasks.get(id).ok_or_else(|| {
        usage(
            format!("unknown task '{id}'"),
            format!(
                "known tasks: {}; a task of your own: put its spec, {id}.toml, in a folder \
                 and pass it with --tasks-dir",
                tasks.ids().join(", ")
            ),
        )
    })
}

/// The known tasks (`--tasks-dir`): the built-in specs with those of the folder replacing
/// the ones of the same id or adding tasks; a missing folder or a spec that does not
/// parse is a failure naming it.
pub fn task_set(args: &TasksDirArgs) -> anyhow::Result<TaskSet> {
    let dir = args.tasks_dir.as_deref();
    if let Some(d) = dir {
        must_exist(
            d,
            "give --tasks-dir a folder of task specs (<task_id>.toml, as in schemas/tasks/)",
        )?;
    }
    TaskSet::with_dir(dir).map_err(|e| {
        CliError {
            message: format!("--tasks-dir: {e}"),
            hint: Some(
                "each <task_id>.toml has the fields of schemas/task-spec.schema.json; \
                 copy one of schemas/tasks/ to start from"
                    .into(),
            ),
            status: ExitStatus::Failure,
        }
        .into()
    })
}

/// The render settings of a square `--size` and a `--quality` preset.
pub fn render_settings(size: u32, quality: QualityArg) -> RenderSettings {
    RenderSettings {
        width: size,
        height: size,
        quality: RenderQuality::from_name(quality.name()).expect("every QualityArg is a preset"),
        depth: false,
        geometry: dexjoco_sim::Geometry::Full,
    }
}

/// `ingest`.
pub struct IngestSettings {
    /// Inputs as given.
    pub inputs: Vec<PathBuf>,
    /// The store.
    pub store: PathBuf,
    /// Library options.
    pub options: IngestOptions,
    /// JSON report on stdout.
    pub json: bool,
}

impl IngestSettings {
    /// Resolves `ingest`'s arguments.
    pub fn resolve(args: IngestArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let IngestArgs {
            inputs,
            out,
            overwrite,
            task,
            tasks,
            quat_tolerance,
            timestep_tolerance,
            json,
        } = args;
        let tasks = task_set(&tasks)?;
        if let Some(t) = &task {
            known_task(&tasks, t)?;
        }
        non_negative("--quat-tolerance", quat_tolerance)?;
        non_negative("--timestep-tolerance", timestep_tolerance)?;
        Ok(Self {
            inputs,
            store: out.unwrap_or_else(|| global.work_dir.join("ingest")),
            options: IngestOptions {
                force: overwrite,
                task,
                validation: ValidationOptions {
                    quat_norm_tolerance: quat_tolerance,
                    timestep_tolerance,
                    ..ValidationOptions::default()
                },
                tasks,
            },
            json,
        })
    }
}

/// A usage error unless `value` is a finite number >= 0.
fn non_negative(flag: &str, value: f64) -> anyhow::Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(usage(
            format!("{flag} {value} must be a number >= 0"),
            "tolerances are distances: 0 or more",
        ))
    }
}

/// `export`.
pub struct ExportSettings {
    /// Episode folders or stores.
    pub inputs: Vec<PathBuf>,
    /// Output folder.
    pub out: PathBuf,
    /// The container episodes are written in.
    pub container: &'static dyn EpisodeContainer,
    /// Replace files already in `out`.
    pub overwrite: bool,
    /// The known tasks.
    pub tasks: TaskSet,
}

impl ExportSettings {
    /// Resolves `export`'s arguments.
    pub fn resolve(args: ExportArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let ExportArgs {
            to,
            inputs,
            out,
            overwrite,
            tasks,
        } = args;
        let inputs = if inputs.is_empty() {
            vec![global.work_dir.join("ingest")]
        } else {
            inputs
        };
        for input in &inputs {
            must_exist(
                input,
                "give episode folders or stores made by `dexjoco-data ingest`",
            )?;
        }
        Ok(Self {
            inputs,
            out: out.unwrap_or_else(|| global.work_dir.join("export")),
            container: match to {
                ExportFormat::Mcap => &McapLog,
            },
            overwrite,
            tasks: task_set(&tasks)?,
        })
    }
}

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
            out: out
                .clone()
                .unwrap_or_else(|| global.work_dir.join("render")),
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
    pub geometries: Vec<dexjoco_sim::Geometry>,
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
        Ok(Self {
            scenes: scenes.clone(),
            frames: *frames,
            sizes: sizes.clone(),
            presets,
            camera: camera.clone(),
            geometries: geometry.iter().map(|g| g.geometry()).collect(),
            out: global.work_dir.join("bench"),
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
        } = args;
        let mut workers = if workers.is_empty() {
            vec![1, render_workers(global.jobs, Vec::new()).0]
        } else {
            workers.clone()
        };
        workers.sort_unstable();
        workers.dedup();
        Ok(Self {
            inputs: if inputs.is_empty() {
                vec![sample_data()?]
            } else {
                inputs.clone()
            },
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
            out: global.work_dir.join("bench"),
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
        // An unknown task is a usage error (exit 2), as in every command.
        let tasks = task_set(tasks)?;
        let spec = known_task(&tasks, task)?.clone();
        if !dexjoco_sim::scripted::PLANNED_TASKS.contains(&spec.id.as_str()) {
            return Err(CliError {
                message: format!("no scripted planner for '{}'", spec.id),
                hint: Some(format!(
                    "tasks with a planner: {}",
                    dexjoco_sim::scripted::PLANNED_TASKS.join(", ")
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

/// `augment`.
pub struct AugmentSettings {
    /// The library's configuration.
    pub config: AugmentConfig,
    /// Worker processes.
    pub workers: usize,
    /// EGL devices for the workers, round-robin.
    pub egl_devices: Vec<usize>,
    /// A worker's deadline for its first frame.
    pub first_frame_timeout: std::time::Duration,
    /// Plan and estimate only.
    pub dry_run: bool,
}

impl AugmentSettings {
    /// Resolves `augment`'s arguments; `sample_data` gives the default input.
    pub fn resolve(
        args: AugmentArgs,
        global: &GlobalArgs,
        sample_data: impl FnOnce() -> anyhow::Result<PathBuf>,
    ) -> anyhow::Result<Self> {
        let AugmentArgs {
            inputs,
            replays,
            scene_dir,
            camera_pool,
            cameras,
            size,
            quality,
            geometry,
            keep_failed,
            tasks,
            depth,
            dynamics,
            max_frames,
            out,
            extend_steps,
            shard,
            dry_run,
            egl_devices,
            deadline,
            overwrite,
        } = args;
        if replays == 0 {
            return Err(usage(
                "--replays 0 makes nothing".into(),
                "ask for 1 or more replays per episode",
            ));
        }
        if size == 0 || !size.is_multiple_of(2) {
            return Err(usage(
                format!("--size {size} must be even and positive (H.264 yuv420p)"),
                "use 640 (the reference) or 224",
            ));
        }
        // Read here so that a bad spec fails before any work; the worker processes read
        // the folder themselves.
        task_set(&tasks)?;
        let inputs = if inputs.is_empty() {
            vec![sample_data()?]
        } else {
            inputs
        };
        let shard = match shard.as_deref() {
            None => None,
            Some("auto") => Some(Shard::from_env(|k| std::env::var(k).ok()).map_err(|e| {
                usage(
                    e,
                    "run inside a Slurm job array or a Kubernetes Indexed Job, or give --shard I/N",
                )
            })?),
            Some(s) => Some(
                Shard::parse(s)
                    .map_err(|e| usage(format!("--shard {e}"), "for example --shard 0/4"))?,
            ),
        };
        if shard.is_some() && overwrite {
            return Err(usage(
                "--overwrite cannot be combined with --shard: the shards share the folder, and one would remove the others' replays".into(),
                "remove the output folder (or run `dexjoco-data augment --overwrite` once, unsharded) before starting the shards",
            ));
        }
        check_egl_choice(&egl_devices)?;
        let (workers, egl_devices) = render_workers(global.jobs, egl_devices);
        Ok(Self {
            workers,
            egl_devices,
            first_frame_timeout: deadline.duration(),
            dry_run,
            config: AugmentConfig {
                inputs,
                out: out.unwrap_or_else(|| global.work_dir.join("augment")),
                replays,
                tasks_dir: tasks.tasks_dir,
                seed: global.seed,
                scene: SceneSource::from_option(scene_dir),
                camera_pool,
                cameras,
                settings: RenderSettings {
                    geometry: geometry.geometry(),
                    ..render_settings(size, quality)
                },
                keep_failed,
                // 0 means whole episodes, as in `bench augment`.
                max_frames: max_frames.filter(|&m| m > 0),
                resimulate_per_replay: false,
                contact_sheet: true,
                depth,
                dynamics,
                extend_steps,
                shard,
                overwrite,
            },
        })
    }
}

/// Worker processes a GPU can feed: more contend for it and render less in all (an H200
/// at 640 px, paper preset: 8 workers 165 frames/s, 16 workers 144; README, Performance).
pub const WORKERS_PER_GPU: usize = 8;

/// Augment's rendering workers and their EGL devices: `-j` when given, else one per core
/// but at most [`WORKERS_PER_GPU`] per GPU on a GPU node; workers spread over every GPU
/// of the node unless `--egl-devices` (or `DEXJOCO_EGL_DEVICE`) chooses.
pub fn render_workers(jobs: Option<usize>, egl_devices: Vec<usize>) -> (usize, Vec<usize>) {
    let cores = dexjoco_core::available_cores();
    let gpus = dexjoco_sim::gpu_devices().unwrap_or_default();
    let requested: Option<usize> = dexjoco_sim::requested_egl_device().ok().flatten();
    // The GPUs the workers will draw on.
    let used = if !egl_devices.is_empty() {
        egl_devices
            .iter()
            .filter(|d| gpus.contains(d))
            .collect::<std::collections::BTreeSet<_>>()
            .len()
    } else if let Some(d) = requested {
        usize::from(gpus.contains(&d))
    } else {
        gpus.len()
    };
    let workers = jobs.unwrap_or(if used > 0 {
        cores.min(WORKERS_PER_GPU * used)
    } else {
        cores
    });
    // With one GPU, the default choice (that GPU, else Mesa) stays; with several and no
    // choice made, the workers are dealt over all of them.
    let egl_devices = if egl_devices.is_empty() && requested.is_none() && gpus.len() > 1 {
        gpus
    } else {
        egl_devices
    };
    (workers, egl_devices)
}

/// Checks the EGL devices asked for (`--egl-devices`, `DEXJOCO_EGL_DEVICE`) against the
/// ones EGL lists here: a value that is not an index, or an index this machine does not
/// have, is a usage error. When EGL lists nothing, the renderer's probe says so later.
pub fn check_egl_choice(egl_devices: &[usize]) -> anyhow::Result<()> {
    let env = dexjoco_sim::EGL_DEVICE_ENV;
    let requested = dexjoco_sim::requested_egl_device().map_err(|e| {
        let message = match e {
            dexjoco_sim::SimError::Egl(why) => why,
            e => e.to_string(),
        };
        usage(
            message,
            format!("unset {env}, or set it to an index that `dexjoco-data doctor` lists"),
        )
    })?;
    let Some(listed) = dexjoco_sim::list_egl_devices()
        .ok()
        .filter(|l| !l.is_empty())
    else {
        return Ok(());
    };
    let asked = egl_devices
        .iter()
        .map(|&d| (d, format!("--egl-devices {d}")))
        .chain(requested.map(|d| (d, format!("{env}={d}"))));
    for (device, what) in asked {
        if device >= listed.len() {
            let names: Vec<String> = listed
                .iter()
                .map(|d| format!("{} ({})", d.index, d.description))
                .collect();
            return Err(usage(
                format!(
                    "{what}: there is no EGL device {device} on this machine (EGL lists {}: {})",
                    listed.len(),
                    names.join(", ")
                ),
                "give device indices that `dexjoco-data doctor` lists",
            ));
        }
    }
    Ok(())
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
        Ok(Self {
            out: out
                .unwrap_or_else(|| global.work_dir.join("cameras").join(format!("{task}.json"))),
            task: spec,
            scene: SceneSource::from_option(scene_dir),
            options,
            preview,
            overwrite,
        })
    }
}

/// `convert`.
pub struct ConvertSettings {
    /// Episode stores or folders.
    pub inputs: Vec<PathBuf>,
    /// Dataset folder.
    pub out: PathBuf,
    /// Library options.
    pub options: ConvertOptions,
    /// The known tasks.
    pub tasks: TaskSet,
}

impl ConvertSettings {
    /// Resolves `convert`'s arguments.
    pub fn resolve(args: ConvertArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let ConvertArgs {
            inputs,
            input_flag,
            out,
            format,
            config,
            overwrite,
            include_failed,
            no_skip_static,
            merge_bimanual,
            exclude,
            reencode,
            video_codec,
            robot_type,
            videos,
            norm_stats,
            norm_stats_horizon,
            tasks,
        } = args;
        let tasks = task_set(&tasks)?;
        let mut inputs = inputs;
        inputs.extend(input_flag);
        if inputs.is_empty() {
            let default = global.work_dir.join("augment");
            if !default.is_dir() {
                return Err(CliError {
                    message: format!(
                        "no input: the augment stage's output {} does not exist",
                        default.display()
                    ),
                    hint: Some(
                        "pass INPUT (or --input INPUT): an episode store (`dexjoco-data ingest` makes one) or a \
                         folder of DexJoCo raw episode folders (replay.zarr + videos/)"
                            .into(),
                    ),
                    status: ExitStatus::Failure,
                }
                .into());
            }
            inputs.push(default);
        }
        for input in &inputs {
            must_exist(
                input,
                "give an episode store or a folder of DexJoCo raw episode folders",
            )?;
        }
        let (format, format_dir) = match format {
            ConvertFormatArg::DiffusionPolicy => {
                (OutputFormat::DiffusionPolicy, "diffusion-policy")
            }
            ConvertFormatArg::LerobotV21 => (OutputFormat::LeRobotV21, "lerobot-v2.1"),
            ConvertFormatArg::LerobotV3 => (OutputFormat::LeRobotV3, "lerobot-v3"),
        };
        if videos && format != OutputFormat::DiffusionPolicy {
            return Err(usage(
                "--videos applies to --format diffusion-policy only".into(),
                "LeRobot formats always carry their videos",
            ));
        }
        let out = out.unwrap_or_else(|| global.work_dir.join("convert").join(format_dir));
        let mut selection = match &config {
            None => Selection::default(),
            Some(p) if p.is_dir() => Selection::from_reference_dir(p)?,
            Some(p) => Selection::load(p)?,
        };
        if no_skip_static {
            selection.skip_static_frames = false;
        }
        if merge_bimanual {
            selection.merge_bimanual = true;
        }
        selection.bad_episodes.extend(exclude);
        Ok(Self {
            out,
            options: ConvertOptions {
                include_failed,
                protected_inputs: inputs.clone(),
                protected_dirs: vec![global.work_dir.clone()],
                format,
                videos,
                norm_stats: norm_stats.then_some(norm_stats_horizon),
                selection,
                video: VideoOptions {
                    codec: match video_codec {
                        VideoCodecArg::Av1 => VideoCodec::Av1,
                        VideoCodecArg::H264 => VideoCodec::H264,
                    },
                    reencode,
                },
                v3: V3Options {
                    robot_type: Some(robot_type),
                    ..V3Options::default()
                },
                overwrite,
                ..ConvertOptions::default()
            },
            inputs,
            tasks,
        })
    }
}

/// `stats`.
pub struct StatsSettings {
    /// Language evaluation input, when asked (None inside: the shipped example).
    pub language_eval: Option<Option<PathBuf>>,
    /// Success-table input, when asked.
    pub success_table: Option<Option<PathBuf>>,
    /// Dataset to describe, when asked.
    pub dataset: Option<PathBuf>,
    /// Output folder.
    pub out: PathBuf,
    /// Options of the language analysis.
    pub language: dexjoco_stats::LanguageOptions,
    /// JSON on stdout.
    pub json: bool,
    /// The known tasks (of `--dataset`'s episodes).
    pub tasks: TaskSet,
}

impl StatsSettings {
    /// Resolves `stats`' arguments.
    pub fn resolve(args: StatsArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let StatsArgs {
            input,
            input_flag,
            mut language_eval,
            mut success_table,
            mut dataset,
            out,
            js_base,
            alpha,
            nmi_weak,
            json,
            tasks,
        } = args;
        let tasks = task_set(&tasks)?;
        if language_eval.is_none() && success_table.is_none() && dataset.is_none() {
            return Err(usage(
                "nothing to do: say which statistics to make".into(),
                "`dexjoco-data stats --language-eval` or `--success-table` (each on the shipped example input \
                 without a path), or `--dataset` (the ingest store)",
            ));
        }
        if let Some(input) = input.or(input_flag) {
            let asked: Vec<&mut Option<Option<PathBuf>>> =
                [&mut language_eval, &mut success_table, &mut dataset]
                    .into_iter()
                    .filter(|a| a.is_some())
                    .collect();
            match asked.as_slice() {
                [Some(Some(given))] => {
                    return Err(usage(
                        format!(
                            "two inputs: '{}' and '{}'",
                            given.display(),
                            input.display()
                        ),
                        "give the input once, as INPUT or after its flag",
                    ));
                }
                [_] => {}
                _ => {
                    return Err(usage(
                        format!(
                            "INPUT '{}' with several analyses: which one is it for?",
                            input.display()
                        ),
                        "give each analysis its input after its flag, e.g. --dataset DIR --language-eval FILE",
                    ));
                }
            }
            for a in asked {
                *a = Some(Some(input.clone()));
            }
        }
        for p in [&language_eval, &success_table, &dataset]
            .into_iter()
            .flatten()
            .flatten()
        {
            must_exist(
                p,
                "give an existing file or folder (see `dexjoco-data stats --help`)",
            )?;
        }
        if !(alpha > 0.0 && alpha < 1.0) {
            return Err(usage(
                format!("--alpha {alpha} is not in (0, 1)"),
                "for example --alpha 0.01",
            ));
        }
        if !(0.0..=1.0).contains(&nmi_weak) {
            return Err(usage(
                format!("--nmi-weak {nmi_weak} is not in [0, 1]"),
                "for example --nmi-weak 0.1",
            ));
        }
        Ok(Self {
            language_eval,
            success_table,
            dataset: dataset.map(|d| d.unwrap_or_else(|| global.work_dir.join("ingest"))),
            out: out.unwrap_or_else(|| global.work_dir.join("stats")),
            language: dexjoco_stats::LanguageOptions {
                alpha,
                nmi_weak,
                js_base: match js_base {
                    JsBaseArg::Two => dexjoco_stats::LogBase::Two,
                    JsBaseArg::E => dexjoco_stats::LogBase::E,
                },
            },
            json,
            tasks,
        })
    }
}

/// Whether `path` exists (as a file, folder or link), else a failure naming it.
pub fn must_exist(path: &Path, hint: &str) -> anyhow::Result<()> {
    if fs_err::symlink_metadata(path).is_err() {
        return Err(CliError {
            message: format!("input '{}' does not exist", path.display()),
            hint: Some(hint.into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod small_fix_tests {
    use clap::Parser;

    use crate::cli::{Cli, Command};

    /// The global options and the subcommand of a command line.
    pub(super) fn parse(argv: &[&str]) -> Cli {
        Cli::parse_from(std::iter::once("dexjoco-data").chain(argv.iter().copied()))
    }

    #[test]
    fn augment_max_frames_0_means_whole_episodes_as_in_bench() {
        for (argv, expected) in [
            (&["augment", "ep", "--max-frames", "0"][..], None),
            (&["augment", "ep"][..], None),
            (&["augment", "ep", "--max-frames", "5"][..], Some(5)),
        ] {
            let cli = parse(argv);
            let Command::Augment(args) = cli.command else {
                panic!("parsed another command");
            };
            let settings = super::AugmentSettings::resolve(args, &cli.global, || unreachable!())
                .expect("resolves");
            assert_eq!(settings.config.max_frames, expected, "{argv:?}");
        }
    }

    #[test]
    fn render_bench_scripted_and_doctor_resolve_their_settings() {
        let cli = parse(&[
            "-q",
            "--work-dir",
            "w",
            "render",
            "--size",
            "32",
            "--width",
            "64",
        ]);
        let Command::Render(args) = &cli.command else {
            panic!("parsed another command");
        };
        let render = super::RenderCommandSettings::resolve(args, &cli.global).unwrap();
        assert_eq!((render.render.width, render.render.height), (64, 32));
        assert_eq!(render.out, std::path::Path::new("w/render"));
        assert!(render.quiet && render.video_fps.is_none());
        let cli = parse(&["render", "--video"]);
        let Command::Render(args) = &cli.command else {
            panic!("parsed another command");
        };
        let video = super::RenderCommandSettings::resolve(args, &cli.global).unwrap();
        assert_eq!(video.video_fps, Some(30));
        let cli = parse(&["render", "--tasks-dir", "specs"]);
        let Command::Render(args) = &cli.command else {
            panic!("parsed another command");
        };
        let err = super::RenderCommandSettings::resolve(args, &cli.global)
            .err()
            .unwrap();
        assert!(
            err.to_string()
                .contains("--tasks-dir applies to --task only")
        );

        let cli = parse(&["-j", "3", "bench", "ingest", "--episodes", "2"]);
        let Command::Bench(crate::cli::BenchCommand::Ingest(args)) = &cli.command else {
            panic!("parsed another command");
        };
        let ingest = super::BenchIngestSettings::resolve(args, &cli.global);
        assert_eq!((ingest.episodes, ingest.threads), (2, 3));
        let cli = parse(&["bench", "render"]);
        let Command::Bench(crate::cli::BenchCommand::Render(args)) = &cli.command else {
            panic!("parsed another command");
        };
        assert_eq!(
            super::BenchRenderSettings::resolve(args, &cli.global)
                .unwrap()
                .presets
                .len(),
            4
        );

        let cli = parse(&[
            "--seed",
            "9",
            "scripted",
            "--task",
            "click_mouse",
            "--out",
            "o",
        ]);
        let Command::Scripted(args) = &cli.command else {
            panic!("parsed another command");
        };
        let scripted = super::ScriptedSettings::resolve(args, &cli.global).unwrap();
        assert_eq!(scripted.seed, 9);

        let cli = parse(&[
            "--seed",
            "4",
            "bench",
            "augment",
            "ep",
            "--workers",
            "4,1,4",
        ]);
        let Command::Bench(crate::cli::BenchCommand::Augment(args)) = &cli.command else {
            panic!("parsed another command");
        };
        let bench =
            super::BenchAugmentSettings::resolve(args, &cli.global, || unreachable!()).unwrap();
        assert_eq!((bench.workers, bench.seed), (vec![1, 4], 4));

        let cli = parse(&["doctor", "--json"]);
        let Command::Doctor(args) = &cli.command else {
            panic!("parsed another command");
        };
        assert!(super::DoctorSettings::resolve(args, &cli.global).json);
    }
}
