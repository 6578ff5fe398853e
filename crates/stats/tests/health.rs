//! The health section of the dataset statistics: each defect injected into small
//! synthetic episodes (written with the raw writer, read back by the one reader) is
//! caught and named; a clean dataset gives no warning; `convert --norm-stats` names a
//! zero-variance column and keeps the file as openpi writes it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, TaskSet, TaskSpec, synth};
use dexjoco_formats::raw::{REPLAY_RECORD, write_raw_episode};
use dexjoco_stats::{DatasetStats, EpisodeFiles, Flatness, Health};
use serde_json::{Value, json};

const FRAMES: usize = 40;

fn spec(task: &str) -> &'static TaskSpec {
    TaskSet::builtin().get(task).unwrap()
}

/// A synthetic episode of `task` with its values varied by `seed`.
fn episode(task: &str, frames: usize, seed: u64) -> Episode {
    synth::episode(spec(task), frames, seed)
}

/// Writes `episode` as `<root>/<task>/<id>` with an optional replay record.
fn write(root: &Path, id: &str, e: &Episode, record: Option<Value>) -> PathBuf {
    let dir = root.join(&e.task).join(id);
    write_raw_episode(&dir, e, spec(&e.task)).unwrap();
    if let Some(r) = record {
        fs_err::write(dir.join(REPLAY_RECORD), r.to_string()).unwrap();
    }
    dir
}

/// Reads every episode under `root` as `stats --dataset` does and computes the stats.
fn stats_of(root: &Path) -> DatasetStats {
    let sources = dexjoco_formats::discover(&[root.to_path_buf()], None).unwrap();
    let mut episodes = Vec::new();
    let mut files = Vec::new();
    for s in &sources {
        let e = s.read(TaskSet::builtin()).unwrap().episode;
        files.push(EpisodeFiles::read(&s.path, &e).unwrap());
        episodes.push(e);
    }
    DatasetStats::compute_with_files(&episodes, &files, TaskSet::builtin()).unwrap()
}

fn warned(h: &Health, all: &[&str]) -> bool {
    h.warnings.iter().any(|w| all.iter().all(|s| w.contains(s)))
}

/// Four clean click_mouse episodes (lengths 40..46): every state column moves (the
/// synthetic episodes hold some still).
fn clean_episodes() -> Vec<Episode> {
    (0..4)
        .map(|i| {
            let mut e = episode("click_mouse", FRAMES + 2 * i, 11 + i as u64);
            let state = e.arrays.get_mut(Episode::STATE).unwrap();
            for k in 0..state.len() {
                for (j, v) in state.row_mut(k).iter_mut().enumerate() {
                    *v += 0.01 * ((k + i) as f64 * 0.37 + j as f64).sin();
                }
            }
            e
        })
        .collect()
}

#[test]
fn a_clean_dataset_gives_no_warning() {
    let dir = tempfile::tempdir().unwrap();
    for (i, e) in clean_episodes().iter().enumerate() {
        write(dir.path(), &format!("episode_{i:06}"), e, None);
    }
    let h = stats_of(dir.path()).health;
    assert!(h.warnings.is_empty(), "{:#?}", h.warnings);
    assert!(h.duplicates.full.is_empty() && h.duplicates.same_arrays.is_empty());
    assert_eq!(h.outcomes[0].recordings, 4);
    assert_eq!(h.lengths[0].count, 4);
    assert!(h.lengths[0].outliers.is_empty());
    assert!(h.to_markdown().contains("No warnings."));
}

/// click_mouse episodes with a constant and a near-constant state column, static leading
/// frames, a duplicate and a length outlier.
fn write_defective_click_mouse(root: &Path) {
    let mut eps = clean_episodes();
    eps.push(episode("click_mouse", 5 * FRAMES, 99)); // a length outlier
    for e in &mut eps {
        let state = e.arrays.get_mut(Episode::STATE).unwrap();
        for k in 0..state.len() {
            // mouse.pose[0] constant, mouse.pose[1] wobbling at 1e-7.
            state.row_mut(k)[23] = 0.25;
            state.row_mut(k)[24] = 0.5 + 1e-7 * (k % 3) as f64;
        }
    }
    // Episode 1 holds still for its first 6 frames: 5 static leading frames.
    let action = eps[1].arrays.get_mut(Episode::ACTION).unwrap();
    let first = action.row(0).to_vec();
    for k in 1..6 {
        action.row_mut(k).copy_from_slice(&first);
    }
    for (i, e) in eps.iter().enumerate() {
        write(root, &format!("episode_{i:06}"), e, None);
    }
    // A duplicate of episode 2 under another folder.
    write(root, "episode_000009", &eps[2], None);
}

