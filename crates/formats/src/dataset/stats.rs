//! Normalization statistics computed as lerobot 0.6.1 computes them
//! (`lerobot/datasets/compute_stats.py`), in f64:
//!
//! - per episode and feature column: min, max, mean, population std
//!   (`sqrt(max(0, E[x^2] - E[x]^2))`), count, and quantiles q01, q10, q50, q90, q99
//!   read from a 5000-bin histogram over `[min - 1e-10, max + 1e-10]` with linear
//!   interpolation inside the bin (an episode of one frame: quantiles = mean);
//! - images: per channel over frames sampled evenly (100 frames for short episodes,
//!   `len^0.75` up to 10 000), downsampled by an integer stride to about 150 px when
//!   300 px or larger, values / 255, shaped 3x1x1;
//! - over episodes: count-weighted means, variances combined with the between-episode
//!   spread, quantiles as count-weighted means of the episode quantiles.

use serde::Serialize;

/// Quantiles lerobot stores, with their keys.
pub const QUANTILES: [(f64, &str); 5] = [
    (0.01, "q01"),
    (0.10, "q10"),
    (0.50, "q50"),
    (0.90, "q90"),
    (0.99, "q99"),
];

/// Histogram bins used to estimate quantiles.
pub const HISTOGRAM_BINS: usize = 5000;

/// Statistics of one feature: one value per column (per channel for images).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeatureStats {
    /// Minimum.
    pub min: Vec<f64>,
    /// Maximum.
    pub max: Vec<f64>,
    /// Mean.
    pub mean: Vec<f64>,
    /// Population standard deviation.
    pub std: Vec<f64>,
    /// Number of samples (frames; sampled frames for images).
    pub count: u64,
    /// q01, q10, q50, q90, q99, in the order of [`QUANTILES`].
    pub quantiles: [Vec<f64>; 5],
}

impl FeatureStats {
    /// Every statistic by its lerobot key (`min`, `max`, `mean`, `std`, `q01`..), in the
    /// order lerobot writes them; `count` is left out (it is an integer).
    pub fn named(&self) -> Vec<(&'static str, &[f64])> {
        let mut v: Vec<(&'static str, &[f64])> = vec![
            ("min", &self.min),
            ("max", &self.max),
            ("mean", &self.mean),
            ("std", &self.std),
        ];
        for (i, (_, k)) in QUANTILES.iter().enumerate() {
            v.push((k, &self.quantiles[i]));
        }
        v
    }

    /// Multiplies every statistic but count by `f` (images: 1/255).
    pub fn scaled(mut self, f: f64) -> Self {
        for v in [&mut self.min, &mut self.max, &mut self.mean, &mut self.std]
            .into_iter()
            .chain(self.quantiles.iter_mut())
        {
            v.iter_mut().for_each(|x| *x *= f);
        }
        self
    }
}

/// Statistics of `n` samples of `width` columns (row-major `data`), as lerobot's
/// `get_feature_stats(array, axis=0)`. `data` must not be empty.
pub fn column_stats(data: &[f64], width: usize) -> FeatureStats {
    let n = data.len() / width;
    assert!(n > 0 && width > 0, "statistics of an empty array");
    let mut min = vec![f64::INFINITY; width];
    let mut max = vec![f64::NEG_INFINITY; width];
    let mut sum = vec![0.0; width];
    let mut sum_sq = vec![0.0; width];
    for row in data.chunks_exact(width) {
        for (j, &x) in row.iter().enumerate() {
            min[j] = min[j].min(x);
            max[j] = max[j].max(x);
            sum[j] += x;
            sum_sq[j] += x * x;
        }
    }
    let mean: Vec<f64> = sum.iter().map(|s| s / n as f64).collect();
    let std: Vec<f64> = (0..width)
        .map(|j| {
            if n < 2 {
                return 0.0;
            }
            (sum_sq[j] / n as f64 - mean[j] * mean[j]).max(0.0).sqrt()
        })
        .collect();
    let quantiles = if n < 2 {
        std::array::from_fn(|_| mean.clone())
    } else {
        let per_column: Vec<[f64; 5]> = (0..width)
            .map(|j| {
                histogram_quantiles(
                    data.iter().skip(j).step_by(width).copied(),
                    min[j],
                    max[j],
                    n,
                )
            })
            .collect();
        std::array::from_fn(|q| per_column.iter().map(|c| c[q]).collect())
    };
    FeatureStats {
        min,
        max,
        mean,
        std,
        count: n as u64,
        quantiles,
    }
}

/// The quantiles of one column from a [`HISTOGRAM_BINS`]-bin histogram, as lerobot's
/// `RunningQuantileStats` after a single update.
fn histogram_quantiles(
    values: impl Iterator<Item = f64>,
    min: f64,
    max: f64,
    n: usize,
) -> [f64; 5] {
    let bins = HISTOGRAM_BINS;
    let start = min - 1e-10;
    let stop = max + 1e-10;
    // numpy.linspace: start + i * step, the last edge exactly `stop`.
    let step = (stop - start) / bins as f64;
    let edge = |i: usize| {
        if i == bins {
            stop
        } else {
            start + i as f64 * step
        }
    };
    let mut hist = vec![0u64; bins];
    for x in values {
        // numpy.histogram: bin i holds [edge i, edge i+1), the last bin is closed.
        let mut i = (((x - start) / step).floor().max(0.0) as usize).min(bins - 1);
        if x < edge(i) && i > 0 {
            i -= 1;
        } else if i + 1 < bins && x >= edge(i + 1) {
            i += 1;
        }
        hist[i] += 1;
    }
    let mut cumsum = Vec::with_capacity(bins);
    let mut acc = 0u64;
    for h in &hist {
        acc += h;
        cumsum.push(acc as f64);
    }
    QUANTILES.map(|(q, _)| {
        let target = q * n as f64;
        let idx = cumsum.partition_point(|c| *c < target);
        if idx == 0 {
            return edge(0);
        }
        if idx >= bins {
            return edge(bins);
        }
        let before = cumsum[idx - 1];
        let in_bin = cumsum[idx] - before;
        if in_bin == 0.0 {
            return edge(idx);
        }
        let fraction = (target - before) / in_bin;
        edge(idx) + fraction * (edge(idx + 1) - edge(idx))
    })
}

