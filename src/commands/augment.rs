//! `dexjoco-data augment`: randomized, validated replays of episodes, rendered from one
//! simulation per episode, written in the DexJoCo raw layout with a report.

use std::path::PathBuf;

use anyhow::Context;
use dexjoco_augment::{AugmentConfig, AugmentError, Executor, WorkerProcesses, augment_with};

use crate::cli::{AugmentArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::AugmentSettings;

/// The sample data's demonstrations (`demos/` of [`crate::locate::data_dir`]).
pub(crate) fn sample_data() -> anyhow::Result<PathBuf> {
    crate::locate::data_dir()
        .map(|d| d.path.join("demos"))
        .filter(|p| p.is_dir())
        .ok_or_else(|| {
            CliError {
                message: "no input given and the sample data (datasets/demos) is not found".into(),
                hint: Some(format!(
                    "pass raw episode folders, an episode store or MCAP files; or point ${} at a \
                     datasets folder (looked beside the binary, in a bundle's share/dexjoco-data, \
                     and in the current folder)",
                    crate::locate::DATA_ENV
                )),
                status: ExitStatus::Failure,
            }
            .into()
        })
}

/// Runs `augment`.
pub fn run(global: &GlobalArgs, args: AugmentArgs) -> anyhow::Result<ExitStatus> {
    let AugmentSettings {
        config,
        workers,
        egl_devices,
        first_frame_timeout,
        dry_run,
    } = AugmentSettings::resolve(args, global, sample_data)?;
    if dry_run {
        return print_plan(&config, workers);
    }
    let out = config.out.clone();
    let executor = Executor::Processes(
        WorkerProcesses::new(
            std::env::current_exe().context("locating the dexjoco-data binary")?,
            worker_args(global, "augment-worker"),
            workers,
        )
        .with_egl_devices(egl_devices)
        .with_first_frame_timeout(first_frame_timeout),
    );
    let bar = Bar::new("augment", global.quiet);
    let started = std::time::Instant::now();
    let report = augment_with(&config, &executor, &bar)
        .map_err(early_error)
        .with_context(|| format!("augmenting into {}", out.display()))?;
    bar.finish();
    let seconds = started.elapsed().as_secs_f64();
    if let Some(shard) = config.shard {
        outln!(
            "augment shard {shard}: {} replay(s) rendered now into {} ({seconds:.1} s); run the same command without --shard after every shard for the report",
            report.rendered_now,
            out.display(),
        );
    } else {
        let failed = report.failed_episodes();
        outln!(
            "augment: {} episode(s) replayed to success, {failed} failed; {} replay(s) in {} ({} rendered now, {seconds:.1} s)",
            report.episodes.len() - failed,
            report.replays.len(),
            out.display(),
            report.rendered_now,
        );
        let extended = report.episodes.iter().filter(|e| e.extended).count();
        if extended > 0 {
            outln!(
                "  {extended} episode(s) succeeded only after their recording ended (--extend-steps): see the report's shift column"
            );
        }
    }
    if report.times.frames > 0 {
        outln!(
            "  where a frame's time went (bottleneck: {}): {}",
            report.times.bottleneck(),
            report.times.summary()
        );
    }
    if !report.dropped.is_empty() {
        outln!(
            "  {} replay(s) failed under their --dynamics draw and were dropped (--keep-failed keeps them)",
            report.dropped.len()
        );
    }
    for k in &report.skipped {
        outln!("  SKIPPED: {}: {}", k.source, k.reason);
    }
    for u in &report.failed_units {
        outln!(
            "  UNIT FAILED: {}/{} replays {:?}: {} (run again to redo it)",
            u.task,
            u.episode,
            u.replays,
            u.reason
        );
    }
    for e in report.episodes.iter().filter(|e| !e.success) {
        outln!(
            "  FAILED: {}/{} (max state deviation {:e})",
            e.task,
            e.episode,
            e.max_state_deviation
        );
    }
    if config.shard.is_none() {
        outln!("report: {}", out.join(dexjoco_augment::REPORT_MD).display());
    }
    warn_flagged(&report, &config);
    let partial = report.failed_episodes() > 0
        || !report.skipped.is_empty()
        || !report.failed_units.is_empty();
    Ok(if partial {
        ExitStatus::Partial
    } else {
        ExitStatus::Success
    })
}

/// The warning, on stderr, that render checks flagged replays: how many, where they are
/// listed, and that `convert` leaves them out.
fn warn_flagged(report: &dexjoco_augment::AugmentReport, config: &AugmentConfig) {
    if report.flagged.is_empty() {
        return;
    }
    let listed = if config.shard.is_some() {
        "in their replay.json `flags` (the run without --shard lists them in its report)".to_owned()
    } else {
        format!(
            "under \"Flagged replays\" in {} (`flagged` in {})",
            config.out.join(dexjoco_augment::REPORT_MD).display(),
            dexjoco_augment::REPORT_JSON
        )
    };
    errln!(
        "warning: {} replay(s) failed a render check (blank frames, a frozen video, NaN or infinity), listed {listed}; they are kept, but `convert` leaves them out unless --include-flagged",
        report.flagged.len()
    );
    for f in report.flagged.iter().take(5) {
        let first = f.flags.first().map(|x| x.describe()).unwrap_or_default();
        errln!("  FLAGGED: {}/{}: {first}", f.task, f.replay);
    }
    if report.flagged.len() > 5 {
        errln!("  ... and {} more", report.flagged.len() - 5);
    }
}

/// The errors augment finds before spending any work, with their exit status and hint: a
/// `--camera` a scene lacks (usage), a renderer that does not open (failure).
fn early_error(e: AugmentError) -> anyhow::Error {
    match e {
        AugmentError::Usage(message) => CliError {
            message,
            hint: Some("name cameras the task's scene has; nothing was written".into()),
            status: ExitStatus::Usage,
        }
        .into(),
        AugmentError::RenderingUnavailable { .. } => CliError {
            message: e.to_string(),
            hint: Some(
                "`dexjoco-data doctor` lists the EGL devices and whether each renders; \
                 --egl-devices (or DEXJOCO_EGL_DEVICE) picks one. Nothing was written"
                    .into(),
            ),
            status: ExitStatus::Failure,
        }
        .into(),
        e => e.into(),
    }
}

/// The arguments that start this binary as a worker (`augment-worker`, `eval-worker`),
/// with the same logging.
pub(crate) fn worker_args(global: &GlobalArgs, command: &str) -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = Vec::new();
    if global.quiet {
        args.push("-q".into());
    }
    for _ in 0..global.verbose {
        args.push("-v".into());
    }
    args.push(command.into());
    args
}

