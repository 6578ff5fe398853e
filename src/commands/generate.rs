//! `dexjoco-data generate`: new demonstrations at new object poses from a few source
//! episodes, subtask by subtask (see `dexjoco_generate`); sources that cannot serve are
//! named and left out, the rest of the run goes on.

use anyhow::Context;
use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_generate::{GenerateConfig, SourceDemo};
use dexjoco_sim::{Scene, load_task_scene};
use rayon::prelude::*;

use crate::cli::{GenerateArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::GenerateSettings;

/// Runs `generate`.
pub fn run(global: &GlobalArgs, args: GenerateArgs) -> anyhow::Result<ExitStatus> {
    let GenerateSettings {
        task,
        tasks,
        inputs,
        scene,
        config,
        dry_run,
        quiet,
    } = GenerateSettings::resolve(args, global, super::augment::sample_data)?;
    let scene = load_task_scene(&scene, &task)?;
    let (sources, left_out) = sources(&inputs, &tasks, &task, &scene, config.extend_steps)?;
    for (name, why) in &left_out {
        errln!("source left out: {name}: {why}");
    }
    if sources.is_empty() {
        return Err(CliError {
            message: format!(
                "no source episode of '{}' can serve ({} left out)",
                task.id,
                left_out.len()
            ),
            hint: Some(
                "give episodes of the task that replay to success on this scene (the same \
                 --scene-dir they were recorded on), e.g. from `dexjoco-data scripted`"
                    .into(),
            ),
            status: ExitStatus::Failure,
        }
        .into());
    }
    if let Some(pilot) = dry_run {
        return print_pilot(&config, &scene, &task, &sources, pilot);
    }
    let bar = Bar::new("generate", quiet);
    let outcome = dexjoco_generate::generate(&config, &scene, &task, &sources, &bar)
        .with_context(|| format!("generating into {}", config.out.display()))?;
    bar.finish();
    let r = &outcome.report;
    if let Some(shard) = config.shard {
        outln!(
            "generate shard {shard}: {} attempt(s) made now ({:.2} s each) into {}; run the same command without --shard after every shard for the report",
            outcome.attempts_now,
            outcome.attempt_seconds / outcome.attempts_now.max(1) as f64,
            config.out.display()
        );
        return Ok(if left_out.is_empty() {
            ExitStatus::Success
        } else {
            ExitStatus::Partial
        });
    }
    outln!(
        "generate {}: {} episode(s) from {} attempt(s) ({:.0} %; {} made now, {:.2} s each) from {} source(s), in {}",
        r.task,
        r.successes,
        r.attempts,
        100.0 * r.success_rate(),
        outcome.attempts_now,
        outcome.attempt_seconds / outcome.attempts_now.max(1) as f64,
        sources.len(),
        config.out.display()
    );
    for s in &r.subtasks {
        outln!(
            "  {:<24} started {:>5}  completed {:>5}  failed at {:>5}",
            s.subtask,
            s.started,
            s.completed,
            s.failed_at
        );
    }
    Ok(if r.successes == 0 {
        ExitStatus::Failure
    } else if r.successes.min(config.count) < config.count || !left_out.is_empty() {
        ExitStatus::Partial
    } else {
        ExitStatus::Success
    })
}

/// A source left out: its path, and why.
type LeftOut = (String, String);

/// The source episodes under `inputs` prepared for `spec` (replayed, cut at subtasks),
/// in discovery order, and those left out with why.
fn sources(
    inputs: &[std::path::PathBuf],
    tasks: &TaskSet,
    spec: &TaskSpec,
    scene: &Scene,
    extend_steps: usize,
) -> anyhow::Result<(Vec<SourceDemo>, Vec<LeftOut>)> {
    let found = dexjoco_formats::discover(inputs, None)?;
    if found.is_empty() {
        return Err(CliError {
            message: format!(
                "no episodes found under {}",
                inputs
                    .iter()
                    .map(|p| format!("'{}'", p.display()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            hint: Some("give raw episode folders, episode stores or MCAP files".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let prepared: Vec<(String, Result<SourceDemo, String>)> = found
        .par_iter()
        .map(|source| {
            let name = source.path.display().to_string();
            let read = match source.read_checked(tasks) {
                Ok(r) => r,
                Err(e) => return (name, Err(e.to_string())),
            };
            if read.episode.task != spec.id {
                let why = format!("an episode of '{}', not '{}'", read.episode.task, spec.id);
                return (name, Err(why));
            }
            let demo = SourceDemo::prepare(scene, spec, &read.episode, extend_steps)
                .map_err(|e| e.to_string());
            (name, demo)
        })
        .collect();
    let mut ok = Vec::new();
    let mut left_out = Vec::new();
    for (name, r) in prepared {
        match r {
            Ok(d) => ok.push(d),
            Err(why) => left_out.push((name, why)),
        }
    }
    Ok((ok, left_out))
}

/// `--dry-run`: a pilot of the first attempts, nothing written.
fn print_pilot(
    config: &GenerateConfig,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    pilot: usize,
) -> anyhow::Result<ExitStatus> {
    let (ok, seconds) = dexjoco_generate::pilot(config, scene, spec, sources, pilot)?;
    let rate = ok as f64 / pilot as f64;
    outln!(
        "pilot ({} source(s)): {ok} of {pilot} attempt(s) succeeded ({:.0} %), {seconds:.2} s per attempt on one worker",
        sources.len(),
        100.0 * rate
    );
    if ok == 0 {
        outln!(
            "no attempt of the pilot succeeded: --count {} is not expected within --max-attempts {}; \
             try more or other sources, or a larger --pilot",
            config.count,
            config.max_attempts
        );
        return Ok(ExitStatus::Partial);
    }
    let expected = (config.count as f64 / rate).ceil() as usize;
    let workers = config.workers.max(1);
    outln!(
        "--count {} expects about {expected} attempt(s) ({} allowed by --max-attempts): about {:.0} s with {workers} worker(s)",
        config.count,
        config.max_attempts,
        expected.min(config.max_attempts) as f64 * seconds / workers as f64
    );
    Ok(ExitStatus::Success)
}
