//! Measures of dependence on a table of counts (rows x columns): Pearson's chi-square
//! test of independence, normalized mutual information and the Jensen-Shannon
//! divergence between rows. They follow SciPy and scikit-learn term for term, and the
//! tests compare them with both. Also the mean/std and quantile summaries of samples that
//! the dataset statistics and their health section share.

use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Base of the logarithm of the Jensen-Shannon divergence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LogBase {
    /// Bits: the divergence lies in [0, 1].
    #[default]
    Two,
    /// Nats (SciPy's default): the divergence lies in [0, ln 2].
    E,
}

impl LogBase {
    /// The base as a number (2 or e).
    pub fn value(self) -> f64 {
        match self {
            Self::Two => 2.0,
            Self::E => std::f64::consts::E,
        }
    }

    /// `2` or `e`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Two => "2",
            Self::E => "e",
        }
    }
}

/// Result of Pearson's chi-square test of independence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChiSquare {
    /// Pearson's statistic, sum of (observed - expected)^2 / expected, without any
    /// continuity correction (also for one degree of freedom).
    pub statistic: f64,
    /// Degrees of freedom, (rows - 1) x (columns - 1) of the table without empty rows and
    /// columns.
    pub dof: u64,
    /// Probability of a statistic at least this large under independence (the
    /// chi-square survival function). 1 when the test cannot be made (`dof` 0).
    pub p_value: f64,
    /// Indices of all-zero rows left out of the test (their expected counts are 0).
    pub dropped_rows: Vec<usize>,
    /// Indices of all-zero columns left out of the test.
    pub dropped_columns: Vec<usize>,
}

impl ChiSquare {
    /// False when fewer than two non-empty rows or columns remain: there is nothing to
    /// test, and the statistic is 0 with p = 1.
    pub fn testable(&self) -> bool {
        self.dof > 0
    }
}

/// Row and column sums of a table, checking that it is rectangular.
fn margins(counts: &[Vec<u64>]) -> (Vec<u64>, Vec<u64>) {
    let width = counts.first().map_or(0, Vec::len);
    assert!(
        counts.iter().all(|r| r.len() == width),
        "a contingency table must be rectangular"
    );
    let rows = counts.iter().map(|r| r.iter().sum()).collect();
    let cols = (0..width)
        .map(|j| counts.iter().map(|r| r[j]).sum())
        .collect();
    (rows, cols)
}

/// Pearson's chi-square test of independence of rows and columns, as
/// `scipy.stats.chi2_contingency(table, correction=False)` on the table with its
/// all-zero rows and columns removed (SciPy refuses tables with zero expected counts);
/// the removed indices are reported.
///
/// # Panics
/// When the rows do not all have the same length.
pub fn chi_square(counts: &[Vec<u64>]) -> ChiSquare {
    let (row_sums, col_sums) = margins(counts);
    let rows: Vec<usize> = (0..row_sums.len()).filter(|&i| row_sums[i] > 0).collect();
    let cols: Vec<usize> = (0..col_sums.len()).filter(|&j| col_sums[j] > 0).collect();
    let dropped_rows = (0..row_sums.len()).filter(|&i| row_sums[i] == 0).collect();
    let dropped_columns = (0..col_sums.len()).filter(|&j| col_sums[j] == 0).collect();
    if rows.len() < 2 || cols.len() < 2 {
        return ChiSquare {
            statistic: 0.0,
            dof: 0,
            p_value: 1.0,
            dropped_rows,
            dropped_columns,
        };
    }
    let total = row_sums.iter().sum::<u64>() as f64;
    let mut statistic = 0.0;
    for &i in &rows {
        for &j in &cols {
            let expected = row_sums[i] as f64 * col_sums[j] as f64 / total;
            let diff = counts[i][j] as f64 - expected;
            statistic += diff * diff / expected;
        }
    }
    let dof = ((rows.len() - 1) * (cols.len() - 1)) as u64;
    let p_value = ChiSquared::new(dof as f64)
        .expect("dof is positive")
        .sf(statistic);
    ChiSquare {
        statistic,
        dof,
        p_value,
        dropped_rows,
        dropped_columns,
    }
}

/// Normalized mutual information between the row label and the column label of the
/// table's observations, with the arithmetic mean of the two entropies as normalizer:
/// `sklearn.metrics.normalized_mutual_info_score(rows, columns)` on the expanded labels
/// (one pair per counted observation), including its conventions: 1 when both labels
/// take a single value, 0 when only one does or the mutual information is 0.
///
/// # Panics
/// When the rows do not all have the same length.
pub fn normalized_mutual_information(counts: &[Vec<u64>]) -> f64 {
    let (row_sums, col_sums) = margins(counts);
    let row_sums: Vec<f64> = row_sums
        .into_iter()
        .filter(|&n| n > 0)
        .map(|n| n as f64)
        .collect();
    let col_sums: Vec<f64> = col_sums
        .into_iter()
        .filter(|&n| n > 0)
        .map(|n| n as f64)
        .collect();
    if row_sums.len() == col_sums.len() && row_sums.len() <= 1 {
        return 1.0;
    }
    if row_sums.len() == 1 || col_sums.len() == 1 {
        return 0.0;
    }
    let total: f64 = row_sums.iter().sum();
    let ln_total = total.ln();
    // Margins of the original indices (zero rows/columns contribute no cells).
    let (rs, cs) = margins(counts);
    let mut terms = Vec::new();
    for (i, row) in counts.iter().enumerate() {
        for (j, &n) in row.iter().enumerate() {
            if n == 0 {
                continue;
            }
            let n = n as f64;
            let p = n / total;
            let log_outer = -(rs[i] as f64 * cs[j] as f64).ln() + ln_total + ln_total;
            let term = p * (n.ln() - ln_total) + p * log_outer;
            // scikit-learn zeroes terms below machine epsilon before summing.
            terms.push(if term.abs() < f64::EPSILON { 0.0 } else { term });
        }
    }
    let mi = terms.iter().sum::<f64>().max(0.0);
    if mi == 0.0 {
        return 0.0;
    }
    let entropy = |sums: &[f64]| -> f64 {
        -sums
            .iter()
            .map(|&n| (n / total) * (n.ln() - ln_total))
            .sum::<f64>()
    };
    let normalizer = (entropy(&row_sums) + entropy(&col_sums)) / 2.0;
    mi / normalizer
}

