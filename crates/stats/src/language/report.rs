//! Analysing a language study as the DexJoCo paper's appendix A: instruction x output
//! distribution, precision over seeds, chi-square independence, normalized mutual
//! information, Jensen-Shannon divergences, and a verdict.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::input::{Instruction, LanguageInput, NONE_OUTPUT};
use crate::measures::{
    ChiSquare, LogBase, MeanStd, chi_square, js_divergence, mean_std, normalized_mutual_information,
};

/// Settings of the analysis. Defaults: [`Self::DEFAULT_ALPHA`], [`Self::DEFAULT_NMI_WEAK`],
/// Jensen-Shannon in bits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]

pub struct LanguageOptions {
    /// Significance level of the chi-square test.
    pub alpha: f64,
    /// NMI below which a dependence is called negligible in the verdict.
    pub nmi_weak: f64,
    /// Log base of the Jensen-Shannon divergence.
    pub js_base: LogBase,
}

impl LanguageOptions {
    /// Default significance level.
    pub const DEFAULT_ALPHA: f64 = 0.05;
    /// Default NMI threshold of a negligible dependence.
    pub const DEFAULT_NMI_WEAK: f64 = 0.1;
}

impl Default for LanguageOptions {
    fn default() -> Self {
        Self {
            alpha: Self::DEFAULT_ALPHA,
            nmi_weak: Self::DEFAULT_NMI_WEAK,
            js_base: LogBase::Two,
        }
    }
}

/// Precision of one instruction: the share of episodes that entered the expected answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Precision {
    /// Instruction label.
    pub instruction: String,
    /// Expected answer.
    pub expected: String,
    /// Episodes over all seeds.
    pub episodes: u64,
    /// Episodes that entered the expected answer.
    pub correct: u64,
    /// Precision in percent per seed.
    pub per_seed: BTreeMap<u32, f64>,
    /// Mean and sample standard deviation (n - 1) over seeds, in percent.
    pub over_seeds: MeanStd,
}

/// Jensen-Shannon divergence of the output distributions of two instructions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JsPair {
    /// First instruction.
    pub a: String,
    /// Second instruction.
    pub b: String,
    /// Divergence in the report's log base.
    pub divergence: f64,
}

/// The result of the language-generalization analysis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LanguageReport {
    /// Where the trials came from.
    pub source: PathBuf,
    /// True for a made-up example input.
    pub example: bool,
    /// The settings used.
    pub options: LanguageOptions,
    /// Instructions (rows), in input order.
    pub instructions: Vec<Instruction>,
    /// Outputs (columns): numbers in numeric order, other answers, then `none`. Every
    /// expected answer and `none` is a column, even when never entered.
    pub outputs: Vec<String>,
    /// Episodes per instruction (row) and output (column), all seeds pooled.
    pub counts: Vec<Vec<u64>>,
    /// `counts` divided by each row's total.
    pub proportions: Vec<Vec<f64>>,
    /// Seeds seen.
    pub seeds: Vec<u32>,
    /// Precision per instruction.
    pub precision: Vec<Precision>,
    /// Chi-square test of independence of instruction and output.
    pub chi_square: ChiSquare,
    /// Outputs never entered, left out of the chi-square test.
    pub chi_square_dropped_outputs: Vec<String>,
    /// Normalized mutual information (arithmetic-mean normalization, natural log).
    pub nmi: f64,
    /// Jensen-Shannon divergence of every pair of instructions.
    pub js_pairs: Vec<JsPair>,
    /// Mean over pairs.
    pub js_mean: Option<f64>,
    /// The largest pair.
    pub js_max: Option<JsPair>,
    /// One-line conclusion.
    pub verdict: String,
    /// Warnings from reading the input.
    pub warnings: Vec<String>,
}

pub(super) fn output_order(a: &String, b: &String) -> std::cmp::Ordering {
    let key = |s: &String| {
        let numeric = !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        let rank = if numeric {
            0
        } else if s == NONE_OUTPUT {
            2
        } else {
            1
        };
        (
            rank,
            if numeric {
                s.trim_start_matches('0').len()
            } else {
                0
            },
            s.clone(),
        )
    };
    key(a).cmp(&key(b))
}

/// The precision of each instruction: the share of its trials that entered the
/// expected answer, per seed and over seeds.
fn precision(input: &LanguageInput, instructions: &[Instruction]) -> Vec<Precision> {
    instructions
        .iter()
        .map(|ins| {
            let mut per_seed_counts: BTreeMap<u32, (u64, u64)> = BTreeMap::new();
            for t in input.trials.iter().filter(|t| t.instruction == ins.label) {
                let e = per_seed_counts.entry(t.seed).or_default();
                e.0 += 1;
                e.1 += u64::from(t.output == ins.expected);
            }
            let per_seed: BTreeMap<u32, f64> = per_seed_counts
                .iter()
                .map(|(&s, &(n, k))| (s, 100.0 * k as f64 / n as f64))
                .collect();
            let values: Vec<f64> = per_seed.values().copied().collect();
            Precision {
                instruction: ins.label.clone(),
                expected: ins.expected.clone(),
                episodes: per_seed_counts.values().map(|c| c.0).sum(),
                correct: per_seed_counts.values().map(|c| c.1).sum(),
                per_seed,
                over_seeds: mean_std(&values).unwrap_or(MeanStd {
                    mean: f64::NAN,
                    std: None,
                    n: 0,
                }),
            }
        })
        .collect()
}

