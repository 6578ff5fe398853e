//! openpi normalization statistics (`norm_stats.json`): the one implementation of
//! normalization statistics in dexjoco-data (`convert --norm-stats` over the converted
//! training columns, `stats --dataset` over the source arrays), computed as openpi's
//! `RunningStats` (`openpi/shared/normalize.py`) computes them, in f64 on the values
//! as stored (float32):
//!
//! - running mean and mean of squares, population std `sqrt(max(0, E[x²] - E[x]²))`
//!   (no guard for a zero std: openpi's file has none either);
//! - per column a 5000-bin histogram over `[min - 1e-10, max + 1e-10]` from the first
//!   update; whenever min or max grows, re-binned onto `[min, max]` (no margin, as
//!   openpi's `_adjust_histograms`), counts moved by their old left edge;
//! - q01 / q99 = the left bin edge where the cumulative count first reaches
//!   `q * count` (no interpolation, unlike lerobot).
//!
//! [`NormStats`] feeds it as openpi's `scripts/compute_norm_stats.py` does
//! ([`NormStatsOptions`]): frames in dataset order in batches of `batch_size` (across
//! episode boundaries; the frames after the last whole batch are left out, as openpi's
//! loader drops them), `actions` over action chunks as openpi's data loader makes them
//! (for every frame `t` the rows `t..t+horizon`, the last frame repeated past the
//! episode's end). The file is what openpi's `normalize.save` writes for the same values.
//!
//! Zero variance: openpi's file has no guard, its `transforms.Normalize` has one: it
//! divides by `std + 1e-6` (z-score) or `q99 - q01 + 1e-6` (quantiles), so a constant
//! column trains as 0 (-1 with quantiles) and any deviation at inference is multiplied
//! by about 1e6. The file is kept as openpi writes it; [`flat_columns`] names those
//! columns so `convert --norm-stats` can warn.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::{Value, json};

use crate::error::{FormatError, ProblemCode, Result};

/// openpi's histogram bins.
const BINS: usize = 5000;

/// openpi's `RunningStats` for vectors of one width.
#[derive(Debug, Clone, Default)]
pub struct RunningStats {
    count: u64,
    mean: Vec<f64>,
    mean_sq: Vec<f64>,
    min: Vec<f64>,
    max: Vec<f64>,
    hist: Vec<Vec<f64>>,
    edges: Vec<Vec<f64>>,
}

/// `np.linspace(a, b, BINS + 1)`.
fn linspace(a: f64, b: f64) -> Vec<f64> {
    let step = (b - a) / BINS as f64;
    let mut v: Vec<f64> = (0..=BINS).map(|i| i as f64 * step + a).collect();
    v[BINS] = b;
    v
}

/// Adds `w` to the bin of `x` as `np.histogram(x, bins=edges, weights=w)` does: bins
/// half-open but the last closed, values outside ignored.
fn add_to_bin(hist: &mut [f64], edges: &[f64], x: f64, w: f64) {
    let last = edges.len() - 1;
    if !(x >= edges[0] && x <= edges[last]) {
        return;
    }
    let i = if x == edges[last] {
        last - 1
    } else {
        edges.partition_point(|e| *e <= x) - 1
    };
    hist[i] += w;
}

impl RunningStats {
    /// Values seen so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Adds a batch of `rows` (row-major, `width` columns).
    pub fn update(&mut self, rows: &[f64], width: usize) {
        let n = rows.len() / width;
        if n == 0 {
            return;
        }
        let col = |j: usize| rows.iter().skip(j).step_by(width).copied();
        let bmin: Vec<f64> = (0..width)
            .map(|j| col(j).fold(f64::INFINITY, f64::min))
            .collect();
        let bmax: Vec<f64> = (0..width)
            .map(|j| col(j).fold(f64::NEG_INFINITY, f64::max))
            .collect();
        let bmean: Vec<f64> = (0..width).map(|j| col(j).sum::<f64>() / n as f64).collect();
        let bmean_sq: Vec<f64> = (0..width)
            .map(|j| col(j).map(|x| x * x).sum::<f64>() / n as f64)
            .collect();
        if self.count == 0 {
            self.mean = bmean.clone();
            self.mean_sq = bmean_sq.clone();
            self.min = bmin;
            self.max = bmax;
            self.hist = vec![vec![0.0; BINS]; width];
            self.edges = (0..width)
                .map(|j| linspace(self.min[j] - 1e-10, self.max[j] + 1e-10))
                .collect();
        } else {
            assert_eq!(width, self.mean.len(), "vector width changed");
            let changed = (0..width).any(|j| bmax[j] > self.max[j] || bmin[j] < self.min[j]);
            for j in 0..width {
                self.max[j] = self.max[j].max(bmax[j]);
                self.min[j] = self.min[j].min(bmin[j]);
            }
            if changed {
                for j in 0..width {
                    let new_edges = linspace(self.min[j], self.max[j]);
                    let mut new_hist = vec![0.0; BINS];
                    for (b, &w) in self.hist[j].iter().enumerate() {
                        add_to_bin(&mut new_hist, &new_edges, self.edges[j][b], w);
                    }
                    self.hist[j] = new_hist;
                    self.edges[j] = new_edges;
                }
            }
        }
        self.count += n as u64;
        let f = n as f64 / self.count as f64;
        for j in 0..width {
            self.mean[j] += (bmean[j] - self.mean[j]) * f;
            self.mean_sq[j] += (bmean_sq[j] - self.mean_sq[j]) * f;
        }
        for r in rows.chunks_exact(width) {
            for (j, &x) in r.iter().enumerate() {
                add_to_bin(&mut self.hist[j], &self.edges[j], x, 1.0);
            }
        }
    }

