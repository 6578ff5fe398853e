//! A generation run into one task's output folder: attempts in index order (attempt k
//! starts from reset k of the seed's draws, as `scripted --seed` and `eval --seed` draw
//! them), computed in parallel in batches and committed in order, so the same seed gives
//! the same episodes whatever the worker count; a killed run continues with the attempts
//! it lacks.
//!
//! ```text
//! <out>/episode_NNNNNN/replay.zarr       a successful attempt N (raw layout), NNNNNN = N
//! <out>/episode_NNNNNN/generate.json     its record: reset, provenance, subtasks
//! <out>/.attempts/attempt_NNNNNN.json    every finished attempt's record (the resume log)
//! <out>/.failed/attempt_NNNNNN/          with keep_failed: a failed attempt's episode and record
//! <out>/generate_settings.json           what decides the bytes (a resume must match)
//! <out>/generate_report.json, .md        attempts, successes, per-subtask outcomes
//! <out>/generate_poses.png               placed objects at reset: sources, successes, failures
//! <out>/generate_sheet.png               the kept episodes' first frames (pixels vary by renderer)
//! <out>/generate_times.json              seconds per attempt (varies by machine)
//! ```

use std::collections::BTreeMap;

use dexjoco_core::{Progress, TaskSpec};
use dexjoco_formats::write_atomic;
use dexjoco_sim::{Scene, TaskEnv};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::attempt::{Attempt, attempt};
use crate::error::GenerateError;
use crate::folder;
use crate::record::{
    AttemptRecord, GenerateConfig, GenerateReport, POSES_FIGURE, SHEET, SubtaskOutcome, TIMES_FILE,
};
use crate::source::SourceDemo;

/// Draws resets in the seed's order, as `scripted --seed` draws them; asked for in
/// increasing order, it keeps none of them (a run of millions of attempts draws them
/// one after another).
struct Resets<'a> {
    scene: &'a Scene,
    spec: &'a TaskSpec,
    rng: rand_chacha::ChaCha8Rng,
    /// The index of the next draw.
    next: usize,
}

impl<'a> Resets<'a> {
    fn new(scene: &'a Scene, spec: &'a TaskSpec, seed: u64) -> Self {
        Self {
            scene,
            spec,
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed),
            next: 0,
        }
    }

    /// Reset `k` (`k` at least every index asked for before).
    fn get(&mut self, k: usize) -> Result<Vec<f64>, GenerateError> {
        assert!(k >= self.next, "resets are drawn in increasing order");
        loop {
            let rng = &mut self.rng;
            let s =
                TaskEnv::sample_initial_state(self.scene, self.spec, &mut || rng.random::<f64>())?;
            self.next += 1;
            if self.next > k {
                return Ok(s);
            }
        }
    }
}

/// What a call of [`generate`] did, beside the folder's report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GenerateOutcome {
    /// The folder's report (every run into it).
    pub report: GenerateReport,
    /// Attempts made by this call.
    pub attempts_now: usize,
    /// Seconds those attempts took, summed over the workers.
    pub attempt_seconds: f64,
}

/// How often a shard reads the other shards' records (a shared file system may hold
/// many).
const SHARD_SYNC: std::time::Duration = std::time::Duration::from_secs(10);

/// Runs attempts until `count` succeeded or `max_attempts` were made, committing each in
/// index order; writes the folder's report and returns it with this call's work.
///
/// A shard (`config.shard`, `I/N`) makes only the attempts `k` with `k % N == I`, in
/// order, into the folder the other shards share, and stops once the attempts every
/// shard finished hold `count` successes before its next one (or at `max_attempts`); it
/// writes no report. The unsharded run afterwards (the finalize step) makes the attempts
/// still missing before the `count`-th success, sets aside those past it (`.surplus/`, put
/// back by a later run that needs them) and writes the report: the folder then holds what
/// one unsharded run writes.
pub fn generate(
    config: &GenerateConfig,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    progress: &dyn Progress,
) -> Result<GenerateOutcome, GenerateError> {
    if sources.is_empty() {
        return Err(GenerateError::Spec("no source episodes".into()));
    }
    let out = &config.out;
    fs_err::create_dir_all(out.join(".attempts"))?;
    let _lock = dexjoco_formats::lock::lock_output(out, config.shard)?;
    // A resume writes into the folders it finds: none may be a link leading elsewhere.
    dexjoco_formats::fs::refuse_links_within(out)?;
    folder::check_settings(
        out,
        &folder::settings(config, spec, sources)?,
        config.overwrite,
    )?;
    if config.shard.is_none() {
        folder::restore_surplus(out, spec, config.seed)?;
    }
    folder::clean_up(out, config.shard)?;
    let log = folder::finished(out, spec, config.seed)?;
    folder::forget(out, &log)?;
    let mut done = log.done;
    let work = attempt_loop(config, scene, spec, sources, progress, &mut done)?;
    if config.shard.is_some() {
        let report = report(spec, config, sources, &done);
        return Ok(GenerateOutcome { report, ..work });
    }
    let end = end_of_run(&done, config);
    folder::set_aside(out, &mut done, end)?;
    folder::remove_staging(out)?;
    let report = report(spec, config, sources, &done);
    write_outputs(config, scene, spec, sources, &done, &report, &work)?;
    Ok(GenerateOutcome { report, ..work })
}

