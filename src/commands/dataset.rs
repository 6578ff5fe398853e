//! `dexjoco-data dataset info|filter|split|merge|features|trim|reencode|stats|to-v21`: management of
//! any LeRobot v3.0 dataset, each writing a new dataset beside the source (never
//! changed; `stats` rewrites the statistics in place, keeping the previous file).

use dexjoco_dataset::SubsetReport;

use crate::cli::{
    DatasetCommand, DatasetFeaturesArgs, DatasetFilterArgs, DatasetInfoArgs, DatasetMergeArgs,
    DatasetReencodeArgs, DatasetSplitArgs, DatasetStatsArgs, DatasetToV21Args, DatasetTrimArgs,
    GlobalArgs,
};
use crate::exit::ExitStatus;
use crate::progress::Bar;
use crate::settings::{
    DatasetFeaturesSettings, DatasetFilterSettings, DatasetMergeSettings, DatasetReencodeSettings,
    DatasetSplitSettings, DatasetTrimSettings, dataset_or_default,
};

/// Runs a `dataset` subcommand.
pub fn run(global: &GlobalArgs, cmd: DatasetCommand) -> anyhow::Result<ExitStatus> {
    match cmd {
        DatasetCommand::Info(args) => info(global, args)?,
        DatasetCommand::Filter(args) => filter(global, args)?,
        DatasetCommand::Split(args) => split(global, args)?,
        DatasetCommand::Merge(args) => merge(global, args)?,
        DatasetCommand::Features(args) => features(global, args)?,
        DatasetCommand::Trim(args) => trim(global, args)?,
        DatasetCommand::Reencode(args) => reencode(global, args)?,
        DatasetCommand::Stats(args) => stats(global, args)?,
        DatasetCommand::ToV21(args) => to_v21(global, args)?,
    }
    Ok(ExitStatus::Success)
}

/// `wrote 8 episodes (1,234 frames, 2 tasks) to OUT: 3 data files, videos 2 copied, 1 cut`.
fn describe(r: &SubsetReport, out: &str) -> String {
    format!(
        "wrote {} episodes ({} frames, {} task(s)) to {out}: {} data file(s), video files {} \
         copied whole and {} cut by stream copy",
        r.episodes, r.frames, r.tasks, r.data_files, r.videos_copied, r.videos_cut
    )
}

/// `dataset info`.
fn info(global: &GlobalArgs, args: DatasetInfoArgs) -> anyhow::Result<()> {
    let dataset = dataset_or_default(args.dataset, global)?;
    let summary = dexjoco_dataset::info(&dataset)?;
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        outln!("{}", summary.text().trim_end());
    }
    Ok(())
}

/// `dataset filter`.
fn filter(global: &GlobalArgs, args: DatasetFilterArgs) -> anyhow::Result<()> {
    let DatasetFilterSettings {
        dataset,
        selection,
        out,
        overwrite,
    } = DatasetFilterSettings::resolve(args, global)?;
    let bar = Bar::new("filter", global.quiet);
    let report = dexjoco_dataset::filter(&dataset, &selection, &out, overwrite, &bar)?;
    bar.finish();
    errln!("{}", describe(&report, &out.display().to_string()));
    outln!("{}", out.display());
    Ok(())
}

/// `dataset split`.
fn split(global: &GlobalArgs, args: DatasetSplitArgs) -> anyhow::Result<()> {
    let DatasetSplitSettings {
        dataset,
        sizes,
        seed,
        out,
        overwrite,
    } = DatasetSplitSettings::resolve(args, global)?;
    let bar = Bar::new("split", global.quiet);
    let reports = dexjoco_dataset::split(&dataset, &sizes, seed, &out, overwrite, &bar)?;
    bar.finish();
    for (name, report) in &reports {
        let at = out.join(name);
        errln!("{}", describe(report, &at.display().to_string()));
        outln!("{}", at.display());
    }
    Ok(())
}

/// `dataset merge`.
fn merge(global: &GlobalArgs, args: DatasetMergeArgs) -> anyhow::Result<()> {
    let DatasetMergeSettings {
        datasets,
        options,
        out,
        overwrite,
    } = DatasetMergeSettings::resolve(args)?;
    let bar = Bar::new("merge", global.quiet);
    let report = dexjoco_dataset::merge(&datasets, &options, &out, overwrite, &bar)?;
    bar.finish();
    errln!("{}", describe(&report, &out.display().to_string()));
    outln!("{}", out.display());
    Ok(())
}