    /// `{mean, std, q01, q99}`, or `None` under two values (openpi refuses those).
    pub fn statistics(&self) -> Option<Value> {
        if self.count < 2 {
            return None;
        }
        let std: Vec<f64> = (0..self.mean.len())
            .map(|j| {
                (self.mean_sq[j] - self.mean[j] * self.mean[j])
                    .max(0.0)
                    .sqrt()
            })
            .collect();
        let quantile = |q: f64| -> Vec<f64> {
            let target = q * self.count as f64;
            self.hist
                .iter()
                .zip(&self.edges)
                .map(|(h, e)| {
                    let mut cum = 0.0;
                    let mut idx = h.len();
                    for (i, c) in h.iter().enumerate() {
                        cum += c;
                        if cum >= target {
                            idx = i;
                            break;
                        }
                    }
                    e[idx]
                })
                .collect()
        };
        Some(json!({
            "mean": self.mean,
            "std": std,
            "q01": quantile(0.01),
            "q99": quantile(0.99),
        }))
    }
}

/// How openpi's `compute_norm_stats.py` feeds `RunningStats`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NormStatsOptions {
    /// Frames per action chunk (openpi's `model.action_horizon`; 1 = each frame once).
    pub action_horizon: usize,
    /// Frames per update (openpi's `batch_size`); the frames after the last whole batch
    /// are left out.
    pub batch_size: usize,
}

impl Default for NormStatsOptions {
    /// openpi's defaults: `action_horizon` 50 (pi0), `batch_size` 32.
    fn default() -> Self {
        Self {
            action_horizon: 50,
            batch_size: 32,
        }
    }
}

/// openpi's `norm_stats.json` of a dataset: `state` and `actions`, fed in batches of
/// frames as openpi's `compute_norm_stats.py` feeds them.
#[derive(Debug, Clone)]
pub struct NormStats {
    options: NormStatsOptions,
    state: RunningStats,
    actions: RunningStats,
    /// The batch being filled: its frames' state rows and action chunks, and the widths.
    batch_state: Vec<f64>,
    batch_actions: Vec<f64>,
    batch_frames: usize,
    widths: (usize, usize),
}

impl NormStats {
    /// Statistics fed as `options` say (a horizon or batch size of 0 counts as 1).
    pub fn new(options: NormStatsOptions) -> Self {
        Self {
            options: NormStatsOptions {
                action_horizon: options.action_horizon.max(1),
                batch_size: options.batch_size.max(1),
            },
            state: RunningStats::default(),
            actions: RunningStats::default(),
            batch_state: Vec::new(),
            batch_actions: Vec::new(),
            batch_frames: 0,
            widths: (0, 0),
        }
    }

    /// Adds one episode's state and action rows (values as stored: float32), frame by
    /// frame into the batch being filled; every full batch updates the statistics.
    pub fn add_episode(&mut self, state: &[f64], state_width: usize, action: &[f64], width: usize) {
        let n = action.len() / width;
        assert_eq!(
            state.len(),
            n * state_width,
            "state and action frames differ"
        );
        if self.batch_frames > 0 {
            assert_eq!(self.widths, (state_width, width), "vector width changed");
        }
        self.widths = (state_width, width);
        for t in 0..n {
            self.batch_state
                .extend_from_slice(&state[t * state_width..(t + 1) * state_width]);
            for k in 0..self.options.action_horizon {
                let r = (t + k).min(n - 1);
                self.batch_actions
                    .extend_from_slice(&action[r * width..(r + 1) * width]);
            }
            self.batch_frames += 1;
            if self.batch_frames == self.options.batch_size {
                self.state.update(&self.batch_state, state_width);
                self.actions.update(&self.batch_actions, width);
                self.batch_state.clear();
                self.batch_actions.clear();
                self.batch_frames = 0;
            }
        }
    }

    /// The `norm_stats.json` document: `{"norm_stats": {"state", "actions"}}`; `None`
    /// under two frames in whole batches (openpi refuses those).
    pub fn document(&self) -> Option<Value> {
        let (state, actions) = (self.state.statistics()?, self.actions.statistics()?);
        Some(json!({"norm_stats": {"state": state, "actions": actions}}))
    }