/// Where an unsharded run with `config` stops: after the `count`-th success in attempt
/// order, else at `max_attempts`.
fn end_of_run(done: &BTreeMap<usize, AttemptRecord>, config: &GenerateConfig) -> usize {
    done.values()
        .filter(|r| r.success)
        .nth(config.count.saturating_sub(1))
        .map_or(config.max_attempts, |r| {
            (r.attempt + 1).min(config.max_attempts)
        })
}

/// Successes among the attempts before `k`.
fn successes_before(done: &BTreeMap<usize, AttemptRecord>, k: usize) -> usize {
    done.range(..k).filter(|(_, r)| r.success).count()
}

/// Makes the missing attempts (this shard's, or all) in batches, committing each in
/// index order, until `count` successes or `max_attempts`; returns this call's work.
fn attempt_loop(
    config: &GenerateConfig,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    progress: &dyn Progress,
    done: &mut BTreeMap<usize, AttemptRecord>,
) -> Result<GenerateOutcome, GenerateError> {
    let out = &config.out;
    let mut resets = Resets::new(scene, spec, config.seed);
    let mine = |k: &usize| config.shard.is_none_or(|s| k % s.count == s.index);
    // Successes among the records (kept up to date as attempts are committed).
    let mut ok = successes_before(done, usize::MAX);
    progress.start(config.count as u64);
    progress.advance(ok.min(config.count) as u64, "");
    let pool = worker_pool(config)?;
    let batch = (config.workers.max(1) * 2).max(2);
    let mut work = GenerateOutcome::default();
    let mut synced = std::time::Instant::now();
    let mut k = 0;
    'run: while k < config.max_attempts && successes_before(done, k) < config.count {
        let todo: Vec<usize> = (k..config.max_attempts)
            .filter(|i| mine(i) && !done.contains_key(i))
            .take(batch)
            .collect();
        let Some(&last) = todo.last() else { break };
        let inputs = todo
            .iter()
            .map(|&i| Ok((i, resets.get(i)?)))
            .collect::<Result<Vec<_>, GenerateError>>()?;
        for result in in_parallel(&pool, scene, spec, sources, config, inputs) {
            let (a, seconds) = result?;
            // Attempts already done before this one count first (in index order).
            if successes_before(done, a.index) >= config.count {
                break 'run;
            }
            let record = folder::commit(out, spec, &a, config)?;
            progress.note(&attempt_line(&record));
            work.attempts_now += 1;
            work.attempt_seconds += seconds;
            let success = record.success;
            done.insert(a.index, record);
            ok += usize::from(success);
            let rate = format!(
                "{:.0} % of {} attempts succeeded",
                100.0 * ok as f64 / done.len() as f64,
                done.len()
            );
            progress.advance(u64::from(success), &rate);
        }
        k = last + 1;
        if config.shard.is_some() && synced.elapsed() >= SHARD_SYNC {
            // The other shards' attempts count too: stop once the successes before the
            // next attempt of this shard are enough. (How often this is read decides only
            // how far a shard runs past the end; the finalize sets that aside.)
            *done = folder::finished(out, spec, config.seed)?.done;
            ok = successes_before(done, usize::MAX);
            synced = std::time::Instant::now();
        }
    }
    Ok(work)
}

/// One line per attempt, above the progress bar.
fn attempt_line(record: &AttemptRecord) -> String {
    match &record.failure {
        None => format!(
            "attempt {}: success at step {}",
            record.attempt,
            record.steps.saturating_sub(1)
        ),
        Some(f) => format!(
            "attempt {}: failed at {} (step {}): {}",
            record.attempt,
            f.subtask.as_deref().unwrap_or("the end"),
            f.step,
            f.reason
        ),
    }
}

