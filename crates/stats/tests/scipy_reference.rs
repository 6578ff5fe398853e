//! The measures against SciPy, scikit-learn and NumPy in the cached test venv, on many
//! seeded random tables: dense, sparse and degenerate ones.

use std::collections::BTreeMap;

use dexjoco_core::{Episode, FrameArray};
use dexjoco_stats::measures::{chi_square, js_divergence, normalized_mutual_information};
use dexjoco_stats::{DatasetStats, LogBase};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

/// Relative tolerance of every comparison.
const REL: f64 = 1e-9;

/// `a` and `b` agree to `REL` relative, or both lie within `floor` of each other (for
/// values that are 0 up to rounding, where a relative error means nothing).
fn close(a: f64, b: f64, floor: f64) -> bool {
    a == b || (a - b).abs() <= REL * a.abs().max(b.abs()) || (a - b).abs() <= floor
}

fn random_table(rng: &mut ChaCha8Rng, kind: usize) -> Vec<Vec<u64>> {
    let rows = rng.random_range(1..=8);
    let cols = rng.random_range(1..=9);
    let mut t = vec![vec![0u64; cols]; rows];
    match kind {
        // Dense small counts.
        0 => t
            .iter_mut()
            .flatten()
            .for_each(|c| *c = rng.random_range(0..30)),
        // Sparse: most cells zero (all-zero rows and columns happen).
        1 => t.iter_mut().flatten().for_each(|c| {
            if rng.random_bool(0.2) {
                *c = rng.random_range(1..6);
            }
        }),
        // Large counts: tiny p-values.
        2 => t
            .iter_mut()
            .flatten()
            .for_each(|c| *c = rng.random_range(0..100_000)),
        // Near-independent: every row a multiple of one profile.
        3 => {
            let profile: Vec<u64> = (0..cols).map(|_| rng.random_range(1..10)).collect();
            for r in &mut t {
                let k = rng.random_range(1..5);
                r.iter_mut().zip(&profile).for_each(|(c, p)| *c = k * p);
            }
        }
        // Perfectly dependent: one output per instruction.
        4 => {
            for (i, r) in t.iter_mut().enumerate() {
                r[i % cols] = rng.random_range(1..40);
            }
        }
        // Explicit zero rows and columns in an otherwise dense table.
        5 => {
            t.iter_mut()
                .flatten()
                .for_each(|c| *c = rng.random_range(1..20));
            let zr = rng.random_range(0..rows);
            let zc = rng.random_range(0..cols);
            t[zr].iter_mut().for_each(|c| *c = 0);
            t.iter_mut().for_each(|r| r[zc] = 0);
        }
        // A single observation.
        _ => {
            let (i, j) = (rng.random_range(0..rows), rng.random_range(0..cols));
            t[i][j] = 1;
        }
    }
    t
}

