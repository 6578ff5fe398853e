//! Planning an augment run: which replays this run (or shard) owns, which are already on
//! disk (resume), and the units of work still to render.
//!
//! Shards split the list of every replay, in (task, episode, replay) order, into `N`
//! contiguous runs of about equal cost (frames x cameras): the split depends only on the
//! inputs and the settings, never on `-j`, the file system's listing order or the machine.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::assets::TaskAssets;
use crate::config::{AugmentConfig, replay_name};
use crate::error::AugmentError;
use crate::inputs::Source;
use crate::physics::recorded_frames;
use crate::report::ReplayRecord;
use crate::staging::{Outcome, dropped_path, read_record, read_record_file};
use dexjoco_sim::dynamics::{dynamics_seed, sample_dynamics};

/// The replays of each source that a run owns: all of them, or its shard's share.
pub(crate) fn owned_replays(
    sources: &[Source],
    config: &AugmentConfig,
    cameras: usize,
) -> Vec<Vec<usize>> {
    let mut owned = vec![Vec::new(); sources.len()];
    let Some(shard) = config.shard else {
        for o in &mut owned {
            *o = (0..config.replays).collect();
        }
        return owned;
    };
    let costs: Vec<u64> = sources
        .iter()
        .map(|s| (recorded_frames(s, config) * cameras) as u64)
        .collect();
    let total: u64 = costs.iter().sum::<u64>() * config.replays as u64;
    let mut before = 0u64;
    for (i, cost) in costs.iter().enumerate() {
        for r in 0..config.replays {
            if shard_of(before, *cost, total, shard.count) == shard.index {
                owned[i].push(r);
            }
            before += cost;
        }
    }
    owned
}

/// The shard of an item of `cost` after `before` of `total`: where its midpoint falls.
fn shard_of(before: u64, cost: u64, total: u64, count: usize) -> usize {
    if total == 0 {
        return 0;
    }
    let mid = u128::from(before) * 2 + u128::from(cost);
    let k = mid * count as u128 / (u128::from(total) * 2);
    (k as usize).min(count - 1)
}

/// Complete replay folders of an output, by (task id, episode id), then replay index,
/// with their records.
pub(crate) type ReplaysOnDisk = BTreeMap<(String, String), BTreeMap<usize, ReplayRecord>>;

/// The replays of `sources`' tasks already in the output, read once (none with
/// `--overwrite`, which starts clean).
pub(crate) fn replays_on_disk(config: &AugmentConfig, sources: &[Source]) -> ReplaysOnDisk {
    if config.overwrite {
        return ReplaysOnDisk::new();
    }
    let task_ids: BTreeSet<&str> = sources.iter().map(|s| s.spec.id.as_str()).collect();
    existing_replays(&config.out, &task_ids)
}

/// How many `owned` replays have no folder `on_disk` (nor, under `--dynamics` without
/// `--keep-failed`, the record of a dropped draw): the most this run can render, known
/// before the physics pass (which may still leave failed episodes out). 0 for a finalize
/// after the shards, or a resume of a complete run.
pub(crate) fn replays_to_render(
    config: &AugmentConfig,
    sources: &[Source],
    owned: &[Vec<usize>],
    on_disk: &ReplaysOnDisk,
) -> usize {
    let dropped_counts = config.dynamics && !config.keep_failed && !config.overwrite;
    sources
        .iter()
        .zip(owned)
        .map(|(s, owned)| {
            let disk = on_disk.get(&(s.spec.id.clone(), s.episode.id.clone()));
            owned
                .iter()
                .filter(|&&r| {
                    let done = disk.is_some_and(|d| d.contains_key(&r));
                    let name = replay_name(&s.episode.id, r);
                    let dropped =
                        dropped_counts && dropped_path(&config.out, &s.spec.id, &name).is_file();
                    !done && !dropped
                })
                .count()
        })
        .sum()
}

/// Replay folders already in `<out>/<task>/`, by (episode id, replay index), with their
/// records (only complete folders have one).
pub(crate) fn existing_replays(out: &Path, tasks: &BTreeSet<&str>) -> ReplaysOnDisk {
    let mut found = ReplaysOnDisk::new();
    for task in tasks {
        let Ok(rd) = fs_err::read_dir(out.join(task)) else {
            continue;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some((episode, r)) = name.rsplit_once("__r") else {
                continue;
            };
            let (Ok(r), Some(rec)) = (r.parse::<usize>(), read_record(&e.path())) else {
                continue;
            };
            if rec.name == name && rec.task == *task {
                found
                    .entry(((*task).to_owned(), episode.to_owned()))
                    .or_default()
                    .insert(r, rec);
            }
        }
    }
    found
}

/// What an earlier run left for one source's replays, and what is still to do.
pub(crate) struct SourceState {
    /// Replays done (folders) or dropped under `--dynamics` with the same draw.
    pub(crate) outcomes: BTreeMap<usize, Outcome>,
    /// Owned replays still to render.
    pub(crate) todo: Vec<usize>,
}