/// `dataset features`.
fn features(global: &GlobalArgs, args: DatasetFeaturesArgs) -> anyhow::Result<()> {
    let DatasetFeaturesSettings {
        dataset,
        options,
        out,
        overwrite,
    } = DatasetFeaturesSettings::resolve(args, global)?;
    let bar = Bar::new("features", global.quiet);
    let report = dexjoco_dataset::edit_features(&dataset, &options, &out, overwrite, &bar)?;
    bar.finish();
    errln!("{}", describe(&report, &out.display().to_string()));
    outln!("{}", out.display());
    Ok(())
}

/// `dataset trim`.
fn trim(global: &GlobalArgs, args: DatasetTrimArgs) -> anyhow::Result<()> {
    let DatasetTrimSettings {
        dataset,
        rule,
        out,
        overwrite,
    } = DatasetTrimSettings::resolve(args, global)?;
    let bar = Bar::new("trim", global.quiet);
    let report = dexjoco_dataset::trim(&dataset, &rule, &out, overwrite, &bar)?;
    bar.finish();
    if !report.still_episodes.is_empty() {
        errln!(
            "no movement found in episode(s) {:?}: kept whole",
            report.still_episodes
        );
    }
    let w = &report.written;
    errln!(
        "trimmed {} of {} episodes ({} frames removed, {} kept) into {}: video files {} cut \
         ({} frames re-encoded by smart cuts), {} re-encoded whole",
        report.episodes_trimmed,
        w.episodes,
        report.frames_removed,
        w.frames,
        out.display(),
        w.videos_cut + w.videos_copied,
        w.frames_reencoded,
        w.videos_reencoded
    );
    outln!("{}", out.display());
    Ok(())
}

/// `dataset reencode`.
fn reencode(global: &GlobalArgs, args: DatasetReencodeArgs) -> anyhow::Result<()> {
    let DatasetReencodeSettings {
        dataset,
        options,
        out,
        overwrite,
    } = DatasetReencodeSettings::resolve(args, global)?;
    let bar = Bar::new("reencode", global.quiet);
    let report = dexjoco_dataset::reencode(&dataset, &options, &out, overwrite, &bar)?;
    bar.finish();
    let mb = |b: u64| b as f64 / 1e6;
    errln!(
        "re-encoded {} video file(s), {} frames, into {}: {:.1} MB -> {:.1} MB",
        report.files,
        report.frames,
        out.display(),
        mb(report.bytes_before),
        mb(report.bytes_after)
    );
    outln!("{}", out.display());
    Ok(())
}

/// `dataset stats`.
fn stats(global: &GlobalArgs, args: DatasetStatsArgs) -> anyhow::Result<()> {
    let dataset = dataset_or_default(args.dataset, global)?;
    let norm = crate::settings::norm_stats_options(&args.norm_stats);
    let report = dexjoco_dataset::restat(&dataset, norm)?;
    for (feature, off) in &report.previous_off_by {
        errln!("  {feature:<40} previous statistics off by up to {off:.6}");
    }
    errln!(
        "wrote {} ({} features){}{}",
        dataset.join("meta/stats.json").display(),
        report.features,
        report.backup.as_ref().map_or(String::new(), |b| format!(
            "; the previous one kept as {}",
            b.display()
        )),
        report
            .norm_stats
            .as_ref()
            .map_or(String::new(), |n| format!("; and {}", n.display()))
    );
    Ok(())
}

/// `dataset to-v21`.
fn to_v21(global: &GlobalArgs, args: DatasetToV21Args) -> anyhow::Result<()> {
    let dataset = dataset_or_default(args.dataset, global)?;
    crate::settings::outputs_apart(&[&args.out], &[&dataset])?;
    let bar = Bar::new("to-v21", global.quiet);
    let report = dexjoco_dataset::to_v21(&dataset, &args.out, args.overwrite, &bar)?;
    bar.finish();
    errln!(
        "wrote {} episodes ({} frames) as LeRobot v2.1 to {}: {} episode video(s) cut by stream copy",
        report.episodes,
        report.frames,
        args.out.display(),
        report.videos_cut
    );
    outln!("{}", args.out.display());
    Ok(())
}