/// Jensen-Shannon divergence between two distributions given as non-negative weights
/// (each normalized to sum 1 first), in the given log base: the square of
/// `scipy.spatial.distance.jensenshannon(p, q, base)`. `None` when either has no mass
/// or the lengths differ.
pub fn js_divergence(p: &[f64], q: &[f64], base: LogBase) -> Option<f64> {
    if p.len() != q.len() || p.iter().chain(q).any(|&x| x < 0.0 || !x.is_finite()) {
        return None;
    }
    let (sp, sq) = (p.iter().sum::<f64>(), q.iter().sum::<f64>());
    if sp <= 0.0 || sq <= 0.0 {
        return None;
    }
    // Relative entropy terms x ln(x / y), 0 for x = 0 (scipy.special.rel_entr).
    let rel_entr = |x: f64, y: f64| if x > 0.0 { x * (x / y).ln() } else { 0.0 };
    let mut left = 0.0;
    let mut right = 0.0;
    for (&a, &b) in p.iter().zip(q) {
        let (a, b) = (a / sp, b / sq);
        let m = (a + b) / 2.0;
        left += rel_entr(a, m);
        right += rel_entr(b, m);
    }
    Some(((left + right) / base.value().ln() / 2.0).max(0.0))
}

/// Mean and standard deviation of values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    /// Arithmetic mean.
    pub mean: f64,
    /// Sample standard deviation (divisor n - 1, as the DexJoCo paper reports over
    /// seeds); `None` for fewer than two values.
    pub std: Option<f64>,
    /// Number of values.
    pub n: usize,
}

/// Mean and sample standard deviation (n - 1 divisor, `numpy.std(x, ddof=1)`). `None`
/// for no values.
pub fn mean_std(values: &[f64]) -> Option<MeanStd> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let std = (n > 1).then(|| {
        let ss: f64 = values.iter().map(|v| (v - mean) * (v - mean)).sum();
        (ss / (n - 1) as f64).sqrt()
    });
    Some(MeanStd { mean, std, n })
}

/// The `q`-quantile of sorted values with linear interpolation between order statistics
/// (`numpy.quantile`'s default method). `None` when empty.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let pos = q.clamp(0.0, 1.0) * (n - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    let t = pos - lo as f64;
    let (a, b) = (sorted[lo], sorted[hi]);
    // numpy interpolates from the nearer end for accuracy.
    Some(if t >= 0.5 {
        b - (b - a) * (1.0 - t)
    } else {
        a + (b - a) * t
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_of_a_known_table() {
        // 2x2 table; statistic by hand: expected 15 everywhere.
        let t = vec![vec![20, 10], vec![10, 20]];
        let c = chi_square(&t);
        assert!((c.statistic - 4.0 * 25.0 / 15.0).abs() < 1e-12);
        assert_eq!(c.dof, 1);
        assert!(c.p_value > 0.008 && c.p_value < 0.01, "{}", c.p_value);
    }

    #[test]
    fn empty_rows_and_columns_are_dropped_and_reported() {
        let t = vec![vec![3, 0, 1], vec![0, 0, 0], vec![1, 0, 3]];
        let c = chi_square(&t);
        assert_eq!(c.dropped_rows, vec![1]);
        assert_eq!(c.dropped_columns, vec![1]);
        assert_eq!(c.dof, 1);
        let single = chi_square(&[vec![5, 0, 2]]);
        assert!(!single.testable());
        assert_eq!(single.p_value, 1.0);
    }

    #[test]
    fn nmi_limits() {
        assert_eq!(normalized_mutual_information(&[vec![7]]), 1.0);
        assert_eq!(normalized_mutual_information(&[vec![3, 4]]), 0.0);
        assert!((normalized_mutual_information(&[vec![5, 0], vec![0, 5]]) - 1.0).abs() < 1e-15);
        assert_eq!(
            normalized_mutual_information(&[vec![5, 5], vec![5, 5]]),
            0.0
        );
    }

    #[test]
    fn js_limits() {
        let bits = js_divergence(&[1.0, 0.0], &[0.0, 1.0], LogBase::Two).unwrap();
        assert!((bits - 1.0).abs() < 1e-15);
        let nats = js_divergence(&[1.0, 0.0], &[0.0, 3.0], LogBase::E).unwrap();
        assert!((nats - std::f64::consts::LN_2).abs() < 1e-15);
        assert_eq!(
            js_divergence(&[2.0, 2.0], &[1.0, 1.0], LogBase::Two),
            Some(0.0)
        );
        assert_eq!(js_divergence(&[0.0, 0.0], &[1.0, 1.0], LogBase::Two), None);
    }

    #[test]
    fn sample_std() {
        // The paper's "2+2": 0, 2 and 2 % over three seeds is 1.3 +- 1.2.
        let m = mean_std(&[0.0, 2.0, 2.0]).unwrap();
        assert!((m.mean - 4.0 / 3.0).abs() < 1e-12);
        assert!((m.std.unwrap() - (4.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_std(&[5.0]).unwrap().std, None);
    }
}