/// pinch_tongs replays: succeeded and clean, failed, flagged twice, and a recording.
fn write_pinch_tongs_replays(root: &Path) {
    let flags = json!([
        {"check": "blank_frame", "camera": "front", "first_frame": 3, "last_frame": 5,
         "detail": "every pixel (0, 0, 0)"},
        {"check": "non_finite", "array": "state", "first_frame": 7, "last_frame": 7,
         "detail": "NaN"}
    ]);
    let records = [
        Some(json!({"success": true, "flags": []})),
        Some(json!({"success": false, "flags": []})),
        Some(json!({"success": true, "flags": flags})),
        None,
    ];
    for (i, r) in records.into_iter().enumerate() {
        let e = episode("pinch_tongs", FRAMES, 50 + i as u64);
        write(root, &format!("replay_{i:06}"), &e, r);
    }
}

/// Two hammer_nail replays of one source: the same arrays, different video bytes.
fn write_replays_of_one_source(root: &Path) {
    let e = episode("hammer_nail", FRAMES, 77);
    for (i, bytes) in [b"first rendering".as_slice(), b"second rendering"]
        .iter()
        .enumerate()
    {
        let dir = write(
            root,
            &format!("replay_{i:06}"),
            &e,
            Some(json!({"success": true, "flags": []})),
        );
        fs_err::create_dir_all(dir.join("videos")).unwrap();
        fs_err::write(dir.join("videos/front.mp4"), bytes).unwrap();
    }
}

#[test]
fn each_injected_defect_is_caught_and_named() {
    let dir = tempfile::tempdir().unwrap();
    write_defective_click_mouse(dir.path());
    write_pinch_tongs_replays(dir.path());
    write_replays_of_one_source(dir.path());
    let stats = stats_of(dir.path());
    let h = &stats.health;

    // Zero-variance and near-constant columns, named after the task spec.
    let flat = |column: &str| {
        h.flat_dimensions
            .iter()
            .find(|d| d.scope == "click_mouse" && d.array == "state" && d.column == column)
    };
    let c = flat("mouse.pose[0]").expect("the constant column");
    assert_eq!((c.flatness, c.index, c.std), (Flatness::Constant, 23, 0.0));
    assert_eq!(c.lerobot_gain, 1e8);
    assert_eq!(c.openpi_gain, 1e6);
    let n = flat("mouse.pose[1]").expect("the near-constant column");
    assert_eq!(n.flatness, Flatness::NearConstant);
    assert!(n.std > 0.0 && n.openpi_gain > 1e5, "{n:?}");
    assert!(warned(
        h,
        &[
            "task click_mouse",
            "1 constant and 1 near-constant",
            "state 'mouse.pose[0]', 'mouse.pose[1]'",
        ]
    ));

    // Static leading frames, counted per episode.
    let s = &h.static_leading[0];
    assert_eq!(s.task, "click_mouse");
    assert_eq!(s.with_static.len(), 1, "{s:?}");
    assert_eq!(
        (s.with_static[0].episode.as_str(), s.with_static[0].frames),
        ("episode_000001", 5)
    );

    // The length outlier: 200 frames against a median of 44.
    let l = &h.lengths[0];
    assert_eq!((l.count, l.min, l.max, l.median), (6, 40, 200, 44.0));
    assert_eq!(l.outliers.len(), 1);
    assert_eq!(l.outliers[0].episode, "episode_000004");
    assert!(warned(
        h,
        &["episode_000004", "200 frames", "convert --exclude"]
    ));

    // The duplicate: same arrays, no videos, so a full duplicate.
    assert_eq!(h.duplicates.full.len(), 1, "{:?}", h.duplicates);
    let members: Vec<&str> = h.duplicates.full[0]
        .episodes
        .iter()
        .map(|(_, e)| e.as_str())
        .collect();
    assert_eq!(members, ["episode_000002", "episode_000009"]);
    assert!(warned(h, &["click_mouse/episode_000002", "duplicates"]));
    // Replays of one source share their arrays by design: listed, not warned about.
    let same = &h.duplicates.same_arrays;
    assert_eq!(same.len(), 1, "{same:?}");
    assert!(same[0].replays && same[0].episodes[0].0 == "hammer_nail");
    assert!(
        !warned(h, &["hammer_nail/replay_000000"]),
        "{:#?}",
        h.warnings
    );

    assert_outcomes_and_tables(&stats);
}

