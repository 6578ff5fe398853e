//! `dexjoco-data export --to mcap`: stored episodes as MCAP teleop logs.

use anyhow::Context;
use dexjoco_core::TaskSet;
use dexjoco_formats::SourceKind;
use dexjoco_formats::mcap::{EpisodeMeta, write_episode_mcap};

use crate::cli::{ExportArgs, ExportFormat, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::settings::ExportSettings;

/// Runs `export`.
pub fn run(global: &GlobalArgs, args: ExportArgs) -> anyhow::Result<ExitStatus> {
    let ExportSettings { inputs, out, to } = ExportSettings::resolve(args, global);
    let mut sources = Vec::new();
    for input in &inputs {
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
    let tasks = TaskSet::builtin();
    let pb = crate::progress::bar(sources.len() as u64, "export", global.quiet);
    for source in &sources {
        let dir = &source.path;
        let ep = source
            .read(tasks)
            .with_context(|| format!("reading the episode '{}'", dir.display()))?
            .episode;
        let task = tasks.get(&ep.task).context("the episode's task")?;
        let name = dir
            .file_name()
            .map_or_else(|| ep.id.clone(), |n| n.to_string_lossy().into_owned());
        let file = match to {
            ExportFormat::Mcap => out.join(format!("{}_{name}.mcap", ep.task)),
        };
        let meta = EpisodeMeta {
            source: Some(dir.display().to_string()),
            ..EpisodeMeta::default()
        };
        write_episode_mcap(&file, &ep, task, &meta)?;
        println!("{}", file.display());
        pb.inc(1);
    }
    pb.finish_and_clear();
    eprintln!("wrote {} MCAP file(s) to {}", sources.len(), out.display());
    Ok(ExitStatus::Success)
}
