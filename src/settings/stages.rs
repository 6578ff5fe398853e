//! Settings of the pipeline stages: ingest, export, augment, convert, stats.

use super::*;

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
        let tasks_dir = tasks.tasks_dir.clone();
        let tasks = task_set(&tasks)?;
        if let Some(t) = &task {
            known_task(&tasks, t)?;
        }
        non_negative("--quat-tolerance", quat_tolerance)?;
        non_negative("--timestep-tolerance", timestep_tolerance)?;
        let store = out.unwrap_or_else(|| global.work_dir.join("ingest"));
        outputs_apart(&[&store], &reads(&inputs, &[tasks_dir.as_deref()]))?;
        Ok(Self {
            inputs,
            store,
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
        let out = out.unwrap_or_else(|| global.work_dir.join("export"));
        outputs_apart(&[&out], &reads(&inputs, &[tasks.tasks_dir.as_deref()]))?;
        Ok(Self {
            inputs,
            out,
            container: match to {
                ExportFormat::Mcap => &McapLog,
            },
            overwrite,
            tasks: task_set(&tasks)?,
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

/// `--shard I/N` or `auto` (from the cluster's environment); refused with `--overwrite`.
pub(crate) fn shard_of(shard: Option<&str>, overwrite: bool) -> anyhow::Result<Option<Shard>> {
    let shard = match shard {
        None => return Ok(None),
        Some("auto") => Shard::from_env(|k| std::env::var(k).ok()).map_err(|e| {
            usage(
                e.to_string(),
                "run inside a Slurm job array or a Kubernetes Indexed Job, or give --shard I/N",
            )
        })?,
        Some(s) => {
            Shard::parse(s).map_err(|e| usage(format!("--shard {e}"), "for example --shard 0/4"))?
        }
    };
    if overwrite {
        return Err(usage(
            "--overwrite cannot be combined with --shard: the shards share the folder, and one would remove the others' replays".into(),
            "remove the output folder (or run `dexjoco-data augment --overwrite` once, unsharded) before starting the shards",
        ));
    }
    Ok(Some(shard))
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
            workers:
                WorkerArgs {
                    egl_devices,
                    deadline,
                },
            overwrite,
            video,
            renderer,
        } = args;
        let (renderer, warp) = renderer.resolve();
        if renderer == dexjoco_render::RendererKind::Warp
            && geometry != crate::cli::GeometryArg::Full
        {
            return Err(usage(
                "--geometry light simplifies OpenGL's meshes; the Warp renderer traces the full ones".into(),
                "leave --geometry out with --renderer warp",
            ));
        }
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
        let shard = shard_of(shard.as_deref(), overwrite)?;
        check_egl_choice(&egl_devices)?;
        let out = out.unwrap_or_else(|| global.work_dir.join("augment"));
        let others = [
            scene_dir.as_deref(),
            camera_pool.as_deref(),
            tasks.tasks_dir.as_deref(),
        ];
        outputs_apart(&[&out], &reads(&inputs, &others))?;
        let (workers, egl_devices) = render_workers(global.jobs, egl_devices);
        Ok(Self {
            workers,
            egl_devices,
            first_frame_timeout: deadline.duration(),
            dry_run,
            config: AugmentConfig {
                inputs,
                out,
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
                video: video.encoding(),
                renderer,
                warp,
            },
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

/// `convert`'s inputs: INPUT and `--input`, else `<work-dir>/augment`; each must exist.
fn convert_inputs(
    mut inputs: Vec<PathBuf>,
    input_flag: Vec<PathBuf>,
    global: &GlobalArgs,
) -> anyhow::Result<Vec<PathBuf>> {
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
    Ok(inputs)
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
            instructions,
            overwrite,
            include_failed,
            include_flagged,
            privileged_state,
            environment_state,
            depth,
            no_skip_static,
            merge_bimanual,
            exclude,
            reencode,
            video_codec,
            robot_type,
            videos,
            norm_stats,
            tasks,
        } = args;
        let tasks_dir = tasks.tasks_dir.clone();
        let tasks = task_set(&tasks)?;
        let inputs = convert_inputs(inputs, input_flag, global)?;
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
        outputs_apart(
            &[&out],
            &reads(
                &inputs,
                &[
                    config.as_deref(),
                    tasks_dir.as_deref(),
                    instructions.as_deref(),
                ],
            ),
        )?;
        let mut selection = selection_of(config.as_deref(), &tasks, instructions.as_deref())?;
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
                include_flagged,
                state_features: state_features(&tasks, environment_state, privileged_state),
                depth,
                protected_inputs: inputs.clone(),
                protected_dirs: vec![global.work_dir.clone()],
                format,
                videos,
                norm_stats: norm_stats_options(&norm_stats),
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

/// openpi's normalization statistics options, when `--norm-stats` asks for them.
pub(crate) fn norm_stats_options(args: &NormStatsArgs) -> Option<NormStatsOptions> {
    args.norm_stats.then_some(NormStatsOptions {
        action_horizon: args.norm_stats_horizon,
        batch_size: args.norm_stats_batch,
    })
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
        let tasks_dir = tasks.tasks_dir.clone();
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
        let out = out.unwrap_or_else(|| global.work_dir.join("stats"));
        let dataset = dataset.map(|d| d.unwrap_or_else(|| global.work_dir.join("ingest")));
        let given: Vec<PathBuf> = [&language_eval, &success_table]
            .into_iter()
            .flatten()
            .flatten()
            .chain(&dataset)
            .cloned()
            .collect();
        outputs_apart(&[&out], &reads(&given, &[tasks_dir.as_deref()]))?;
        Ok(Self {
            language_eval,
            success_table,
            dataset,
            out,
            language: language_options(alpha, nmi_weak, js_base)?,
            json,
            tasks,
        })
    }
}

/// The language analysis' options, checked.
fn language_options(
    alpha: f64,
    nmi_weak: f64,
    js_base: JsBaseArg,
) -> anyhow::Result<dexjoco_stats::LanguageOptions> {
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
    Ok(dexjoco_stats::LanguageOptions {
        alpha,
        nmi_weak,
        js_base: match js_base {
            JsBaseArg::Two => dexjoco_stats::LogBase::Two,
            JsBaseArg::E => dexjoco_stats::LogBase::E,
        },
    })
}

/// The state features `convert` exports beyond the proprioception, if any.
fn state_features(
    tasks: &dexjoco_core::TaskSet,
    environment: bool,
    privileged: bool,
) -> Option<dexjoco_convert::StateFeatures> {
    (environment || privileged).then(|| dexjoco_convert::StateFeatures {
        tasks: tasks.clone(),
        environment,
        privileged,
    })
}

/// The selection of a convert `--config` (a file, the reference's config folder, or the
/// defaults), with the task set's prompt variants (a `--tasks-dir` spec's too), then an
/// `--instructions` file's.
fn selection_of(
    config: Option<&Path>,
    tasks: &dexjoco_core::TaskSet,
    instructions: Option<&Path>,
) -> anyhow::Result<Selection> {
    let mut selection = match config {
        None => Selection::default(),
        Some(p) if p.is_dir() => Selection::from_reference_dir(p)?,
        Some(p) => Selection::load(p)?,
    };
    for spec in tasks.iter() {
        (selection.prompt_variants)
            .entry(spec.id.clone())
            .or_insert_with(|| spec.prompt_variants.clone());
    }
    if let Some(path) = instructions {
        selection.load_prompt_variants(path)?;
    }
    Ok(selection)
}