/// Sorts one source's replays into done and to do, checking that what is on disk was made
/// from this very episode with this seed.
pub(crate) fn source_state(
    src: &Source,
    source_hash: &str,
    owned: &[usize],
    on_disk: Option<&BTreeMap<usize, ReplayRecord>>,
    assets: &TaskAssets,
    config: &AugmentConfig,
) -> Result<SourceState, AugmentError> {
    let key = src.key();
    let mut outcomes = BTreeMap::new();
    // Every replay folder of this episode counts, also those past --replays (made by an
    // earlier run with more), so the report lists what convert will read.
    for (r, rec) in on_disk.into_iter().flatten() {
        let folder = config.out.join(&src.spec.id).join(&rec.name);
        let seed = dexjoco_render::randomize::replay_seed(config.seed, &key, *r);
        if rec.sample.seed != seed {
            return Err(AugmentError::Input(format!(
                "'{}' was made with another --seed (replay seed {}, now {seed}): augment into another --out, or pass --overwrite to start clean",
                folder.display(),
                rec.sample.seed
            )));
        }
        if rec.source_hash != source_hash {
            return Err(AugmentError::Input(format!(
                "'{}' was made from other content of episode '{key}' (now '{}'): another dataset with the same episode names? Augment into another --out, or pass --overwrite to start clean",
                folder.display(),
                src.path.display()
            )));
        }
        outcomes.insert(*r, Outcome::Kept(rec.clone()));
    }
    let mut todo = Vec::new();
    for &r in owned {
        if outcomes.contains_key(&r) {
            continue;
        }
        // Without --keep-failed (which would now keep it), a replay dropped under
        // --dynamics with the same seed, source and draw is done (a changed spec draws
        // again).
        let name = replay_name(&src.episode.id, r);
        if config.dynamics
            && !config.keep_failed
            && let Some(rec) = read_record_file(&dropped_path(&config.out, &src.spec.id, &name))
        {
            let seed = dexjoco_render::randomize::replay_seed(config.seed, &key, r);
            let draw = sample_dynamics(&src.spec, &assets.scene.model, dynamics_seed(seed))?;
            if rec.sample.seed == seed
                && rec.source_hash == source_hash
                && rec.dynamics.as_ref() == Some(&draw)
            {
                outcomes.insert(r, Outcome::Dropped(rec));
                continue;
            }
        }
        todo.push(r);
    }
    Ok(SourceState { outcomes, todo })
}

/// Replays per unit: one with `--dynamics` or the reference approach, else as few units as
/// keep every worker busy, since each unit simulates its episode once: one per episode
/// when there are at least twice as many episodes as workers, else as many per episode as
/// make the unit count a multiple of the worker count (the output never depends on it).
pub(crate) fn replays_per_unit(
    todo: usize,
    one_per_unit: bool,
    workers: usize,
    sources_with_work: usize,
) -> usize {
    if one_per_unit {
        1
    } else {
        let (workers, sources) = (workers.max(1), sources_with_work.max(1));
        let units_per_episode = if sources >= 2 * workers {
            1
        } else {
            workers / gcd(workers, sources)
        };
        todo.div_ceil(units_per_episode).max(1)
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Disk space per rendered frame (each camera's frame counted) of the replays of `tasks`
/// already in `out`: their folders' space over their steps x cameras; `None` when none
/// is there.
pub(crate) fn bytes_per_frame(out: &Path, tasks: &BTreeSet<&str>, cameras: usize) -> Option<f64> {
    let (mut bytes, mut frames) = (0u64, 0u64);
    for ((task, _), records) in existing_replays(out, tasks) {
        for rec in records.values() {
            bytes += tree_bytes(&out.join(&task).join(&rec.name));
            frames += (rec.steps * cameras) as u64;
        }
    }
    (frames > 0).then(|| bytes as f64 / frames as f64)
}

/// The disk space the files and folders under `dir` take (allocated blocks, which is
/// what fills a disk: a small file takes a whole block).
fn tree_bytes(dir: &Path) -> u64 {
    use std::os::unix::fs::MetadataExt;
    let Ok(rd) = fs_err::read_dir(dir) else {
        return 0;
    };
    rd.flatten()
        .map(|e| {
            let own = e.metadata().map_or(0, |m| m.blocks() * 512);
            match e.file_type() {
                Ok(t) if t.is_dir() => own + tree_bytes(&e.path()),
                _ => own,
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_keep_workers_busy_with_few_simulations() {
        // One episode, two workers: two units of two replays.
        assert_eq!(replays_per_unit(4, false, 2, 1), 2);
        // Three episodes, two workers: halves, six units in all.
        assert_eq!(replays_per_unit(10, false, 2, 3), 5);
        // Many episodes: whole episodes, each simulated once.
        assert_eq!(replays_per_unit(10, false, 16, 1100), 10);
        assert_eq!(replays_per_unit(10, false, 1, 1), 10);
        // The reference approach and --dynamics: one replay per unit.
        assert_eq!(replays_per_unit(10, true, 2, 1), 1);
    }

    #[test]
    fn shards_are_contiguous_balanced_and_cover_everything_once() {
        // 7 items of unequal cost over 3 shards.
        let costs = [10u64, 10, 30, 5, 5, 20, 20];
        let total: u64 = costs.iter().sum();
        let mut before = 0;
        let mut load = [0u64; 3];
        let mut last = 0;
        for c in costs {
            let k = shard_of(before, c, total, 3);
            assert!(k >= last, "contiguous");
            last = k;
            load[k] += c;
            before += c;
        }
        assert_eq!(load.iter().sum::<u64>(), total);
        assert_eq!(load, [20, 40, 40]);
        assert_eq!(shard_of(0, 5, 5, 1), 0);
    }
}