/// The Jensen-Shannon divergence of every pair of instructions' output counts.
fn js_pairs(instructions: &[Instruction], counts: &[Vec<u64>], base: LogBase) -> Vec<JsPair> {
    let mut js_pairs = Vec::new();
    for a in 0..instructions.len() {
        for b in a + 1..instructions.len() {
            let p: Vec<f64> = counts[a].iter().map(|&c| c as f64).collect();
            let q: Vec<f64> = counts[b].iter().map(|&c| c as f64).collect();
            if let Some(d) = js_divergence(&p, &q, base) {
                js_pairs.push(JsPair {
                    a: instructions[a].label.clone(),
                    b: instructions[b].label.clone(),
                    divergence: d,
                });
            }
        }
    }
    js_pairs
}

impl LanguageReport {
    /// Runs the analysis.
    pub fn analyze(input: &LanguageInput, options: LanguageOptions) -> Self {
        let instructions = input.instructions.clone();
        let mut outputs: Vec<String> = input
            .trials
            .iter()
            .map(|t| t.output.clone())
            .chain(instructions.iter().map(|i| i.expected.clone()))
            .chain([NONE_OUTPUT.to_string()])
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        outputs.sort_by(output_order);
        let row_of = |label: &str| instructions.iter().position(|i| i.label == label);
        let col_of = |out: &str| outputs.iter().position(|o| o == out);
        let mut counts = vec![vec![0u64; outputs.len()]; instructions.len()];
        for t in &input.trials {
            if let (Some(i), Some(j)) = (row_of(&t.instruction), col_of(&t.output)) {
                counts[i][j] += 1;
            }
        }
        let proportions = counts
            .iter()
            .map(|r| {
                let n = r.iter().sum::<u64>();
                r.iter()
                    .map(|&c| if n > 0 { c as f64 / n as f64 } else { 0.0 })
                    .collect()
            })
            .collect();
        let seeds: Vec<u32> = input
            .trials
            .iter()
            .map(|t| t.seed)
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();

        let precision = precision(input, &instructions);

        let chi = chi_square(&counts);
        let chi_square_dropped_outputs = chi
            .dropped_columns
            .iter()
            .map(|&j| outputs[j].clone())
            .collect();
        let nmi = normalized_mutual_information(&counts);

        let js_pairs = js_pairs(&instructions, &counts, options.js_base);
        let js_mean = (!js_pairs.is_empty())
            .then(|| js_pairs.iter().map(|p| p.divergence).sum::<f64>() / js_pairs.len() as f64);
        let js_max = js_pairs
            .iter()
            .fold(None::<&JsPair>, |best, p| match best {
                Some(b) if b.divergence >= p.divergence => Some(b),
                _ => Some(p),
            })
            .cloned();

        let mut report = Self {
            source: input.source.clone(),
            example: input.example,
            options,
            instructions,
            outputs,
            counts,
            proportions,
            seeds,
            precision,
            chi_square: chi,
            chi_square_dropped_outputs,
            nmi,
            js_pairs,
            js_mean,
            js_max,
            verdict: String::new(),
            warnings: input.warnings.clone(),
        };
        report.verdict = report.make_verdict();
        report
    }

    /// The log base's unit name for the Jensen-Shannon divergence.
    pub fn js_unit(&self) -> &'static str {
        match self.options.js_base {
            LogBase::Two => "bits",
            LogBase::E => "nats",
        }
    }

    fn make_verdict(&self) -> String {
        let c = &self.chi_square;
        let js = self
            .js_mean
            .map_or_else(|| "n/a".into(), |m| format!("{m:.3} {}", self.js_unit()));
        if !c.testable() {
            return "NO TEST: fewer than two instructions or outputs with episodes".into();
        }
        let p = format_p(c.p_value);
        if c.p_value >= self.options.alpha {
            format!(
                "NOT LANGUAGE-CONDITIONED: outputs are independent of the instruction as far as the test can tell \
                 (chi-square p = {p} >= {}; NMI {:.3}; mean JS {js})",
                self.options.alpha, self.nmi
            )
        } else if self.nmi < self.options.nmi_weak {
            format!(
                "NO LANGUAGE GENERALIZATION: outputs depend on the instruction (chi-square p = {p} < {}) but only \
                 negligibly (NMI {:.3} < {}; mean JS {js})",
                self.options.alpha, self.nmi, self.options.nmi_weak
            )
        } else {
            format!(
                "LANGUAGE-CONDITIONED: outputs follow the instruction (chi-square p = {p} < {}; NMI {:.3} >= {}; \
                 mean JS {js})",
                self.options.alpha, self.nmi, self.options.nmi_weak
            )
        }
    }
}

/// A p-value with three significant digits, in scientific notation when small.
pub fn format_p(p: f64) -> String {
    if p == 0.0 {
        "0".into()
    } else if p < 1e-3 {
        format!("{p:.2e}")
    } else {
        format!("{p:.3}")
    }
}
