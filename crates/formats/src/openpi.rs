//! openpi normalization statistics (`norm_stats.json`): the one implementation of
//! normalization statistics in dexjoco-data (`convert --norm-stats` over the converted
//! training columns, `stats --dataset` over the source arrays), computed as openpi's
//! `RunningStats` (`openpi/shared/normalize.py`) computes them, in f64 on the values
//! as stored (float32):
//!
//! - one update per episode (openpi updates per batch; the result depends on the
//!   batching only through the histogram re-binning when min or max grows);
//! - running mean and mean of squares, population std `sqrt(max(0, E[x²] - E[x]²))`;
//! - per column a 5000-bin histogram over `[min - 1e-10, max + 1e-10]`, re-binned
//!   (counts moved by their old left edge) whenever min or max grows;
//! - q01 / q99 = the left bin edge where the cumulative count first reaches
//!   `q * count` (no interpolation, unlike lerobot);
//! - `actions` over action chunks as openpi's data loader makes them: for every frame
//!   `t` the rows `t..t+horizon`, the last frame repeated past the episode's end.

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
                    let new_edges = linspace(self.min[j] - 1e-10, self.max[j] + 1e-10);
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

/// openpi's `norm_stats.json` of a dataset: `state` and `actions`, fed episode by episode.
#[derive(Debug, Clone)]
pub struct NormStats {
    horizon: usize,
    state: RunningStats,
    actions: RunningStats,
}

impl NormStats {
    /// Statistics with actions over chunks of `horizon` frames (openpi's
    /// `action_horizon`; 1 = each frame once).
    pub fn new(horizon: usize) -> Self {
        Self {
            horizon: horizon.max(1),
            state: RunningStats::default(),
            actions: RunningStats::default(),
        }
    }

    /// Adds one episode's state and action rows (values as stored: float32).
    pub fn add_episode(&mut self, state: &[f64], state_width: usize, action: &[f64], width: usize) {
        self.state.update(state, state_width);
        let n = action.len() / width;
        let mut rows = Vec::with_capacity(n * self.horizon * width);
        for t in 0..n {
            for k in 0..self.horizon {
                let r = (t + k).min(n - 1);
                rows.extend_from_slice(&action[r * width..(r + 1) * width]);
            }
        }
        self.actions.update(&rows, width);
    }

    /// The `norm_stats.json` document: `{"norm_stats": {"state", "actions"}}`; `None`
    /// under two frames (openpi refuses those).
    pub fn document(&self) -> Option<Value> {
        let (state, actions) = (self.state.statistics()?, self.actions.statistics()?);
        Some(json!({"norm_stats": {"state": state, "actions": actions}}))
    }

    /// Writes `norm_stats.json` (indent 2, as openpi's pydantic writer) into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(NORM_STATS);
        let doc = self.document().ok_or_else(|| {
            FormatError::input(
                ProblemCode::WrongLength,
                &dexjoco_core::Location::default().path(&path),
                "openpi's normalization statistics need at least two frames",
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

/// Writes a `norm_stats.json` document (indent 2 and a final newline, as openpi's pydantic
/// writer), atomically.
pub fn write_document(path: &Path, doc: &Value) -> Result<()> {
    let mut text = serde_json::to_string_pretty(doc).expect("JSON values serialize");
    text.push('\n');
    crate::fs::write_atomic(path, text.as_bytes())
}