    /// Writes `norm_stats.json` (as openpi's `normalize.save`) into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(NORM_STATS);
        let doc = self.document().ok_or_else(|| {
            FormatError::input(
                ProblemCode::WrongLength,
                &dexjoco_core::Location::default().path(&path),
                format!(
                    "openpi's normalization statistics need at least {} frames in whole \
                     batches of {} (openpi leaves out the frames after the last whole batch); \
                     the dataset has {}: lower the batch size (convert --norm-stats-batch)",
                    self.options.batch_size.max(2),
                    self.options.batch_size,
                    self.state.count() as usize + self.batch_frames
                ),
            )
        })?;
        write_document(&path, &doc)
    }
}

/// File name of openpi's normalization statistics.
pub const NORM_STATS: &str = "norm_stats.json";

/// The openpi key of an array: `actions` for `action`, else the array name.
pub fn openpi_key(array: &str) -> &str {
    if array == "action" { "actions" } else { array }
}

/// The `norm_stats.json` document of named arrays' running statistics (keys as
/// [`openpi_key`]); arrays with under two values are left out.
pub fn norm_stats_document(arrays: &BTreeMap<String, RunningStats>) -> Value {
    let stats: serde_json::Map<String, Value> = arrays
        .iter()
        .filter_map(|(name, s)| Some((openpi_key(name).to_owned(), s.statistics()?)))
        .collect();
    json!({ "norm_stats": stats })
}

/// Writes a `norm_stats.json` document as openpi's `normalize.save` does (pydantic's
/// `model_dump_json(indent=2)`: indent 2, shortest round-trip floats, no final newline),
/// atomically.
pub fn write_document(path: &Path, doc: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(doc).expect("JSON values serialize");
    crate::fs::write_atomic(path, text.as_bytes())
}

/// openpi's epsilon in `transforms.Normalize` / `Unnormalize`: `(x - mean) / (std + 1e-6)`,
/// `(x - q01) / (q99 - q01 + 1e-6) * 2 - 1`.
pub const OPENPI_NORMALIZE_EPS: f64 = 1e-6;

/// A column of a `norm_stats.json` document whose std is at or under
/// [`OPENPI_NORMALIZE_EPS`] x max(1, |mean|): zero variance up to the rounding of
/// `E[x²] - E[x]²` (a constant column's std comes out 0 or at floating-point noise).
#[derive(Debug, Clone, PartialEq)]
pub struct FlatColumn {
    /// The document's key (`state`, `actions`).
    pub key: String,
    /// Column index.
    pub index: usize,
    /// Column name (`state[3]` when none is given).
    pub name: String,
    /// Its mean.
    pub mean: f64,
    /// Its std.
    pub std: f64,
    /// `q99 - q01`.
    pub quantile_range: f64,
}

impl FlatColumn {
    /// One line: the column, its statistics, what openpi does with it and what to do.
    pub fn warning(&self) -> String {
        format!(
            "norm_stats.json: {} column {} '{}' has zero variance (mean {}, std {:e}, q99 - q01 \
             {:e}); the file is kept as openpi writes it, and openpi's Normalize divides by std \
             + 1e-6 (quantiles: q99 - q01 + 1e-6), so the column trains as a constant and a \
             deviation d at inference becomes d x {:.1e}; drop the column from the training \
             columns or fix its statistics",
            self.key,
            self.index,
            self.name,
            self.mean,
            self.std,
            self.quantile_range,
            1.0 / (self.std + OPENPI_NORMALIZE_EPS)
        )
    }
}

/// The zero-variance columns of a `norm_stats.json` document, key by key in document
/// order; `names` gives column names per key (missing ones are `key[i]`).
pub fn flat_columns(doc: &Value, names: &BTreeMap<String, Vec<String>>) -> Vec<FlatColumn> {
    let floats = |v: &Value, field: &str| -> Vec<f64> {
        v.get(field)
            .and_then(Value::as_array)
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default()
    };
    let mut out = Vec::new();
    let Some(stats) = doc.get("norm_stats").and_then(Value::as_object) else {
        return out;
    };
    for (key, v) in stats {
        let (mean, std) = (floats(v, "mean"), floats(v, "std"));
        let (q01, q99) = (floats(v, "q01"), floats(v, "q99"));
        for (i, (&m, &s)) in mean.iter().zip(&std).enumerate() {
            if s > OPENPI_NORMALIZE_EPS * m.abs().max(1.0) {
                continue;
            }
            out.push(FlatColumn {
                key: key.clone(),
                index: i,
                name: names
                    .get(key)
                    .and_then(|n| n.get(i))
                    .cloned()
                    .unwrap_or_else(|| format!("{key}[{i}]")),
                mean: m,
                std: s,
                quantile_range: q99.get(i).zip(q01.get(i)).map_or(0.0, |(a, b)| a - b),
            });
        }
    }
    out
}
