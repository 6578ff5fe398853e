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
    } = ExportSettings::resolve(args, global)?;
    let sources = stored_episodes(&inputs)?;
    let tasks = TaskSet::builtin();
    let planned = plan_files(&sources, &out, container, tasks)?;
    if !overwrite {
        refuse_existing(&planned)?;
    }
    let pb = crate::progress::bar(planned.len() as u64, "export", global.quiet);
    for (source, file) in &planned {
        let ep = source
            .read(tasks)
            .with_context(|| format!("reading the episode '{}'", source.path.display()))?
            .episode;
        let task = tasks.get(&ep.task).context("the episode's task")?;
        let meta = EpisodeMeta {
            source: Some(source.path.display().to_string()),
            ..EpisodeMeta::default()
        };
        container.write(file, &ep, task, &meta)?;
        outln!("{}", file.display());
        pb.inc(1);
    }
    pb.finish_and_clear();
    errln!(
        "wrote {} {} file(s) to {}",
        planned.len(),
        container.name(),
        out.display()
    );
    Ok(ExitStatus::Success)
}

/// The episode folders under every input (a failure when an input holds none).
fn stored_episodes(inputs: &[PathBuf]) -> anyhow::Result<Vec<Source>> {
    let mut sources = Vec::new();
    for input in inputs {
        let found = dexjoco_formats::discover_input(input, None)
            .with_context(|| format!("finding episodes in '{}'", input.display()))?;
        let raw: Vec<_> = found
            .into_iter()
            .filter(|s| s.kind == SourceKind::Raw)
            .collect();
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
    Ok(sources)
}

/// Every file name first: two episodes never share one.
fn plan_files<'s>(
    sources: &'s [Source],
    out: &Path,
    container: &dyn EpisodeContainer,
    tasks: &TaskSet,
) -> anyhow::Result<Vec<(&'s Source, PathBuf)>> {
    let mut planned = Vec::with_capacity(sources.len());
    let mut taken = HashSet::new();
    for source in sources {
        let task = task_of(source, tasks)?;
        let file = unique_name(&mut taken, out, &task, source, container.extension());
        planned.push((source, file));
    }
    Ok(planned)
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