#[test]
fn chi_square_nmi_and_js_match_scipy_and_sklearn() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut tables: Vec<Vec<Vec<u64>>> = (0..420).map(|k| random_table(&mut rng, k % 7)).collect();
    // Hand-made corner cases: one row, one column, one cell, a 2x2 (dof 1: SciPy would
    // apply Yates' correction by default; we compare with correction=False), all zeros.
    tables.extend([
        vec![vec![3, 5, 0, 2]],
        vec![vec![4], vec![0], vec![9]],
        vec![vec![12]],
        vec![vec![20, 10], vec![10, 20]],
        vec![vec![0, 0], vec![0, 0]],
        vec![vec![1, 0], vec![0, 1]],
    ]);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("tables.json");
    let payload: Vec<Value> = tables
        .iter()
        .map(|t| serde_json::json!({ "counts": t }))
        .collect();
    fs_err::write(&input, serde_json::to_string(&payload).unwrap()).unwrap();
    let reference = dexjoco_testkit::run_python_json(
        "stats_reference.py",
        &["tables", input.to_str().unwrap()],
    );
    let reference = reference.as_array().expect("a list of results");
    assert_eq!(reference.len(), tables.len());

    let (mut tested_chi, mut tiny_p, mut dropped, mut js_pairs) = (0, 0, 0, 0);
    for (t, r) in tables.iter().zip(reference) {
        let ours = chi_square(t);
        match &r["chi2"] {
            Value::Null => assert!(
                !ours.testable(),
                "{t:?}: SciPy has no test, we do: {ours:?}"
            ),
            c => {
                tested_chi += 1;
                let (stat, p, dof) = (
                    c["statistic"].as_f64().unwrap(),
                    c["p_value"].as_f64().unwrap(),
                    c["dof"].as_u64().unwrap(),
                );
                assert_eq!(ours.dof, dof, "{t:?}");
                assert!(
                    close(ours.statistic, stat, 1e-9),
                    "{t:?}: statistic {} vs SciPy {stat}",
                    ours.statistic
                );
                assert!(
                    close(ours.p_value, p, 1e-300),
                    "{t:?}: p {} vs SciPy {p}",
                    ours.p_value
                );
                tiny_p += usize::from(p < 1e-12 && p > 0.0);
                dropped +=
                    usize::from(!ours.dropped_rows.is_empty() || !ours.dropped_columns.is_empty());
            }
        }
        let nmi = r["nmi"].as_f64().unwrap();
        let our_nmi = normalized_mutual_information(t);
        assert!(
            close(our_nmi, nmi, 1e-12),
            "{t:?}: NMI {our_nmi} vs scikit-learn {nmi}"
        );

        let pairs = r["js"].as_array().unwrap();
        let ours: Vec<(usize, usize)> = (0..t.len())
            .flat_map(|a| (a + 1..t.len()).map(move |b| (a, b)))
            .filter(|&(a, b)| t[a].iter().sum::<u64>() > 0 && t[b].iter().sum::<u64>() > 0)
            .collect();
        assert_eq!(ours.len(), pairs.len(), "{t:?}");
        for ((a, b), pr) in ours.into_iter().zip(pairs) {
            assert_eq!(
                (a as u64, b as u64),
                (pr["a"].as_u64().unwrap(), pr["b"].as_u64().unwrap())
            );
            let p: Vec<f64> = t[a].iter().map(|&c| c as f64).collect();
            let q: Vec<f64> = t[b].iter().map(|&c| c as f64).collect();
            for (base, key) in [(LogBase::Two, "base2"), (LogBase::E, "base_e")] {
                let want = pr[key].as_f64().unwrap();
                let got = js_divergence(&p, &q, base).unwrap();
                assert!(
                    close(got, want, 1e-12),
                    "{t:?} rows {a},{b} base {}: JS {got} vs SciPy {want}",
                    base.name()
                );
            }
            js_pairs += 1;
        }
    }
    // The comparisons above must have covered the interesting cases.
    eprintln!(
        "compared {tested_chi} chi-square tests ({tiny_p} with p < 1e-12, {dropped} with empty rows/columns), {js_pairs} JS pairs"
    );
    assert!(
        tested_chi > 250,
        "only {tested_chi} chi-square tests compared"
    );
    assert!(tiny_p > 20, "only {tiny_p} tiny p-values compared");
    assert!(
        dropped > 30,
        "only {dropped} tables with empty rows/columns compared"
    );
    assert!(js_pairs > 3000, "only {js_pairs} JS pairs compared");
}

#[test]
fn the_tolerance_catches_real_differences() {
    // Guards the helper: a comparison that would let anything pass is useless.
    assert!(close(1.0, 1.0 + 1e-12, 0.0));
    assert!(!close(1.0, 1.0 + 1e-8, 0.0));
    assert!(!close(0.018, 0.019, 1e-12));
}

