//! `dexjoco-data convert`: episodes -> LeRobot v3.0 or a Diffusion Policy replay buffer.

use anyhow::Context;
use dexjoco_convert::{ConvertError, InputEpisode};
use dexjoco_core::TaskSet;
use dexjoco_formats::Source;

use crate::cli::{ConvertArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::ConvertSettings;

/// Runs `convert`.
pub fn run(global: &GlobalArgs, args: ConvertArgs) -> anyhow::Result<ExitStatus> {
    let ConvertSettings {
        input,
        out,
        options,
    } = ConvertSettings::resolve(args, global)?;
    if dexjoco_formats::fs::is_non_empty_dir(&out) && !options.overwrite {
        return Err(CliError {
            message: format!("output folder {} is not empty", out.display()),
            hint: Some("pass --overwrite to replace it, or choose another --out".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let sources = dexjoco_formats::discover(std::slice::from_ref(&input), None)?;
    if sources.is_empty() {
        return Err(CliError {
            message: format!(
                "no episodes in {} (no manifest.json, and no folder with replay.zarr below it)",
                input.display()
            ),
            hint: Some("`dexjoco-data ingest` makes an episode store from recordings".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    tracing::info!(
        "converting {} episode(s) from {} to {}",
        sources.len(),
        input.display(),
        out.display()
    );
    let bar = Bar::new("convert", global.quiet);
    bar.0.set_length(sources.len() as u64);
    let tasks = TaskSet::builtin();
    let inputs = sources.iter().map(|s| read_episode(s, tasks));
    let summary = dexjoco_convert::convert(inputs, &out, &options, &bar)
        .with_context(|| format!("converting {} into {}", input.display(), out.display()))?;
    bar.finish();
    println!(
        "wrote {}: {} episodes, {} frames ({} static leading frames skipped); videos: {} stream-copied, {} encoded{}",
        summary.out.display(),
        summary.episodes,
        summary.frames,
        summary.skipped_frames,
        summary.videos_copied,
        summary.videos_encoded,
        if summary.excluded.is_empty() {
            String::new()
        } else {
            format!("; left out: {}", summary.excluded.join(", "))
        }
    );
    if summary.failed.is_empty() {
        return Ok(ExitStatus::Success);
    }
    println!(
        "{} episode(s) could not be converted and are not in the dataset:",
        summary.failed.len()
    );
    for f in &summary.failed {
        println!("  {}: {}", f.episode, f.reason);
    }
    Ok(ExitStatus::Partial)
}

/// Reads one episode through the one reader (arrays, cameras from `videos/`).
fn read_episode(source: &Source, tasks: &TaskSet) -> Result<InputEpisode, ConvertError> {
    let episode = source
        .read(tasks)
        .map_err(|e| ConvertError::Input {
            path: source.path.clone(),
            message: e.to_string(),
        })?
        .episode;
    Ok(InputEpisode {
        episode,
        dir: source.path.clone(),
    })
}