/// The report, the pose figure, the first-frames sheet and the timing of an unsharded
/// run.
fn write_outputs(
    config: &GenerateConfig,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    done: &BTreeMap<usize, AttemptRecord>,
    report: &GenerateReport,
    work: &GenerateOutcome,
) -> Result<(), GenerateError> {
    let out = &config.out;
    let resets: Vec<Vec<f64>> = sources.iter().map(|s| s.reset.clone()).collect();
    let records: Vec<&AttemptRecord> = done.values().collect();
    crate::figure::write_pose_figure(&out.join(POSES_FIGURE), spec, &resets, &records)?;
    let kept: Vec<&[f64]> = records
        .iter()
        .filter(|r| r.success)
        .map(|r| r.reset.as_slice())
        .collect();
    if let Err(e) = crate::sheet::write_first_frames(&out.join(SHEET), scene, spec, &kept) {
        tracing::warn!("no first-frames sheet ({e}); the episodes are not affected");
    }
    let json = serde_json::to_vec_pretty(report).expect("serializable");
    write_atomic(&out.join("generate_report.json"), &json)?;
    write_atomic(
        &out.join("generate_report.md"),
        report.to_markdown().as_bytes(),
    )?;
    let times = serde_json::json!({
        "attempts_now": work.attempts_now,
        "attempt_seconds": work.attempt_seconds,
        "seconds_per_attempt": work.attempt_seconds / work.attempts_now.max(1) as f64,
        "workers": config.workers,
    });
    write_atomic(
        &out.join(TIMES_FILE),
        &serde_json::to_vec_pretty(&times).expect("serializable"),
    )?;
    Ok(())
}

/// The run's threads: attempts are independent simulations without rendering, so they
/// run as threads of one process (no EGL context to keep apart).
fn worker_pool(config: &GenerateConfig) -> Result<rayon::ThreadPool, GenerateError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(config.workers.max(1))
        .thread_name(|i| format!("generate-{i}"))
        .build()
        .map_err(|e| std::io::Error::other(e.to_string()).into())
}

/// Makes the attempts `inputs` (index, reset) in parallel; each with its seconds.
fn in_parallel(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    config: &GenerateConfig,
    inputs: Vec<(usize, Vec<f64>)>,
) -> Vec<Result<(Attempt, f64), GenerateError>> {
    pool.install(|| {
        inputs
            .into_par_iter()
            .map(|(i, reset)| {
                let t = std::time::Instant::now();
                let a = attempt(scene, spec, sources, reset, i, config.seed, &config.options)?;
                Ok((a, t.elapsed().as_secs_f64()))
            })
            .collect()
    })
}

/// A pilot for `--dry-run`: attempts `0..attempts` of the seed, made and not written;
/// returns the successes and the seconds per attempt (one worker).
pub fn pilot(
    config: &GenerateConfig,
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    attempts: usize,
) -> Result<(usize, f64), GenerateError> {
    let mut resets = Resets::new(scene, spec, config.seed);
    let inputs = (0..attempts)
        .map(|i| Ok((i, resets.get(i)?)))
        .collect::<Result<Vec<_>, GenerateError>>()?;
    let mut ok = 0;
    let mut seconds = 0.0;
    for r in in_parallel(&worker_pool(config)?, scene, spec, sources, config, inputs) {
        let (a, s) = r?;
        ok += usize::from(a.planned.success_at.is_some());
        seconds += s;
    }
    Ok((ok, seconds / attempts.max(1) as f64))
}

/// The report over every finished attempt.
fn report(
    spec: &TaskSpec,
    config: &GenerateConfig,
    sources: &[SourceDemo],
    done: &BTreeMap<usize, AttemptRecord>,
) -> GenerateReport {
    let subtasks = spec
        .subtasks
        .iter()
        .map(|s| {
            let count = |f: &dyn Fn(&AttemptRecord) -> bool| done.values().filter(|r| f(r)).count();
            SubtaskOutcome {
                subtask: s.id.clone(),
                started: count(&|r| r.provenance.iter().any(|p| p.subtask == s.id)),
                completed: count(&|r| {
                    r.subtasks
                        .iter()
                        .any(|sp| sp.id == s.id && sp.end.is_some())
                }),
                failed_at: count(&|r| {
                    r.failure.as_ref().and_then(|f| f.subtask.as_deref()) == Some(s.id.as_str())
                }),
            }
        })
        .collect();
    let episodes: Vec<usize> = done
        .values()
        .filter(|r| r.success)
        .map(|r| r.attempt)
        .collect();
    GenerateReport {
        task: spec.id.clone(),
        seed: config.seed,
        attempts: done.len(),
        successes: episodes.len(),
        episodes,
        subtasks,
        sources: sources
            .iter()
            .map(|s| [s.id.clone(), s.sha256.clone()])
            .collect(),
        sources_extended: sources
            .iter()
            .filter(|s| s.extended > 0)
            .map(|s| (s.id.clone(), s.extended))
            .collect(),
    }
}
