//! `convert --norm-stats` against openpi's own code: the reference copy of
//! `openpi/shared/normalize.py` (`RunningStats`, `save`, `load`), imported in place by
//! `tests/python/openpi_norm_stats.py` and fed as openpi's `compute_norm_stats.py` feeds
//! it (lerobot's loader with action chunks, batches of 32 frames in dataset order, the
//! tail dropped) from the LeRobot v3.0 dataset convert wrote; the file's structure
//! against the DexJoCo authors' `norm_stats.json` files.

use std::path::{Path, PathBuf};

use dexjoco_convert::{ConvertOptions, InputEpisode, NormStatsOptions, convert};
use dexjoco_core::{NoProgress, TaskSet};
use dexjoco_formats::discover_input;
use serde_json::Value;

/// The four statistics of each key, in openpi's order.
const STATS: [&str; 4] = ["mean", "std", "q01", "q99"];
/// float32's machine epsilon.
const EPS32: f64 = f32::EPSILON as f64;

/// The two click_mouse demonstrations shipped in `datasets/demos` (1044 frames, no videos).
fn demo_inputs() -> Vec<InputEpisode> {
    let dir = dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse");
    discover_input(&dir, None)
        .unwrap()
        .into_iter()
        .map(|source| InputEpisode {
            episode: source.read(TaskSet::builtin()).unwrap().episode,
            dir: source.path,
        })
        .collect()
}

fn openpi_src() -> PathBuf {
    dexjoco_testkit::reference_code_dir().join("openpi/src")
}

fn floats(v: &Value) -> Vec<f64> {
    let a = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    a.iter().map(|x| x.as_f64().unwrap()).collect()
}

/// The key paths of a JSON document in file order, arrays as their length.
fn structure(v: &Value, path: &str, out: &mut Vec<String>) {
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                structure(child, &format!("{path}/{k}"), out);
            }
        }
        Value::Array(a) => out.push(format!("{path}[{}]", a.len())),
        other => out.push(format!("{path}={other}")),
    }
}

fn structure_of(v: &Value) -> Vec<String> {
    let mut out = Vec::new();
    structure(v, "", &mut out);
    out
}

/// Every number of ours equals openpi's on the same batches widened to float64 (the
/// arithmetic ours uses): only the summation order inside a batch differs, a few ulp.
fn check_float64_feed(ours: &Value, openpi: &Value) {
    for key in ["state", "actions"] {
        for stat in STATS {
            let (a, b) = (floats(&ours[key][stat]), floats(&openpi[key][stat]));
            assert_eq!(a.len(), b.len(), "{key}.{stat}");
            for (j, (x, y)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-12 * y.abs().max(1.0),
                    "{key}.{stat}[{j}]: ours {x}, openpi (float64 batches) {y}"
                );
            }
        }
    }
}

/// openpi as it runs (float32 batches, float32 running mean and mean of squares): mean
/// within `k·ε32·rms` and variance within `3k·ε32·E[x²]` (`E[x²]` and `2·mean·Δmean`), a
/// first-order worst-case bound on float32 accumulation with `k` = updates + rows per
/// batch (`np.mean(batch, axis=0)` adds rows one after another in float32; each update
/// rounds once more); `rms² = E[x²]` from ours.
fn check_float32_feed(ours: &Value, openpi: &Value, batches: usize, rows: [usize; 2]) {
    for (key, rows) in ["state", "actions"].into_iter().zip(rows) {
        let k = (batches + rows) as f64;
        let (mean, std) = (floats(&ours[key]["mean"]), floats(&ours[key]["std"]));
        let (mean32, std32) = (floats(&openpi[key]["mean"]), floats(&openpi[key]["std"]));
        for j in 0..mean.len() {
            let mean_sq = mean[j] * mean[j] + std[j] * std[j];
            let (dm, dv) = (
                (mean[j] - mean32[j]).abs(),
                (std[j] * std[j] - std32[j] * std32[j]).abs(),
            );
            assert!(
                dm <= k * EPS32 * mean_sq.sqrt(),
                "{key}.mean[{j}]: ours {}, openpi (float32) {}",
                mean[j],
                mean32[j]
            );
            assert!(
                dv <= 3.0 * k * EPS32 * mean_sq,
                "{key}.std[{j}]: ours {}, openpi (float32) {}",
                std[j],
                std32[j]
            );
        }
    }
}

/// Our file's structure equals the DexJoCo authors' click_mouse files (same state and
/// action widths): keys, nesting, order, lengths.
fn check_authors_structure(ours: &Value) {
    let assets = dexjoco_testkit::reference_code_dir().join("openpi/assets");
    for task in ["click_mouse", "click_mouse_rand_full"] {
        let path = assets.join(task).join("local_repo/norm_stats.json");
        let authors: Value = serde_json::from_str(&fs_err::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(
            structure_of(ours),
            structure_of(&authors),
            "{}",
            path.display()
        );
    }
}

fn convert_demos(out: &Path, options: NormStatsOptions) {
    let summary = convert(
        demo_inputs().into_iter().map(Ok),
        out,
        &ConvertOptions {
            norm_stats: Some(options),
            ..ConvertOptions::default()
        },
        &NoProgress,
    )
    .unwrap();
    assert_eq!((summary.episodes, summary.frames), (2, 1044));
}

#[test]
fn norm_stats_equal_openpi_normalize_fed_as_compute_norm_stats() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lerobot");
    let options = NormStatsOptions::default();
    convert_demos(&out, options);
    let text = fs_err::read_to_string(out.join("norm_stats.json")).unwrap();
    let got = dexjoco_testkit::run_python_json(
        "openpi_norm_stats.py",
        &[
            openpi_src().to_str().unwrap(),
            out.to_str().unwrap(),
            out.to_str().unwrap(),
            &options.action_horizon.to_string(),
            &options.batch_size.to_string(),
        ],
    );
    // openpi's loader: 1044 frames, 32 whole batches, the last 20 frames left out.
    assert_eq!(
        (got["frames"].as_u64(), got["batches"].as_u64()),
        (Some(1044), Some(32))
    );
    assert_eq!(got["dtype"], "float32");
    let ours: Value = serde_json::from_str(&text).unwrap();
    check_float64_feed(&ours["norm_stats"], &got["float64"]);
    check_float32_feed(
        &ours["norm_stats"],
        &got["float32"],
        32,
        [32, 32 * options.action_horizon],
    );
    // openpi's load + serialize_json gives our file back byte for byte (key order, indent,
    // float formatting, no final newline), and its own save has the same structure.
    assert_eq!(got["ours_reserialized"].as_str(), Some(text.as_str()));
    let openpi_file: Value = serde_json::from_str(got["openpi_file"].as_str().unwrap()).unwrap();
    assert_eq!(structure_of(&ours), structure_of(&openpi_file));
    check_authors_structure(&ours);
}
