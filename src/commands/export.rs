//! `dexjoco-data export --to mcap`: stored episodes written in another episode container
//! (MCAP teleop logs), one file per episode.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_core::TaskSet;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, Source, SourceKind};

use crate::cli::{ExportArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::settings::ExportSettings;

/// Runs `export`.
pub fn run(global: &GlobalArgs, args: ExportArgs) -> anyhow::Result<ExitStatus> {
    let ExportSettings {
        inputs,
        out,
        container,
        overwrite,
        tasks,
    } = ExportSettings::resolve(args, global)?;
    let tasks = &tasks;
    let (sources, mut left_out) = stored_episodes(&inputs)?;
    let planned = plan_files(&sources, &out, container, tasks, &mut left_out);
    if !overwrite {
        refuse_existing(&planned)?;
    }
    let pb = crate::progress::bar(planned.len() as u64, "export", global.quiet);
    let mut written = 0;
    for (source, file) in &planned {
        // A bad episode is left out and named; the others are written.
        let read = source
            .read_checked(tasks)
            .map_err(anyhow::Error::from)
            .and_then(|r| {
                let task = tasks.get(&r.episode.task).with_context(|| {
                    format!("unknown task '{}' (--tasks-dir adds tasks)", r.episode.task)
                })?;
                Ok((r.episode, task))
            });
        match read {
            Ok((ep, task)) => {
                let meta = EpisodeMeta {
                    source: Some(source.path.display().to_string()),
                    ..EpisodeMeta::default()
                };
                container.write(file, &ep, task, &meta)?;
                outln!("{}", file.display());
                written += 1;
            }
            Err(e) => left_out.push((source.path.clone(), crate::exit::one_line(&e))),
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    errln!(
        "wrote {written} {} file(s) to {}",
        container.name(),
        out.display()
    );
    for (path, why) in &left_out {
        errln!("  SKIPPED: {}: {why}", path.display());
    }
    Ok(if left_out.is_empty() {
        ExitStatus::Success
    } else if written == 0 {
        ExitStatus::Failure
    } else {
        ExitStatus::Partial
    })
}

/// An input left out, and why.
type LeftOut = Vec<(PathBuf, String)>;

/// The episode folders under every input (a failure when an input holds none), and the
/// MCAP logs among them, left out: they are in the format export writes already.
fn stored_episodes(inputs: &[PathBuf]) -> anyhow::Result<(Vec<Source>, LeftOut)> {
    let mut sources = Vec::new();
    let mut left_out = Vec::new();
    for input in inputs {
        let found = dexjoco_formats::discover_input(input, None)
            .with_context(|| format!("finding episodes in '{}'", input.display()))?;
        let (raw, mcap): (Vec<_>, Vec<_>) =
            found.into_iter().partition(|s| s.kind == SourceKind::Raw);
        left_out.extend(mcap.into_iter().map(|s| {
            let why = "an MCAP log already (export writes stored episode folders; \
                       `dexjoco-data ingest` stores it)";
            (s.path, why.to_owned())
        }));
        if raw.is_empty() {
            return Err(CliError {
                message: format!("'{}' holds no episode folder", input.display()),
                hint: Some("give <store>/<task>/episode_NNNNNN folders, or a store made by `dexjoco-data ingest`".into()),
                status: ExitStatus::Failure,
            }
            .into());
        }
        sources.extend(raw);
    }
    Ok((sources, left_out))
}

/// Every file name first: two episodes never share one. An episode whose task cannot be
/// told joins `left_out`.
fn plan_files<'s>(
    sources: &'s [Source],
    out: &Path,
    container: &dyn EpisodeContainer,
    tasks: &TaskSet,
    left_out: &mut LeftOut,
) -> Vec<(&'s Source, PathBuf)> {
    let mut planned = Vec::with_capacity(sources.len());
    let mut taken = HashSet::new();
    for source in sources {
        match task_of(source, tasks) {
            Ok(task) => {
                let file = unique_name(&mut taken, out, &task, source, container.extension());
                planned.push((source, file));
            }
            Err(e) => left_out.push((source.path.clone(), crate::exit::one_line(&e))),
        }
    }
    planned
}

/// Nothing already there is replaced without --overwrite.
fn refuse_existing(planned: &[(&Source, PathBuf)]) -> anyhow::Result<()> {
    let existing: Vec<String> = planned
        .iter()
        .filter(|(_, f)| fs_err::symlink_metadata(f).is_ok())
        .map(|(_, f)| f.display().to_string())
        .collect();
    if existing.is_empty() {
        return Ok(());
    }
    Err(CliError {
        message: format!(
            "{} file(s) already exist: {}",
            existing.len(),
            existing.join(", ")
        ),
        hint: Some("pass --overwrite to replace them, or choose another --out".into()),
        status: ExitStatus::Failure,
    }
    .into())
}

/// The task of a stored episode as the reader takes it (its store entry, else its
/// path), without reading its arrays; read when neither says.
fn task_of(source: &Source, tasks: &TaskSet) -> anyhow::Result<String> {
    let dir = &source.path;
    if let Some(t) = dexjoco_formats::ManifestEntry::of_episode_dir(dir)
        .and_then(|e| e.task)
        .or_else(|| dexjoco_formats::raw::task_from_path(dir, tasks))
    {
        return Ok(t);
    }
    Ok(source
        .read(tasks)
        .with_context(|| format!("reading the episode '{}'", dir.display()))?
        .episode
        .task)
}

/// `<out>/<task>_<folder>.<ext>`, or `<task>_<folder>-2.<ext>`, `-3`... when an earlier
/// episode of this run took the name (no `.<ext>` for a container of folders).
fn unique_name(
    taken: &mut HashSet<PathBuf>,
    out: &Path,
    task: &str,
    source: &Source,
    ext: Option<&str>,
) -> PathBuf {
    let folder = source
        .path
        .file_name()
        .map_or_else(|| "episode".into(), |n| n.to_string_lossy().into_owned());
    let ext = ext.map(|e| format!(".{e}")).unwrap_or_default();
    let mut file = out.join(format!("{task}_{folder}{ext}"));
    let mut k = 2;
    while !taken.insert(file.clone()) {
        file = out.join(format!("{task}_{folder}-{k}{ext}"));
        k += 1;
    }
    if k > 2 {
        tracing::warn!(
            "'{}' would share its file name with an earlier episode: written as '{}'",
            source.path.display(),
            file.display()
        );
    }
    file
}
