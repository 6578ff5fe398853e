//! Settings of the `dataset` subcommands, resolved from their arguments.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_dataset::{MergeOptions, Predicate, ReencodeOptions, Selection, SplitSizes, TrimRule};
use dexjoco_video::{Codec, Encoding, X264Preset};

use super::{must_exist, outputs_apart, usage};
use crate::cli::{
    DatasetFeaturesArgs, DatasetFilterArgs, DatasetMergeArgs, DatasetReencodeArgs,
    DatasetSplitArgs, DatasetTrimArgs, GlobalArgs, ReencodeCodecArg,
};

/// The dataset a `dataset` subcommand reads: the one given, else convert's.
pub fn dataset_or_default(
    dataset: Option<PathBuf>,
    global: &GlobalArgs,
) -> anyhow::Result<PathBuf> {
    let dataset = dataset.unwrap_or_else(|| global.work_dir.join("convert/lerobot-v3"));
    must_exist(
        &dataset,
        "give a LeRobot v3.0 dataset folder (holding meta/info.json), or run `dexjoco-data convert`",
    )?;
    Ok(dataset)
}

/// `DATASET<suffix>` beside the dataset.
fn beside(dataset: &Path, suffix: &str) -> PathBuf {
    let abs = dexjoco_formats::fs::resolve(dataset);
    let name = abs
        .file_name()
        .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    abs.with_file_name(format!("{name}{suffix}"))
}

