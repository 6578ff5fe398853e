//! `dexjoco-data stats`: the language-generalization analysis and success-rate tables.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_core::TaskSet;
use dexjoco_formats::fs::StagedDir;
use dexjoco_stats::{LanguageInput, LanguageOptions, LanguageReport, SuccessTable};

use crate::cli::{GlobalArgs, StatsArgs};
use crate::exit::{CliError, ExitStatus};
use crate::settings::StatsSettings;

/// An example input shipped in the sample data's `examples/` (see
/// [`crate::locate::data_dir`]).
fn example_input(name: &str) -> anyhow::Result<PathBuf> {
    crate::locate::data_dir()
        .map(|d| d.path.join("examples").join(name))
        .filter(|p| p.is_dir())
        .ok_or_else(|| {
            CliError {
                message: format!("the example input datasets/examples/{name} is not found"),
                hint: Some(format!(
                    "pass your own input (see `dexjoco-data stats --help`), or point ${} at a \
                     datasets folder; in a checkout, `python3 datasets/examples/generate_examples.py` \
                     recreates the examples",
                    crate::locate::DATA_ENV
                )),
                status: ExitStatus::Failure,
            }
            .into()
        })
}

/// Runs `stats`.
pub fn run(global: &GlobalArgs, args: StatsArgs) -> anyhow::Result<ExitStatus> {
    let StatsSettings {
        language_eval,
        success_table,
        dataset,
        out,
        language,
        json: as_json,
        tasks,
    } = StatsSettings::resolve(args, global)?;
    let mut json = serde_json::Map::new();
    let mut summaries = Vec::new();

    let mut statuses = Vec::new();
    if let Some(input) = &language_eval {
        let s = write_language_eval(input.as_deref(), &out, language, &mut json, &mut summaries)?;
        statuses.push(s);
    }
    if let Some(input) = &success_table {
        statuses.push(write_success_table(
            input.as_deref(),
            &out,
            &mut json,
            &mut summaries,
        )?);
    }
    if let Some(path) = &dataset {
        statuses.push(write_dataset_stats(
            path,
            &tasks,
            global.quiet,
            &out,
            &mut json,
            &mut summaries,
        )?);
    }
    let status = if statuses.contains(&ExitStatus::Partial) {
        ExitStatus::Partial
    } else {
        ExitStatus::Success
    };

    if as_json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&serde_json::Value::Object(json))?
        );
    } else {
        outln!("{}", summaries.join("\n"));
    }
    Ok(status)
}

/// Names each run folder left out (exit 3 follows).
fn report_left_out(left_out: &[dexjoco_stats::evaltree::LeftOutRun]) -> ExitStatus {
    for l in left_out {
        errln!("left out: '{}': {}", l.path.display(), l.reason);
    }
    if left_out.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Partial
    }
}

/// The language evaluation of `input` (the shipped example when `None`): written under
/// `out/language-eval`, added to the JSON object and the Markdown summaries. Partial when
/// run folders were left out.
fn write_language_eval(
    input: Option<&Path>,
    out: &Path,
    options: LanguageOptions,
    json: &mut serde_json::Map<String, serde_json::Value>,
    summaries: &mut Vec<String>,
) -> anyhow::Result<ExitStatus> {
    let path = match input {
        Some(p) => p.to_path_buf(),
        None => example_input("language-eval")?,
    };
    let input = LanguageInput::load(&path)
        .with_context(|| format!("reading the language evaluation {}", path.display()))?;
    if input.example {
        tracing::warn!(
            "{} is a made-up EXAMPLE input: its numbers are not results",
            path.display()
        );
    }
    for w in &input.warnings {
        tracing::warn!("{w}");
    }
    let report = LanguageReport::analyze(&input, options);
    let dir = out.join("language-eval");
    let files = write_whole(&dir, |d| Ok(report.write(d)?))
        .with_context(|| format!("writing the language evaluation to {}", dir.display()))?;
    tracing::info!("wrote {} files to {}", files.len(), dir.display());
    json.insert("language_eval".into(), serde_json::to_value(&report)?);
    summaries.push(format!(
        "## Language evaluation\n\n{}",
        report.to_markdown()
    ));
    if !input.left_out.is_empty() {
        json.insert(
            "language_eval_left_out".into(),
            serde_json::to_value(&input.left_out)?,
        );
    }
    Ok(report_left_out(&input.left_out))
}