/// Indices of the frames lerobot samples for image statistics out of `len` frames.
pub fn sample_indices(len: usize) -> Vec<usize> {
    if len == 0 {
        return Vec::new();
    }
    let min = 100.min(len);
    let num = ((len as f64).powf(0.75) as usize).clamp(min, 10_000.max(min));
    if num == 1 {
        return vec![0];
    }
    // numpy: round(linspace(0, len - 1, num)), rounding half to even.
    let step = (len - 1) as f64 / (num - 1) as f64;
    (0..num)
        .map(|i| {
            let x = if i == num - 1 {
                (len - 1) as f64
            } else {
                i as f64 * step
            };
            x.round_ties_even() as usize
        })
        .collect()
}

/// The integer stride lerobot downsamples an image of this size by (1 when below 300 px).
pub fn downsample_stride(width: u32, height: u32) -> usize {
    if width.max(height) < 300 {
        return 1;
    }
    let s = if width > height {
        width / 150
    } else {
        height / 150
    };
    s.max(1) as usize
}

/// Accumulates the sampled frames of one camera of one episode into per-channel samples.
#[derive(Debug, Default)]
pub struct ImageSampler {
    pixels: Vec<f64>,
    frames: u64,
}

impl ImageSampler {
    /// Adds one RGB8 frame (rows top to bottom), strided as lerobot does.
    pub fn add_frame(&mut self, rgb: &[u8], width: u32, height: u32) {
        let s = downsample_stride(width, height);
        let (w, h) = (width as usize, height as usize);
        for y in (0..h).step_by(s) {
            for x in (0..w).step_by(s) {
                let p = (y * w + x) * 3;
                self.pixels
                    .extend(rgb[p..p + 3].iter().map(|v| f64::from(*v)));
            }
        }
        self.frames += 1;
    }

    /// Per-channel statistics / 255 with count = sampled frames; None without frames.
    pub fn finish(self) -> Option<FeatureStats> {
        if self.frames == 0 {
            return None;
        }
        let mut s = column_stats(&self.pixels, 3);
        s.count = self.frames;
        Some(s.scaled(1.0 / 255.0))
    }
}

/// Combines per-episode statistics as lerobot's `aggregate_feature_stats`.
pub fn aggregate(stats: &[&FeatureStats]) -> Option<FeatureStats> {
    let first = stats.first()?;
    let width = first.mean.len();
    let total: u64 = stats.iter().map(|s| s.count).sum();
    let t = total as f64;
    let col = |f: &dyn Fn(&FeatureStats, usize) -> f64, j: usize| -> f64 {
        stats.iter().map(|s| f(s, j) * s.count as f64).sum::<f64>() / t
    };
    let mean: Vec<f64> = (0..width).map(|j| col(&|s, j| s.mean[j], j)).collect();
    let std = (0..width)
        .map(|j| {
            col(
                &|s, j| s.std[j] * s.std[j] + (s.mean[j] - mean[j]).powi(2),
                j,
            )
            .sqrt()
        })
        .collect();
    let quantiles = std::array::from_fn(|q| {
        (0..width)
            .map(|j| col(&|s, j| s.quantiles[q][j], j))
            .collect()
    });
    Some(FeatureStats {
        min: (0..width)
            .map(|j| stats.iter().map(|s| s.min[j]).fold(f64::INFINITY, f64::min))
            .collect(),
        max: (0..width)
            .map(|j| {
                stats
                    .iter()
                    .map(|s| s.max[j])
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect(),
        mean,
        std,
        count: total,
        quantiles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_matches_lerobots_heuristic() {
        assert_eq!(sample_indices(3), vec![0, 1, 2]);
        assert_eq!(sample_indices(100).len(), 100);
        assert_eq!(sample_indices(1000).len(), 177);
        assert_eq!(sample_indices(10_000).len(), 1000);
        let s = sample_indices(1000);
        assert_eq!((s[0], *s.last().unwrap()), (0, 999));
        assert_eq!(downsample_stride(640, 640), 4);
        assert_eq!(downsample_stride(64, 64), 1);
    }

    #[test]
    fn basic_statistics() {
        let s = column_stats(&[1.0, 10.0, 3.0, 10.0], 2);
        assert_eq!(s.min, vec![1.0, 10.0]);
        assert_eq!(s.mean, vec![2.0, 10.0]);
        assert_eq!(s.std, vec![1.0, 0.0]);
        assert_eq!(s.count, 2);
        let one = column_stats(&[4.0], 1);
        assert_eq!(one.quantiles[0], vec![4.0]);
        let a = column_stats(&[0.0, 2.0], 1);
        let b = column_stats(&[4.0, 6.0], 1);
        let all = aggregate(&[&a, &b]).unwrap();
        let direct = column_stats(&[0.0, 2.0, 4.0, 6.0], 1);
        assert!((all.mean[0] - direct.mean[0]).abs() < 1e-12);
        assert!((all.std[0] - direct.std[0]).abs() < 1e-12);
        assert_eq!(all.count, 4);
    }
}