/// `dataset filter`.
pub struct DatasetFilterSettings {
    /// The source dataset.
    pub dataset: PathBuf,
    /// Which episodes to keep.
    pub selection: Selection,
    /// The output dataset.
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetFilterSettings {
    /// Resolves `dataset filter`'s arguments.
    pub fn resolve(args: DatasetFilterArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let DatasetFilterArgs {
            dataset,
            out,
            episodes,
            task,
            min_length,
            max_length,
            predicates,
            drop,
            overwrite,
        } = args;
        let dataset = dataset_or_default(dataset, global)?;
        let out = out.unwrap_or_else(|| beside(&dataset, "_filtered"));
        outputs_apart(&[&out], &[&dataset])?;
        let predicates = predicates
            .iter()
            .map(|p| {
                p.parse::<Predicate>()
                    .map_err(|e| usage(format!("--where {e}"), "as --where 'success == true'"))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let selection = Selection {
            episodes: episode_list(&episodes)?,
            tasks: task,
            min_length,
            max_length,
            predicates,
            drop,
        };
        if selection == Selection::default() {
            return Err(usage(
                "dataset filter: no condition given".into(),
                "give --episodes, --task, --min-length/--max-length or --where",
            ));
        }
        Ok(Self {
            dataset,
            selection,
            out,
            overwrite,
        })
    }
}

/// `0,2,5-7` as index ranges (both ends included), never expanded here: a range is
/// checked against the dataset before anything is made of it.
fn episode_list(items: &[String]) -> anyhow::Result<Vec<std::ops::RangeInclusive<usize>>> {
    let mut out = Vec::new();
    for item in items.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        let bad = || {
            usage(
                format!("--episodes: {item:?} is no index or range A-B"),
                "as --episodes 0,2,5-7",
            )
        };
        match item.split_once('-') {
            Some((a, b)) => {
                let (a, b): (usize, usize) = (
                    a.trim().parse().map_err(|_| bad())?,
                    b.trim().parse().map_err(|_| bad())?,
                );
                if a > b {
                    return Err(bad());
                }
                out.push(a..=b);
            }
            None => {
                let i: usize = item.parse().map_err(|_| bad())?;
                out.push(i..=i);
            }
        }
    }
    Ok(out)
}

/// `dataset split`.
pub struct DatasetSplitSettings {
    /// The source dataset.
    pub dataset: PathBuf,
    /// Split names and fractions.
    pub sizes: SplitSizes,
    /// Seed of the shuffle.
    pub seed: u64,
    /// The output folder (one dataset per split inside).
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetSplitSettings {
    /// Resolves `dataset split`'s arguments.
    pub fn resolve(args: DatasetSplitArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let DatasetSplitArgs {
            dataset,
            splits,
            seed,
            out,
            overwrite,
        } = args;
        let dataset = dataset_or_default(dataset, global)?;
        let out = out.unwrap_or_else(|| beside(&dataset, "_split"));
        outputs_apart(&[&out], &[&dataset])?;
        let sizes = splits
            .parse::<SplitSizes>()
            .map_err(|e| usage(format!("--splits {e}"), "as --splits train=0.9,val=0.1"))?;
        Ok(Self {
            dataset,
            sizes,
            seed,
            out,
            overwrite,
        })
    }
}

/// `dataset merge`.
pub struct DatasetMergeSettings {
    /// The source datasets, in order.
    pub datasets: Vec<PathBuf>,
    /// How they are reconciled.
    pub options: MergeOptions,
    /// The output dataset.
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetMergeSettings {
    /// Resolves `dataset merge`'s arguments.
    pub fn resolve(args: DatasetMergeArgs) -> anyhow::Result<Self> {
        let DatasetMergeArgs {
            datasets,
            out,
            rename,
            pad,
            overwrite,
        } = args;
        for d in &datasets {
            must_exist(
                d,
                "give LeRobot v3.0 dataset folders (holding meta/info.json)",
            )?;
        }
        let inputs: Vec<&Path> = datasets.iter().map(PathBuf::as_path).collect();
        outputs_apart(&[&out], &inputs)?;
        let rename = renames(&rename)?;
        Ok(Self {
            datasets,
            options: MergeOptions {
                rename,
                pad,
                ..MergeOptions::default()
            },
            out,
            overwrite,
        })
    }
}

/// `OLD=NEW` pairs.
fn renames(items: &[String]) -> anyhow::Result<Vec<(String, String)>> {
    items
        .iter()
        .map(|r| {
            r.split_once('=')
                .filter(|(a, b)| !a.trim().is_empty() && !b.trim().is_empty())
                .map(|(a, b)| (a.trim().to_owned(), b.trim().to_owned()))
                .ok_or_else(|| {
                    usage(
                        format!("--rename {r:?}: expected OLD=NEW"),
                        "as --rename observation.images.cam_high=observation.images.top",
                    )
                })
        })
        .collect()
}

/// `dataset features`.
pub struct DatasetFeaturesSettings {
    /// The source dataset.
    pub dataset: PathBuf,
    /// Renames and removals.
    pub options: MergeOptions,
    /// The output dataset.
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetFeaturesSettings {
    /// Resolves `dataset features`' arguments.
    pub fn resolve(args: DatasetFeaturesArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let DatasetFeaturesArgs {
            dataset,
            out,
            remove,
            rename,
            overwrite,
        } = args;
        let dataset = dataset_or_default(dataset, global)?;
        outputs_apart(&[&out], &[&dataset])?;
        let rename = renames(&rename)?;
        if remove.is_empty() && rename.is_empty() {
            return Err(usage(
                "dataset features: nothing to do".into(),
                "give --remove KEY or --rename OLD=NEW",
            ));
        }
        Ok(Self {
            dataset,
            options: MergeOptions {
                rename,
                pad: false,
                remove,
            },
            out,
            overwrite,
        })
    }
}

/// `dataset trim`, resolved.
#[derive(Debug)]
pub struct DatasetTrimSettings {
    /// The source dataset.
    pub dataset: PathBuf,
    /// Which frames to keep.
    pub rule: TrimRule,
    /// The output dataset.
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetTrimSettings {
    /// Resolves `dataset trim`'s arguments.
    pub fn resolve(args: DatasetTrimArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let DatasetTrimArgs {
            dataset,
            out,
            idle,
            column,
            threshold,
            margin,
            frames,
            overwrite,
        } = args;
        let dataset = dataset_or_default(dataset, global)?;
        let out = out.unwrap_or_else(|| beside(&dataset, "_trimmed"));
        outputs_apart(&[&out], &[&dataset])?;
        let rule = match (idle, frames.is_empty()) {
            (true, _) => TrimRule::Idle {
                column,
                threshold,
                margin,
            },
            (false, false) => TrimRule::Ranges(frame_ranges(&frames)?),
            (false, true) => {
                return Err(usage(
                    "dataset trim: nothing to trim by".into(),
                    "give --idle, or --frames EPISODE=FROM..TO",
                ));
            }
        };
        Ok(Self {
            dataset,
            rule,
            out,
            overwrite,
        })
    }
}

/// `3=10..250` items as episode -> frame range.
fn frame_ranges(items: &[String]) -> anyhow::Result<BTreeMap<usize, (i64, i64)>> {
    let mut out = BTreeMap::new();
    for item in items {
        let bad = || {
            usage(
                format!("--frames: {item:?} is not EPISODE=FROM..TO"),
                "as --frames 3=10..250 (frames 10 to 249 of episode 3)",
            )
        };
        let (episode, range) = item.split_once('=').ok_or_else(bad)?;
        let (from, to) = range.split_once("..").ok_or_else(bad)?;
        let episode: usize = episode.trim().parse().map_err(|_| bad())?;
        let range = (
            from.trim().parse().map_err(|_| bad())?,
            to.trim().parse().map_err(|_| bad())?,
        );
        if out.insert(episode, range).is_some() {
            return Err(usage(
                format!("--frames: episode {episode} is given twice"),
                "one range per episode",
            ));
        }
    }
    Ok(out)
}

/// `dataset reencode`, resolved.
#[derive(Debug)]
pub struct DatasetReencodeSettings {
    /// The source dataset.
    pub dataset: PathBuf,
    /// What to encode, and how.
    pub options: ReencodeOptions,
    /// The output dataset.
    pub out: PathBuf,
    /// Replace `out`.
    pub overwrite: bool,
}

impl DatasetReencodeSettings {
    /// Resolves `dataset reencode`'s arguments.
    pub fn resolve(args: DatasetReencodeArgs, global: &GlobalArgs) -> anyhow::Result<Self> {
        let DatasetReencodeArgs {
            dataset,
            out,
            codec,
            crf,
            preset,
            gop,
            keys,
            overwrite,
        } = args;
        let dataset = dataset_or_default(dataset, global)?;
        let out = out.unwrap_or_else(|| beside(&dataset, "_reencoded"));
        outputs_apart(&[&out], &[&dataset])?;
        let codec = match codec {
            ReencodeCodecArg::H264 => Codec::H264 {
                crf: crf.unwrap_or(23).min(51),
                preset: match preset {
                    Some(p) => p
                        .parse()
                        .map_err(|e: String| usage(format!("--preset: {e}"), "as --preset fast"))?,
                    None => X264Preset::Medium,
                },
            },
            ReencodeCodecArg::Av1 => Codec::Av1 {
                crf: crf.unwrap_or(30),
                preset: match preset {
                    Some(p) => p.parse::<u8>().ok().filter(|p| *p <= 13).ok_or_else(|| {
                        usage(
                            format!("--preset: {p:?} is no SVT-AV1 preset (0..13)"),
                            "as --preset 8",
                        )
                    })?,
                    None => 12,
                },
            },
        };
        Ok(Self {
            dataset,
            options: ReencodeOptions {
                encoding: Encoding {
                    codec,
                    interval: gop,
                },
                keys,
                jobs: global.jobs.unwrap_or_else(dexjoco_core::available_cores),
            },
            out,
            overwrite,
        })
    }
}