/// The success-rate table of the runs under `input` (the shipped example when `None`):
/// written under `out/success-table`, added to the JSON object and the summaries. Partial
/// when run folders were left out.
fn write_success_table(
    input: Option<&Path>,
    out: &Path,
    json: &mut serde_json::Map<String, serde_json::Value>,
    summaries: &mut Vec<String>,
) -> anyhow::Result<ExitStatus> {
    let path = match input {
        Some(p) => p.to_path_buf(),
        None => example_input("success-table")?,
    };
    let table = SuccessTable::load(&path)
        .with_context(|| format!("reading the evaluation runs under {}", path.display()))?;
    if table.example {
        tracing::warn!(
            "{} is a made-up EXAMPLE input: its numbers are not results",
            path.display()
        );
    }
    for w in &table.warnings {
        tracing::warn!("{w}");
    }
    let dir = out.join("success-table");
    let files = write_whole(&dir, |d| Ok(table.write(d)?))
        .with_context(|| format!("writing the success table to {}", dir.display()))?;
    tracing::info!("wrote {} files to {}", files.len(), dir.display());
    json.insert("success_table".into(), serde_json::to_value(&table)?);
    let mut md = format!(
        "## Success rates (%) of {} polic{}, mean ± sample std over seeds\n\n",
        table.policies.len(),
        if table.policies.len() == 1 {
            "y"
        } else {
            "ies"
        }
    );
    if table.example {
        md.push_str(
            "> EXAMPLE INPUT (synthetic, made by a script): these numbers are not results.\n\n",
        );
    }
    md.push_str(&table.to_markdown());
    let progress = table.progress_markdown();
    if !progress.is_empty() {
        md.push('\n');
        md.push_str(&progress);
    }
    summaries.push(md);
    Ok(report_left_out(&table.left_out))
}

/// The statistics of the dataset at `path`, whose tasks are among `tasks` (and its
/// replays when it is an augment output): written under `out/dataset`, added to the JSON object and the summaries.
/// Partial when episodes were left out.
fn write_dataset_stats(
    path: &Path,
    tasks: &TaskSet,
    quiet: bool,
    out: &Path,
    json: &mut serde_json::Map<String, serde_json::Value>,
    summaries: &mut Vec<String>,
) -> anyhow::Result<ExitStatus> {
    let mut status = ExitStatus::Success;
    let (stats, left_out) = dataset_stats(path, tasks, quiet)?;
    if !left_out.is_empty() {
        status = ExitStatus::Partial;
        let list: Vec<serde_json::Value> = left_out
            .iter()
            .map(|(p, r)| serde_json::json!({"episode": p, "reason": r}))
            .collect();
        json.insert("dataset_left_out".into(), list.into());
    }
    let replays = dexjoco_stats::ReplayStats::read(path)?;
    let dir = out.join("dataset");
    let files = write_whole(&dir, |d| {
        let mut files = stats.write(d)?;
        // An augment output folder: its report's replay success rates.
        if let Some(replays) = &replays {
            for (name, text) in [
                ("replay_success.md", replays.to_markdown()),
                (
                    "replay_success.json",
                    serde_json::to_string_pretty(replays)?,
                ),
            ] {
                dexjoco_formats::write_atomic(&d.join(name), text.as_bytes())?;
                files.push(d.join(name));
            }
        }
        Ok(files)
    })
    .with_context(|| format!("writing the dataset statistics to {}", dir.display()))?;
    tracing::info!("wrote {} files to {}", files.len(), dir.display());
    json.insert("dataset".into(), serde_json::to_value(&stats)?);
    summaries.push(format!(
        "## Dataset `{}`\n\n{}",
        path.display(),
        stats.to_markdown()
    ));
    if let Some(r) = replays.as_ref().filter(|r| !r.subtasks.is_empty()) {
        summaries.push(format!(
            "## Subtasks of the kept replays\n\n{}",
            dexjoco_stats::subtasks::to_markdown(&r.subtasks)
        ));
    }
    // Where its replays were made, with a warning when in more than one place.
    if let Some(made_on) = dexjoco_stats::ReplayProvenance::read(path)? {
        if let Some(w) = made_on.warning() {
            tracing::warn!("{w}");
        }
        json.insert("made_on".into(), serde_json::to_value(&made_on)?);
        summaries.push(format!(
            "## Where the replays were made\n\n{}",
            made_on.to_markdown()
        ));
    }
    if let Some(replays) = &replays {
        json.insert("replays".into(), serde_json::to_value(replays)?);
        summaries.push(format!(
            "## Replays (`{}`, {} per episode)\n\n{}",
            path.join(dexjoco_stats::AUGMENT_REPORT).display(),
            replays.replays_per_episode,
            replays.to_markdown()
        ));
    }
    Ok(status)
}

