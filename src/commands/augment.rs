//! `dexjoco-data augment`: randomized, validated replays of episodes, rendered from one
//! simulation per episode, written in the DexJoCo raw layout with a report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_augment::augment;

use crate::cli::{AugmentArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::AugmentSettings;

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
            status: ExitStatus::Failure,
        }
        .into()
    })
}

/// Runs `augment`.
pub fn run(global: &GlobalArgs, args: AugmentArgs) -> anyhow::Result<ExitStatus> {
    let AugmentSettings { config } = AugmentSettings::resolve(args, global, sample_data)?;
    let out = config.out.clone();
    let bar = Bar::new("augment", global.quiet);
    let started = std::time::Instant::now();
    let report =
        augment(&config, &bar).with_context(|| format!("augmenting into {}", out.display()))?;
    bar.finish();
    let failed = report.failed_episodes();
    let ok = report.episodes.len() - failed;
    outln!(
        "augment: {} episode(s) replayed to success, {failed} failed; {} replay(s) in {} ({} rendered now, {:.1} s)",
        ok,
        report.replays.len(),
        out.display(),
        report.rendered_now,
        started.elapsed().as_secs_f64()
    );
    if !report.dropped.is_empty() {
        outln!(
            "  {} replay(s) failed under their --dynamics draw and were dropped (--keep-failed keeps them)",
            report.dropped.len()
        );
    }
    for k in &report.skipped {
        outln!("  SKIPPED: {}: {}", k.source, k.reason);
    }
    for e in report.episodes.iter().filter(|e| !e.success) {
        outln!(
            "  FAILED: {}/{} (max state deviation {:e})",
            e.task,
            e.episode,
            e.max_state_deviation
        );
    }
    outln!("report: {}", out.join(dexjoco_augment::REPORT_MD).display());
    Ok(if failed > 0 || !report.skipped.is_empty() {
        ExitStatus::Partial
    } else {
        ExitStatus::Success
    })
}
