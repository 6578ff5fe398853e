//! Settings of each pipeline command, resolved once from its arguments and the global
//! options (defaults from the work folder, checks of values), the way uv does it: every
//! `resolve` destructures the whole arguments struct, so a new flag that is not handled
//! here fails to compile.
//!
//! `stages.rs`: the pipeline stages (ingest, export, augment, convert, stats); `eval.rs`:
//! the policy evaluation; `generate.rs`: the demonstration generator;
//! `tools.rs`: the other commands (render, bench, doctor, scripted, cameras); here what
//! they share (task sets, usage errors, EGL device choice, worker counts).

use std::path::{Path, PathBuf};

use dexjoco_augment::{AugmentConfig, Shard};
use dexjoco_convert::{
    ConvertOptions, NormStatsOptions, OutputFormat, Selection, V3Options, VideoCodec, VideoOptions,
};
use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_formats::EpisodeContainer;
use dexjoco_formats::mcap::McapLog;
use dexjoco_ingest::{IngestOptions, ValidationOptions};
use dexjoco_render::{RenderQuality, RenderSettings};
use dexjoco_sim::SceneSource;

use crate::cli::{
    AugmentArgs, BenchAugmentArgs, BenchIngestArgs, BenchRenderArgs, CamerasArgs, ConvertArgs,
    ConvertFormatArg, DoctorArgs, ExportArgs, ExportFormat, GlobalArgs, IngestArgs, JsBaseArg,
    NormStatsArgs, QualityArg, RenderArgs, ScriptedArgs, StatsArgs, TasksDirArgs, VideoCodecArg,
    WorkerArgs,
};
use crate::exit::{CliError, ExitStatus};

mod dataset;
mod eval;
mod generate;
mod stages;
mod tools;

pub use dataset::*;
pub use eval::*;
pub use generate::*;
pub use stages::*;
pub use tools::*;

/// A usage error (exit code 2) with a hint.
pub fn usage(message: String, hint: impl Into<String>) -> anyhow::Error {
    CliError {
        message,
        hint: Some(hint.into()),
        status: ExitStatus::Usage,
    }
    .into()
}

/// The rule of every command that writes, applied before anything is written: an output
/// that is, holds or lies inside one of the command's inputs (links resolved) is a usage
/// error (exit 2) naming both paths ([`dexjoco_formats::fs::first_overlap`]).
pub fn outputs_apart(outputs: &[&Path], inputs: &[&Path]) -> anyhow::Result<()> {
    match dexjoco_formats::fs::first_overlap(outputs, inputs) {
        None => Ok(()),
        Some((out, input, how)) => Err(usage(
            format!(
                "the output '{}' {} the input '{}'{}",
                out.display(),
                how.words(),
                input.display(),
                resolved_note(out, input),
            ),
            "a command never writes into, over or around what it reads: choose an output \
             folder apart from every input (--out, or --work-dir for the default outputs)",
        )),
    }
}

/// ` (links resolved: 'A' and 'B')` when a link makes the two paths meet, else nothing.
fn resolved_note(out: &Path, input: &Path) -> String {
    use dexjoco_formats::fs::resolve;
    let (ro, ri) = (resolve(out), resolve(input));
    let plain = |p: &Path| {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    };
    if ro == plain(out) && ri == plain(input) {
        String::new()
    } else {
        format!(
            " (links resolved: '{}' and '{}')",
            ro.display(),
            ri.display()
        )
    }
}

/// What a command reads: its inputs and the other paths it was given.
pub fn reads<'a>(inputs: &'a [PathBuf], others: &[Option<&'a Path>]) -> Vec<&'a Path> {
    inputs
        .iter()
        .map(PathBuf::as_path)
        .chain(others.iter().flatten().copied())
        .collect()
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
        geometry: dexjoco_render::Geometry::Full,
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
    let gpus = dexjoco_render::gpu_devices().unwrap_or_default();
    let requested: Option<usize> = dexjoco_render::requested_egl_device().ok().flatten();
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
    let env = dexjoco_render::EGL_DEVICE_ENV;
    let requested = dexjoco_render::requested_egl_device().map_err(|e| {
        let message = match e {
            dexjoco_render::RenderError::Egl(why) => why.to_string(),
            e => e.to_string(),
        };
        usage(
            message,
            format!("unset {env}, or set it to an index that `dexjoco-data doctor` lists"),
        )
    })?;
    let Some(listed) = dexjoco_render::list_egl_devices()
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
