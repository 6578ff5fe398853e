//! `dexjoco-data export --to mcap`: stored episodes as MCAP teleop logs.

use std::path::PathBuf;

use anyhow::Context;
use dexjoco_ingest::teleop::{EpisodeMeta, write_episode_mcap};
use dexjoco_ingest::{MANIFEST, read_stored_episode, stored_episode_dirs};

use crate::cli::{ExportArgs, ExportFormat, GlobalArgs};
use crate::exit::{CliError, ExitStatus};

/// Runs `export`.
pub fn run(global: &GlobalArgs, args: &ExportArgs) -> anyhow::Result<ExitStatus> {
    let inputs = if args.episodes.is_empty() {
        vec![global.work_dir.join("ingest")]
    } else {
        args.episodes.clone()
    };
    let mut dirs: Vec<PathBuf> = Vec::new();
    for input in &inputs {
        if input.join(MANIFEST).is_file() {
            dirs.extend(stored_episode_dirs(input)?);
        } else if input.join(dexjoco_ingest::raw::REPLAY_ZARR).is_dir() {
            dirs.push(input.clone());
        } else {
            return Err(CliError {
                message: format!("'{}' is neither an episode folder nor a store", input.display()),
                hint: Some("give <store>/<task>/episode_NNNNNN folders, or a store made by `dexjoco-data ingest`".into()),
                status: ExitStatus::Failure,
            }
            .into());
        }
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("export"));
    let pb = crate::progress::bar(dirs.len() as u64, "export", global.quiet);
    for dir in &dirs {
        let ep = read_stored_episode(dir)
            .with_context(|| format!("reading the episode '{}'", dir.display()))?;
        let task = dexjoco_core::task_info(&ep.task).context("the episode's task")?;
        let name = dir
            .file_name()
            .map_or_else(|| ep.id.clone(), |n| n.to_string_lossy().into_owned());
        let file = match args.to {
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
    eprintln!("wrote {} MCAP file(s) to {}", dirs.len(), out.display());
    Ok(ExitStatus::Success)
}
