//! `dexjoco-data convert`: episodes -> LeRobot v3.0 or a Diffusion Policy replay buffer.

use std::path::Path;

use anyhow::Context;
use dexjoco_convert::{
    ConvertError, ConvertOptions, InputEpisode, OutputFormat, Reporter, Selection, V3Options,
    VideoCodec, VideoOptions,
};

use crate::cli::{ConvertArgs, ConvertFormatArg, GlobalArgs, VideoCodecArg};
use crate::exit::{CliError, ExitStatus};

struct Bar(indicatif::ProgressBar);

impl Reporter for Bar {
    fn episode(&self, id: &str, excluded: bool) {
        if excluded {
            self.0.println(format!("left out {id} (bad-episodes list)"));
        }
        self.0.inc(1);
    }

    fn failed(&self, id: &str, reason: &str) {
        self.0.println(format!("LEFT OUT {id}: {reason}"));
        self.0.inc(1);
    }
}

/// Runs `convert`.
pub fn run(global: &GlobalArgs, args: &ConvertArgs) -> anyhow::Result<ExitStatus> {
    let input = match &args.input {
        Some(p) => p.clone(),
        None => {
            let default = global.work_dir.join("augment");
            if !default.is_dir() {
                return Err(CliError {
                    message: format!(
                        "no input: the augment stage's output {} does not exist",
                        default.display()
                    ),
                    hint: Some(
                        "pass --input DIR: an episode store (`dexjoco-data ingest` makes one) or a folder of \
                         DexJoCo raw episode folders (replay.zarr + videos/)"
                            .into(),
                    ),
                    status: ExitStatus::Failure,
                }
                .into());
            }
            default
        }
    };
    let (format, format_dir) = match args.format {
        ConvertFormatArg::DiffusionPolicy => (OutputFormat::DiffusionPolicy, "diffusion-policy"),
        ConvertFormatArg::LerobotV21 => (OutputFormat::LeRobotV21, "lerobot-v2.1"),
        ConvertFormatArg::LerobotV3 => (OutputFormat::LeRobotV3, "lerobot-v3"),
    };
    if args.videos && format != OutputFormat::DiffusionPolicy {
        return Err(CliError {
            message: "--videos applies to --format diffusion-policy only".into(),
            hint: Some("LeRobot formats always carry their videos".into()),
            status: ExitStatus::Usage,
        }
        .into());
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("convert").join(format_dir));
    if dexjoco_convert::is_non_empty_dir(&out) && !args.overwrite {
        return Err(CliError {
            message: format!("output folder {} is not empty", out.display()),
            hint: Some("pass --overwrite to replace it, or choose another --out".into()),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let mut selection = match &args.config {
        None => Selection::default(),
        Some(p) if p.is_dir() => Selection::from_reference_dir(p)?,
        Some(p) => Selection::load(p)?,
    };
    if args.no_skip_static {
        selection.skip_static_frames = false;
    }
    if args.merge_bimanual {
        selection.merge_bimanual = true;
    }
    selection.bad_episodes.extend(args.exclude.iter().cloned());
    let options = ConvertOptions {
        format,
        videos: args.videos,
        norm_stats: args.norm_stats.then_some(args.norm_stats_horizon),
        selection,
        video: VideoOptions {
            codec: match args.video_codec {
                VideoCodecArg::Av1 => VideoCodec::Av1,
                VideoCodecArg::H264 => VideoCodec::H264,
            },
            reencode: args.reencode,
        },
        v3: V3Options {
            robot_type: Some(args.robot_type.clone()),
            ..V3Options::default()
        },
        overwrite: args.overwrite,
        ..ConvertOptions::default()
    };
    let folders = dexjoco_ingest::episode_dirs(&input)?;
    if folders.is_empty() {
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
        folders.len(),
        input.display(),
        out.display()
    );
    let bar = Bar(crate::progress::bar(
        folders.len() as u64,
        "convert",
        global.quiet,
    ));
    let inputs = folders.into_iter().map(|dir| read_episode(&dir));
    let summary = dexjoco_convert::convert(inputs, &out, &options, &bar)
        .with_context(|| format!("converting {} into {}", input.display(), out.display()))?;
    bar.0.finish_and_clear();
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

/// Reads one DexJoCo raw episode folder (arrays from `replay.zarr`, cameras from
/// `videos/`).
fn read_episode(dir: &Path) -> Result<InputEpisode, ConvertError> {
    let episode = dexjoco_ingest::read_stored_episode(dir).map_err(|e| ConvertError::Input {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(InputEpisode {
        episode,
        dir: dir.to_path_buf(),
    })
}