fn episode(
    rng: &mut ChaCha8Rng,
    id: usize,
    task: &str,
    action_w: usize,
    state_w: usize,
) -> Episode {
    let n = rng.random_range(5..60);
    let mut arrays = BTreeMap::new();
    let mut gen_array = |w: usize, scale: f64| {
        let data: Vec<f64> = (0..n * w)
            .map(|k| scale * rng.random::<f64>() + (k % w) as f64)
            .collect();
        FrameArray::new(w, data).unwrap()
    };
    arrays.insert(Episode::ACTION.into(), gen_array(action_w, 2.0));
    arrays.insert(Episode::STATE.into(), gen_array(state_w, 0.5));
    arrays.insert(
        Episode::TIMESTAMP.into(),
        Episode::regular_timestamps(n, 30.0),
    );
    Episode {
        id: format!("ep{id}"),
        task: task.into(),
        prompt: String::new(),
        fps: 30.0,
        arrays,
        cameras: vec![],
    }
}

fn rows(episodes: &[&Episode], name: &str) -> Vec<Vec<f64>> {
    episodes
        .iter()
        .flat_map(|e| {
            e.array(name)
                .unwrap()
                .rows()
                .map(<[f64]>::to_vec)
                .collect::<Vec<_>>()
        })
        .collect()
}

fn compare(ours: &dexjoco_stats::ArrayStats, want: &Value, what: &str) {
    let fields: [(&str, &Vec<f64>); 6] = [
        ("mean", &ours.mean),
        ("std", &ours.std),
        ("min", &ours.min),
        ("max", &ours.max),
        ("q01", &ours.q01),
        ("q99", &ours.q99),
    ];
    for (key, values) in fields {
        let w: Vec<f64> = want[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(values.len(), w.len(), "{what} {key}");
        for (d, (a, b)) in values.iter().zip(&w).enumerate() {
            assert!(close(*a, *b, 1e-12), "{what} {key}[{d}]: {a} vs NumPy {b}");
        }
    }
}

#[test]
fn norm_stats_match_numpy() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut episodes = Vec::new();
    for i in 0..12 {
        episodes.push(episode(&mut rng, i, "click_mouse", 23, 31));
    }
    for i in 12..20 {
        episodes.push(episode(&mut rng, i, "bimanual_hanoi", 46, 50));
    }
    // One task with a single one-frame episode: quantiles of one value.
    let mut single = episode(&mut rng, 20, "pinch_tongs", 23, 31);
    for a in single.arrays.values_mut() {
        *a = FrameArray::new(a.width(), a.row(0).to_vec()).unwrap();
    }
    episodes.push(single);
    let stats = DatasetStats::compute(&episodes).unwrap();
    assert_eq!(stats.episodes, 21);
    assert_eq!(
        stats.frames,
        episodes.iter().map(Episode::len).sum::<usize>()
    );
    assert_eq!(stats.tasks.len(), 3);
    // Widths differ between single-arm and bimanual tasks: no dataset-wide action/state.
    assert_eq!(
        stats.mixed_width_arrays,
        vec!["action".to_string(), "state".to_string()]
    );
    assert!(stats.arrays.is_empty());

    let mut payload = serde_json::Map::new();
    for t in &stats.tasks {
        let eps: Vec<&Episode> = episodes.iter().filter(|e| e.task == t.task).collect();
        assert_eq!(t.episodes, eps.len());
        for name in [Episode::ACTION, Episode::STATE] {
            payload.insert(
                format!("{}/{name}", t.task),
                serde_json::to_value(rows(&eps, name)).unwrap(),
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("columns.json");
    fs_err::write(&input, serde_json::to_string(&payload).unwrap()).unwrap();
    let want = dexjoco_testkit::run_python_json(
        "stats_reference.py",
        &["columns", input.to_str().unwrap()],
    );
    for t in &stats.tasks {
        for name in [Episode::ACTION, Episode::STATE] {
            let key = format!("{}/{name}", t.task);
            compare(&t.arrays[name], &want[&key], &key);
        }
    }
    // Per-task norm stats use openpi's key for actions.
    let json = &stats.tasks[0].norm_stats;
    assert!(json["norm_stats"]["actions"]["q99"].is_array());
    assert!(json["norm_stats"]["state"]["std"].is_array());
}
