//! `dexjoco-data dataset info|filter|split|merge|features|stats`: management of any LeRobot v3.0 dataset,
//! each writing a new dataset beside the source (never changed).

use dexjoco_dataset::SubsetReport;

use crate::cli::{DatasetCommand, GlobalArgs};
use crate::exit::ExitStatus;
use crate::progress::Bar;
use crate::settings::{
    DatasetFeaturesSettings, DatasetFilterSettings, DatasetMergeSettings, DatasetSplitSettings,
    dataset_or_default,
};

/// Runs a `dataset` subcommand.
pub fn run(global: &GlobalArgs, cmd: DatasetCommand) -> anyhow::Result<ExitStatus> {
    match cmd {
        DatasetCommand::Info(args) => {
            let dataset = dataset_or_default(args.dataset, global)?;
            let summary = dexjoco_dataset::info(&dataset)?;
            if args.json {
                outln!("{}", serde_json::to_string_pretty(&summary)?);
            } else {
                outln!("{}", summary.text().trim_end());
            }
        }
        DatasetCommand::Filter(args) => {
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
        }
        DatasetCommand::Split(args) => {
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
        }
        DatasetCommand::Merge(args) => {
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
        }
        DatasetCommand::Features(args) => {
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
        }
        DatasetCommand::Stats(args) => {
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
        }
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