/// Writes one output folder whole: into a staging folder beside it (under its lock),
/// then renamed over it, so no file of an earlier run remains and a killed run leaves
/// the previous folder as it was. Returns the files, as they are named once in place.
fn write_whole<F>(dir: &Path, write: F) -> anyhow::Result<Vec<PathBuf>>
where
    F: FnOnce(&Path) -> anyhow::Result<Vec<PathBuf>>,
{
    let staged = StagedDir::begin(dir)?;
    let files = write(staged.path())?;
    let files = files
        .into_iter()
        .map(|f| match f.strip_prefix(staged.path()) {
            Ok(rel) => dir.join(rel),
            Err(_) => f,
        })
        .collect();
    staged.commit()?;
    Ok(files)
}

/// Reads every episode of a store (its landed episodes, from `manifest.json`) or of a
/// folder tree of DexJoCo raw episodes (with its replay record and videos' digest), and
/// computes their statistics; the health section's warnings go to stderr. An episode that
/// cannot be read, or whose array widths differ from the other episodes of its task, is
/// named and left out (the count is returned); it never stops the others.
fn dataset_stats(
    path: &Path,
    tasks: &TaskSet,
    quiet: bool,
) -> anyhow::Result<(dexjoco_stats::DatasetStats, Vec<(String, String)>)> {
    use rayon::prelude::*;
    let sources = dexjoco_formats::discover(&[path.to_path_buf()], None)?;
    if sources.is_empty() {
        return Err(CliError {
            message: format!("no episodes in '{}'", path.display()),
            hint: Some(
                "point --dataset at an ingest store (with manifest.json) or a folder of DexJoCo raw \
                 episodes (folders holding replay.zarr); `dexjoco-data ingest` makes a store"
                    .into(),
            ),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let pb = crate::progress::bar(sources.len() as u64, "read", quiet);
    let read: Vec<_> = sources
        .par_iter()
        .map(|s| {
            let r = s.read(tasks).map_err(|e| e.to_string()).and_then(|r| {
                // The replay record and the videos' digest, for the health section.
                let files = dexjoco_stats::EpisodeFiles::read(&s.path, &r.episode)
                    .map_err(|e| e.to_string())?;
                Ok((r.episode, files))
            });
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    let mut episodes = Vec::with_capacity(read.len());
    let mut files = Vec::with_capacity(read.len());
    let mut dirs = Vec::with_capacity(read.len());
    let mut left_out = Vec::new();
    for (r, source) in read.into_iter().zip(&sources) {
        match r {
            Ok((e, f)) => {
                episodes.push(e);
                files.push(f);
                dirs.push(&source.path);
            }
            Err(e) => left_out.push((source.path.display().to_string(), e)),
        }
    }
    let outliers = dexjoco_stats::width_outliers(&episodes);
    for (i, e) in outliers.iter().rev() {
        left_out.push((dirs[*i].display().to_string(), e.to_string()));
        episodes.remove(*i);
        files.remove(*i);
    }
    left_out.sort();
    for (p, r) in &left_out {
        errln!("left out: '{p}': {r}");
    }
    if episodes.is_empty() {
        return Err(CliError {
            message: format!(
                "none of the {} episode(s) in '{}' could be read",
                left_out.len(),
                path.display()
            ),
            hint: Some("see the reasons above".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let stats = dexjoco_stats::DatasetStats::compute_with_files(&episodes, &files, tasks)
        .with_context(|| format!("dataset statistics of {}", path.display()))?;
    for w in &stats.health.warnings {
        tracing::warn!("health: {w}");
    }
    Ok((stats, left_out))
}
