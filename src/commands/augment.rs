//! `dexjoco-data augment`: randomized, validated replays of episodes, rendered from one
//! simulation per episode, written in the DexJoCo raw layout with a report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_augment::{AugmentConfig, augment};
use dexjoco_sim::{RenderQuality, RenderSettings, SceneSource};

use crate::cli::{AugmentArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};

const DEMOS: &str = "datasets/demos";

/// The sample data: `datasets/demos` here, else in the checkout the binary was built from.
pub(crate) fn sample_data() -> anyhow::Result<PathBuf> {
    [
        PathBuf::from(DEMOS),
        Path::new(env!("CARGO_MANIFEST_DIR")).join(DEMOS),
    ]
    .into_iter()
    .find(|p| p.is_dir())
    .ok_or_else(|| {
        CliError {
            message: format!("no input given and the sample data {DEMOS} is not here"),
            hint: Some("pass raw episode folders, an episode store or MCAP files".into()),
            status: ExitStatus::Usage,
        }
        .into()
    })
}

/// Runs `augment`.
pub fn run(global: &GlobalArgs, args: &AugmentArgs) -> anyhow::Result<ExitStatus> {
    if args.size == 0 || !args.size.is_multiple_of(2) {
        return Err(CliError {
            message: format!(
                "--size {} must be even and positive (H.264 yuv420p)",
                args.size
            ),
            hint: Some("use 640 (the reference) or 224".into()),
            status: ExitStatus::Usage,
        }
        .into());
    }
    let inputs = if args.inputs.is_empty() {
        vec![sample_data()?]
    } else {
        args.inputs.clone()
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("augment"));
    let config = AugmentConfig {
        inputs,
        out: out.clone(),
        replays: args.replays,
        tasks_dir: args.tasks_dir.clone(),
        seed: global.seed,
        scene: SceneSource::from_option(args.scene_dir.clone()),
        camera_pool: args.camera_pool.clone(),
        cameras: args.cameras.clone(),
        settings: RenderSettings {
            width: args.size,
            height: args.size,
            quality: RenderQuality::from_name(args.quality.name())
                .expect("every QualityArg is a preset"),
            depth: false,
        },
        keep_failed: args.keep_failed,
        max_frames: args.max_frames,
        resimulate_per_replay: false,
        contact_sheet: true,
        depth: args.depth,
        dynamics: args.dynamics,
    };
    let bar = crate::progress::bar(0, "augment", global.quiet);
    let started = std::time::Instant::now();
    let report = super::ingest::with_pool(global, || {
        augment(&config, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
    })?
    .with_context(|| format!("augmenting into {}", out.display()))?;
    bar.finish_and_clear();
    let failed = report.failed_episodes();
    let ok = report.episodes.len() - failed;
    println!(
        "augment: {} episode(s) replayed to success, {failed} failed; {} replay(s) in {} ({} rendered now, {:.1} s)",
        ok,
        report.replays.len(),
        out.display(),
        report.rendered_now,
        started.elapsed().as_secs_f64()
    );
    if !report.dropped.is_empty() {
        println!(
            "  {} replay(s) failed under their --dynamics draw and were dropped (--keep-failed keeps them)",
            report.dropped.len()
        );
    }
    for k in &report.skipped {
        println!("  SKIPPED: {}: {}", k.source, k.reason);
    }
    for e in report.episodes.iter().filter(|e| !e.success) {
        println!(
            "  FAILED: {}/{} (max state deviation {:e})",
            e.task, e.episode, e.max_state_deviation
        );
    }
    println!("report: {}", out.join(dexjoco_augment::REPORT_MD).display());
    Ok(if failed > 0 || !report.skipped.is_empty() {
        ExitStatus::Partial
    } else {
        ExitStatus::Success
    })
}
