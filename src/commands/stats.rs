//! `dexjoco-data stats`: the language-generalization analysis and success-rate tables.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_stats::{LanguageInput, LanguageOptions, LanguageReport, LogBase, SuccessTable};

use crate::cli::{GlobalArgs, JsBaseArg, StatsArgs};
use crate::exit::{CliError, ExitStatus};

/// Where the example inputs live in the repository.
const EXAMPLES: &str = "datasets/examples";

/// An example input shipped in `datasets/examples/`: looked up from the current folder,
/// then from the source checkout the binary was built from.
fn example_input(name: &str) -> anyhow::Result<PathBuf> {
    let candidates = [
        PathBuf::from(EXAMPLES).join(name),
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(EXAMPLES)
            .join(name),
    ];
    candidates
        .iter()
        .find(|p| p.is_dir())
        .cloned()
        .ok_or_else(|| {
            CliError {
                message: format!("the example input {EXAMPLES}/{name} is not here"),
                hint: Some(format!(
                    "run from the repository root, or pass your own input (see `dexjoco-data stats --help`); \
                     `python3 {EXAMPLES}/generate_examples.py` recreates the examples"
                )),
                status: ExitStatus::Failure,
            }
            .into()
        })
}

fn usage(message: String, hint: &str) -> anyhow::Error {
    CliError {
        message,
        hint: Some(hint.into()),
        status: ExitStatus::Usage,
    }
    .into()
}

/// Runs `stats`.
pub fn run(global: &GlobalArgs, args: &StatsArgs) -> anyhow::Result<ExitStatus> {
    if args.language_eval.is_none() && args.success_table.is_none() && args.dataset.is_none() {
        return Err(usage(
            "nothing to do: say which statistics to make".into(),
            "`dexjoco-data stats --language-eval` or `--success-table` (each on the shipped example input \
             without a path), or `--dataset` (the ingest store)",
        ));
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(usage(
            format!("--alpha {} is not in (0, 1)", args.alpha),
            "for example --alpha 0.01",
        ));
    }
    if !(0.0..=1.0).contains(&args.nmi_weak) {
        return Err(usage(
            format!("--nmi-weak {} is not in [0, 1]", args.nmi_weak),
            "for example --nmi-weak 0.1",
        ));
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("stats"));
    let mut json = serde_json::Map::new();
    let mut summaries = Vec::new();

    if let Some(input) = &args.language_eval {
        let path = match input {
            Some(p) => p.clone(),
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
        let options = LanguageOptions {
            alpha: args.alpha,
            nmi_weak: args.nmi_weak,
            js_base: match args.js_base {
                JsBaseArg::Two => LogBase::Two,
                JsBaseArg::E => LogBase::E,
            },
        };
        let report = LanguageReport::analyze(&input, options);
        let dir = out.join("language-eval");
        let files = report
            .write(&dir)
            .with_context(|| format!("writing the language evaluation to {}", dir.display()))?;
        tracing::info!("wrote {} files to {}", files.len(), dir.display());
        json.insert("language_eval".into(), serde_json::to_value(&report)?);
        summaries.push(format!(
            "## Language evaluation\n\n{}",
            report.to_markdown()
        ));
    }

    if let Some(input) = &args.success_table {
        let path = match input {
            Some(p) => p.clone(),
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
        let files = table
            .write(&dir)
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
        summaries.push(md);
    }

    let mut status = ExitStatus::Success;
    if let Some(input) = &args.dataset {
        let path = input
            .clone()
            .unwrap_or_else(|| global.work_dir.join("ingest"));
        let (stats, unreadable) = dataset_stats(&path, global.quiet)?;
        if unreadable > 0 {
            status = ExitStatus::Partial;
        }
        let dir = out.join("dataset");
        let files = stats
            .write(&dir)
            .with_context(|| format!("writing the dataset statistics to {}", dir.display()))?;
        tracing::info!("wrote {} files to {}", files.len(), dir.display());
        json.insert("dataset".into(), serde_json::to_value(&stats)?);
        summaries.push(format!(
            "## Dataset `{}`\n\n{}",
            path.display(),
            stats.to_markdown()
        ));
        // An augment output folder: its report's replay success rates.
        if let Some(replays) = dexjoco_stats::ReplayStats::read(&path)? {
            let md = replays.to_markdown();
            dexjoco_ingest::write_atomic(&dir.join("replay_success.md"), md.as_bytes())?;
            dexjoco_ingest::write_atomic(
                &dir.join("replay_success.json"),
                serde_json::to_string_pretty(&replays)?.as_bytes(),
            )?;
            json.insert("replays".into(), serde_json::to_value(&replays)?);
            summaries.push(format!(
                "## Replays (`{}`, {} per episode)\n\n{md}",
                path.join(dexjoco_stats::AUGMENT_REPORT).display(),
                replays.replays_per_episode
            ));
        }
    }

    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::Value::Object(json))?
        );
    } else {
        println!("{}", summaries.join("\n"));
    }
    Ok(status)
}

/// Reads every episode of a store (its landed episodes, from `manifest.json`) or of a
/// folder tree of DexJoCo raw episodes, and computes their statistics. An episode that
/// cannot be read is reported and left out (the count is returned); it never stops the
/// others.
fn dataset_stats(path: &Path, quiet: bool) -> anyhow::Result<(dexjoco_stats::DatasetStats, usize)> {
    use rayon::prelude::*;
    let dirs = dexjoco_ingest::episode_dirs(path)?;
    if dirs.is_empty() {
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
    let pb = crate::progress::bar(dirs.len() as u64, "read", quiet);
    let read: Vec<_> = dirs
        .par_iter()
        .map(|d| {
            let r = dexjoco_ingest::read_stored_episode(d);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    let mut episodes = Vec::with_capacity(read.len());
    let mut unreadable = 0;
    for r in read {
        match r {
            Ok(e) => episodes.push(e),
            Err(e) => {
                unreadable += 1;
                tracing::warn!("left out: {e}");
            }
        }
    }
    let stats = dexjoco_stats::DatasetStats::compute(&episodes)
        .with_context(|| format!("dataset statistics of {}", path.display()))?;
    Ok((stats, unreadable))
}