/// The channel of a worker process (`augment-worker`, `eval-worker`) to its parent: the
/// stdin it was given, and a copy of the stdout it was given; stdout itself then points at
/// stderr, so that whatever a library prints (a driver's notice, a C library's printf)
/// cannot corrupt the messages.
pub(crate) fn worker_channel() -> anyhow::Result<(std::io::StdinLock<'static>, std::fs::File)> {
    let messages = rustix::io::dup(std::io::stdout()).context("duplicating stdout")?;
    rustix::stdio::dup2_stdout(std::io::stderr()).context("pointing stdout at stderr")?;
    Ok((std::io::stdin().lock(), std::fs::File::from(messages)))
}

/// Runs `augment-worker` (started by `augment`).
pub fn run_worker() -> anyhow::Result<ExitStatus> {
    let (input, output) = worker_channel()?;
    dexjoco_augment::serve_worker(input, output)?;
    Ok(ExitStatus::Success)
}

/// `augment --dry-run`: the plan and an estimate.
fn print_plan(config: &AugmentConfig, workers: usize) -> anyhow::Result<ExitStatus> {
    let plan = dexjoco_augment::dry_run(config, 30)?;
    let share = config
        .shard
        .map_or_else(String::new, |s| format!(" (shard {s})"));
    outln!(
        "Plan{share}: {} task(s), {} camera(s) per replay, {}x{} {}",
        plan.tasks.len(),
        plan.cameras,
        config.settings.width,
        config.settings.height,
        config.settings.quality.name()
    );
    outln!();
    outln!(
        "| task | episodes | replays | done | frames to render | calibrated frames/s (1 worker) |"
    );
    outln!("|---|---:|---:|---:|---:|---:|");
    for t in &plan.tasks {
        outln!(
            "| {} | {} | {} | {} | {} | {} |",
            t.task,
            t.episodes,
            t.replays,
            t.done,
            t.frames_to_render,
            t.frames_per_s.map_or("-".into(), |f| format!("{f:.1}"))
        );
    }
    let replays: usize = plan.tasks.iter().map(|t| t.replays).sum();
    let done: usize = plan.tasks.iter().map(|t| t.done).sum();
    outln!(
        "| **all** | {} | {replays} | {done} | {} | |",
        plan.tasks.iter().map(|t| t.episodes).sum::<usize>(),
        plan.frames_to_render()
    );
    for (source, reason) in &plan.skipped {
        outln!("SKIPPED: {source}: {reason}");
    }
    if !plan.settings_differ.is_empty() {
        outln!();
        outln!(
            "{} was made with other settings ({}): this run would be refused; pass --overwrite to start clean (the done counts above would be redone)",
            config.out.display(),
            plan.settings_differ.join("; ")
        );
    }
    if let Some(t) = plan.times() {
        outln!();
        outln!(
            "Where a frame's time goes here (calibration, per frame; the bottleneck is {}):",
            t.bottleneck()
        );
        outln!("  {}", t.summary());
    }
    outln!();
    if let Some(s) = plan.seconds_one_worker {
        let cores = dexjoco_core::available_cores();
        let here = workers.min(cores).max(1);
        outln!(
            "Estimate (calibrated: 30 frames of each scene rendered, encoded and stepped here):"
        );
        outln!("  {:<28} {}", "1 worker process:", duration(s));
        outln!(
            "  {:<28} {} (assumes {here} process(es) scale linearly; `dexjoco-data bench augment` measures it)",
            format!("-j {workers} on this machine:"),
            duration(s / here as f64)
        );
        for nodes in [4, 16, 64] {
            outln!(
                "  {:<28} {} (--shard over {nodes} nodes, -j {here} each)",
                format!("{nodes} nodes like this one:"),
                duration(s / (here * nodes) as f64)
            );
        }
        outln!(
            "  A replay that needs its extension adds up to {} frames per camera.",
            config.extend_steps
        );
    }
    Ok(ExitStatus::Success)
}

fn duration(seconds: f64) -> String {
    let s = seconds.round() as u64;
    match s {
        0..=119 => format!("{s} s"),
        120..=7199 => format!("{:.1} min", seconds / 60.0),
        7200..=172_799 => format!("{:.1} h", seconds / 3600.0),
        _ => format!("{:.1} days", seconds / 86400.0),
    }
}