/// Success and flag rates per task and per check, and the tables in both files.
fn assert_outcomes_and_tables(stats: &DatasetStats) {
    let h = &stats.health;
    let o = h.outcomes.iter().find(|o| o.task == "pinch_tongs").unwrap();
    assert_eq!(
        (o.recordings, o.replays, o.succeeded, o.checked, o.flagged),
        (1, 3, 2, 3, 1)
    );
    assert_eq!(o.per_check["blank_frame"], 1);
    assert_eq!(o.per_check["non_finite"], 1);
    assert_eq!(o.per_check["frozen_video"], 0);
    assert!(warned(h, &["task pinch_tongs", "1 of 3 replays failed"]));
    assert!(warned(
        h,
        &[
            "replay_000002",
            "blank_frame on front, frames 3-5",
            "non_finite in state"
        ]
    ));
    let click = h.outcomes.iter().find(|o| o.task == "click_mouse").unwrap();
    assert_eq!((click.recordings, click.replays), (6, 0));

    // The tables: in summary.md and dataset_stats.json.
    let md = stats.to_markdown();
    assert!(md.contains("### Health"), "{md}");
    assert!(
        md.contains(
            "| pinch_tongs | 1 | 3 | 2 (67 %) | 3 | 1 (33 %) | 1 (33 %) | 0 (0 %) | 1 (33 %) |"
        ),
        "{md}"
    );
    assert!(
        md.contains("| click_mouse | 6 | 40 | 41.0 | 44.0 | "),
        "{md}"
    );
    let out = tempfile::tempdir().unwrap();
    stats.write(out.path()).unwrap();
    let json: Value = serde_json::from_str(
        &fs_err::read_to_string(out.path().join("dataset_stats.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        json["health"]["warnings"].as_array().unwrap().len(),
        h.warnings.len()
    );
    let back: DatasetStats = serde_json::from_value(json).unwrap();
    assert_eq!(&back.health, h);
}

#[test]
fn norm_stats_warn_about_a_constant_state_column_and_keep_openpis_file() {
    use dexjoco_convert::{ConvertOptions, InputEpisode, NormStatsOptions};
    use dexjoco_formats::openpi::{NORM_STATS, flat_columns};
    let dir = tempfile::tempdir().unwrap();
    let inputs: Vec<InputEpisode> = clean_episodes()
        .into_iter()
        .enumerate()
        .map(|(i, mut e)| {
            let state = e.arrays.get_mut(Episode::STATE).unwrap();
            for k in 0..state.len() {
                state.row_mut(k)[7] = 0.25;
            }
            e.id = format!("episode_{i:06}");
            let dir = write(dir.path(), &e.id, &e, None);
            InputEpisode { episode: e, dir }
        })
        .collect();
    let out = dir.path().join("lerobot");
    let options = ConvertOptions {
        norm_stats: Some(NormStatsOptions {
            action_horizon: 4,
            batch_size: 8,
        }),
        ..ConvertOptions::default()
    };
    dexjoco_convert::convert(
        inputs.into_iter().map(Ok),
        &out,
        &options,
        &dexjoco_core::NoProgress,
    )
    .unwrap();
    let text = fs_err::read_to_string(out.join(NORM_STATS)).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    // The file as openpi writes it: the std of the constant column is 0, not guarded.
    assert_eq!(doc["norm_stats"]["state"]["std"][7], json!(0.0));
    let info: Value =
        serde_json::from_str(&fs_err::read_to_string(out.join("meta/info.json")).unwrap()).unwrap();
    let names: Vec<String> =
        serde_json::from_value(info["features"]["observation.state"]["names"].clone()).unwrap();
    let flat = flat_columns(&doc, &BTreeMap::from([("state".to_owned(), names)]));
    let state: Vec<_> = flat.iter().filter(|c| c.key == "state").collect();
    assert_eq!(state.len(), 1, "{flat:?}");
    assert_eq!(
        (state[0].index, state[0].name.as_str()),
        (7, "arm.hand_qpos[0]")
    );
    let w = state[0].warning();
    assert!(
        w.contains("state column 7 'arm.hand_qpos[0]' has zero variance") && w.contains("1e-6"),
        "{w}"
    );
    // Naming the columns leaves the file as openpi writes it.
    assert_eq!(fs_err::read_to_string(out.join(NORM_STATS)).unwrap(), text);
}
