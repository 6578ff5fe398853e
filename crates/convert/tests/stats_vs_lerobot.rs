//! Our statistics against lerobot 0.6.1's own `compute_stats` on the same arrays.
//!
//! Tolerance: lerobot computes float32 data in float32 (mean, mean of squares, histogram
//! edges); we compute the same formulas in f64. min/max agree to 1e-7; mean within 1e-5
//! relative (+1e-6; images: 1e-4, a float32 sum over millions of pixels); the variance std^2 within 16 float32 epsilons of E[x^2] (lerobot's
//! `E[x^2] - E[x]^2` in float32 loses that much; ours is checked against numpy's float64
//! `np.std` to 1e-9 relative; images, summed over millions of pixels: 0.01 of E[x^2]); quantiles within one histogram bin ((max - min) / 5000)
//! plus 1e-6.

use dexjoco_formats::dataset::stats::{self, FeatureStats, ImageSampler, QUANTILES};
use rand::{Rng, SeedableRng};
use serde_json::{Value, json};

fn close(ours: &[f64], theirs: &Value, tol: impl Fn(usize) -> f64, what: &str) {
    let theirs: Vec<f64> = theirs
        .as_array()
        .unwrap_or_else(|| panic!("{what}: missing"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(ours.len(), theirs.len(), "{what}: length");
    for (j, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        assert!(
            (a - b).abs() <= tol(j),
            "{what}[{j}]: ours {a}, lerobot {b}, tolerance {}",
            tol(j)
        );
    }
}

fn compare(ours: &FeatureStats, theirs: &Value, what: &str, mean_rel: f64, var_rel: f64) {
    let bin = |j: usize| (ours.max[j] - ours.min[j]) / 5000.0 + 1e-6;
    close(&ours.min, &theirs["min"], |_| 1e-7, &format!("{what} min"));
    close(&ours.max, &theirs["max"], |_| 1e-7, &format!("{what} max"));
    close(
        &ours.mean,
        &theirs["mean"],
        |j| mean_rel * ours.mean[j].abs() + 1e-6,
        &format!("{what} mean"),
    );
    let var: Vec<f64> = ours.std.iter().map(|s| s * s).collect();
    let their_var: Vec<Value> = theirs["std"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| json!(s.as_f64().unwrap().powi(2)))
        .collect();
    let eps32 = f64::from(f32::EPSILON);
    close(
        &var,
        &Value::Array(their_var),
        |j| var_rel * eps32 * (ours.mean[j].powi(2) + var[j]) + 1e-9,
        &format!("{what} std^2"),
    );
    if let Some(exact) = theirs.get("std64") {
        close(
            &ours.std,
            exact,
            |j| 1e-9 * ours.std[j].abs() + 1e-12,
            &format!("{what} std vs float64"),
        );
    }
    for (i, (_, key)) in QUANTILES.iter().enumerate() {
        close(
            &ours.quantiles[i],
            &theirs[*key],
            bin,
            &format!("{what} {key}"),
        );
    }
    assert_eq!(
        theirs["count"][0].as_f64().unwrap() as u64,
        ours.count,
        "{what} count"
    );
}

#[test]
fn statistics_equal_lerobots_own_code() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let width = 5;
    // Episodes of different lengths (one of a single frame), a constant column, a
    // skewed column and values that are exactly float32.
    let lens = [1usize, 7, 40, 333, 1000];
    let mut episodes: Vec<Vec<Vec<f64>>> = Vec::new();
    for &n in &lens {
        let rows = (0..n)
            .map(|_| {
                let u: f64 = rng.random();
                let row = [
                    rng.random_range(-1.0..1.0),
                    0.25,
                    u.powi(4) * 3.0,
                    rng.random_range(100.0..101.0),
                    (rng.random_range(0..5) as f64) * 0.5,
                ];
                row.iter()
                    .map(|v| f64::from(*v as f32))
                    .collect::<Vec<f64>>()
            })
            .collect();
        episodes.push(rows);
    }
    // Frames of 320x320 (strided by 2 as lerobot does) with random pixels.
    let (frames, h, w) = (130usize, 320u32, 320u32);
    let pixels: Vec<u8> = (0..frames * (h * w * 3) as usize)
        .map(|_| rng.random())
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("frames.u8");
    fs_err::write(&raw, &pixels).unwrap();
    let spec = json!({
        "episodes": episodes,
        "images": {"path": raw, "frames": frames, "height": h, "width": w},
    });
    let spec_path = dir.path().join("spec.json");
    fs_err::write(&spec_path, spec.to_string()).unwrap();
    let theirs =
        dexjoco_testkit::run_python_json("lerobot_stats.py", &[spec_path.to_str().unwrap()]);

    let ours: Vec<FeatureStats> = episodes
        .iter()
        .map(|rows| stats::column_stats(&rows.concat(), width))
        .collect();
    for (i, s) in ours.iter().enumerate() {
        compare(
            s,
            &theirs["episodes"][i],
            &format!("episode {i} ({} frames)", lens[i]),
            1e-5,
            16.0,
        );
    }
    let agg = stats::aggregate(&ours.iter().collect::<Vec<_>>()).unwrap();
    compare(&agg, &theirs["aggregate"], "aggregate", 1e-5, 16.0);

    let idx = stats::sample_indices(frames);
    let their_idx: Vec<usize> = theirs["image_samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    assert_eq!(idx, their_idx, "sampled frame indices");
    let mut sampler = ImageSampler::default();
    let size = (h * w * 3) as usize;
    for &i in &idx {
        sampler.add_frame(&pixels[i * size..(i + 1) * size], w, h);
    }
    let img = sampler.finish().unwrap();
    // lerobot sums 2.5 million pixel values in float32 one after another (numpy reduces
    // axis 0 without pairwise summation): mean within 1e-4 relative, variance within
    // 0.01 of E[x^2] (5e4 float32 epsilons). Ours equals numpy's float64 statistics.
    compare(&img, &theirs["image"], "image", 1e-4, 5e4);
}
