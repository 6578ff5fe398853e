//! `dexjoco-data convert`: episodes -> LeRobot v3.0 or a Diffusion Policy replay buffer.

use anyhow::Context;
use dexjoco_convert::{ConvertError, InputEpisode};
use dexjoco_core::TaskSet;
use dexjoco_formats::Source;

use crate::cli::{ConvertArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::ConvertSettings;

/// An output-folder refusal as a user error with a hint.
fn output_error(e: ConvertError) -> anyhow::Error {
    let hint = match &e {
        ConvertError::OutputNotEmpty(_) => {
            "pass --overwrite to replace it (a dataset convert made), or choose another --out"
        }
        ConvertError::OverwriteRefused { .. } => {
            "choose another --out; remove the folder yourself if it really is to go"
        }
        _ => return e.into(),
    };
    CliError {
        message: e.to_string(),
        hint: Some(hint.into()),
        status: ExitStatus::Failure,
    }
    .into()
}

/// Runs `convert`.
pub fn run(global: &GlobalArgs, args: ConvertArgs) -> anyhow::Result<ExitStatus> {
    let ConvertSettings {
        inputs,
        out,
        mut options,
        tasks,
    } = ConvertSettings::resolve(args, global)?;
    // Checked again under the output's lock when writing; this fails before any work.
    dexjoco_convert::check_output(&out, &options).map_err(output_error)?;
    let sources = dexjoco_formats::discover(&inputs, Some(&out))?;
    let shown = inputs
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    if sources.is_empty() {
        return Err(CliError {
            message: format!(
                "no episodes in {shown} (no manifest.json, and no folder with replay.zarr below it)"
            ),
            hint: Some("`dexjoco-data ingest` makes an episode store from recordings".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    tracing::info!(
        "converting {} episode(s) from {shown} to {}",
        sources.len(),
        out.display()
    );
    // Every episode's language slice has the length the longest needs.
    options.v3.language_slots = dexjoco_convert::language_slots(
        sources.iter().map(|s| s.path.as_path()),
        &options.selection,
    );
    let bar = Bar::new("convert", global.quiet);
    bar.0.set_length(sources.len() as u64);
    let inputs = sources.iter().map(|s| read_episode(s, &tasks));
    let summary = dexjoco_convert::convert(inputs, &out, &options, &bar)
        .map_err(output_error)
        .with_context(|| format!("converting {shown} into {}", out.display()))?;
    bar.finish();
    outln!(
        "wrote {}: {} episodes, {} frames ({} static leading frames skipped); videos: {} stream-copied{}, {} encoded{}",
        summary.out.display(),
        summary.episodes,
        summary.frames,
        summary.skipped_frames,
        summary.videos_copied,
        match summary.videos_smart_cut {
            0 => String::new(),
            k => format!(
                " ({k} by smart cut: {} frames re-encoded)",
                summary.frames_reencoded
            ),
        },
        summary.videos_encoded,
        if summary.excluded.is_empty() {
            String::new()
        } else {
            format!("; left out: {}", summary.excluded.join(", "))
        }
    );
    if options.norm_stats.is_some() {
        warn_flat_norm_stats(&summary.out);
    }
    if summary.failed.is_empty() {
        return Ok(ExitStatus::Success);
    }
    outln!(
        "{} episode(s) could not be converted and are not in the dataset:",
        summary.failed.len()
    );
    for f in &summary.failed {
        outln!("  {}: {}", f.episode, f.reason);
    }
    Ok(ExitStatus::Partial)
}

/// Warns about each zero-variance column of the dataset's `norm_stats.json` (named after
/// the LeRobot features' names where the dataset has `meta/info.json`): the file stays as
/// openpi writes it, and openpi's Normalize divides by std + 1e-6.
fn warn_flat_norm_stats(dataset: &std::path::Path) {
    let read = |p: std::path::PathBuf| -> Option<serde_json::Value> {
        serde_json::from_slice(&fs_err::read(p).ok()?).ok()
    };
    let Some(doc) = read(dataset.join(dexjoco_formats::openpi::NORM_STATS)) else {
        return;
    };
    let mut names = std::collections::BTreeMap::new();
    if let Some(info) = read(dataset.join("meta").join("info.json")) {
        for (key, feature) in [("state", "observation.state"), ("actions", "action")] {
            let list = info["features"][feature]["names"].as_array().map(|a| {
                a.iter()
                    .filter_map(|n| n.as_str().map(str::to_owned))
                    .collect::<Vec<_>>()
            });
            if let Some(list) = list {
                names.insert(key.to_owned(), list);
            }
        }
    }
    for c in dexjoco_formats::openpi::flat_columns(&doc, &names) {
        tracing::warn!("{}", c.warning());
    }
}

/// Reads one episode through the one reader (arrays, cameras from `videos/`).
fn read_episode(source: &Source, tasks: &TaskSet) -> Result<InputEpisode, ConvertError> {
    let episode = source
        .read_checked(tasks)
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
