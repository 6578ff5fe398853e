//! The language-generalization analysis of the DexJoCo paper (appendix A): which
//! password a policy enters for each instruction, and whether that depends on the
//! instruction at all.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::StatsError;
use crate::evaltree::{Entered, find_runs};
use crate::measures::{
    ChiSquare, LogBase, MeanStd, chi_square, js_divergence, mean_std, normalized_mutual_information,
};

/// The output label of an episode in which no digit was entered.
pub const NONE_OUTPUT: &str = "none";

/// The file, at the root of an evaluation tree, that names each instruction config:
/// columns `config,instruction,expected` and optionally `prompt`.
pub const MANIFEST_FILE: &str = "instructions.csv";

/// The file whose presence marks an input as a made-up example, not results.
pub const EXAMPLE_MARKER: &str = "EXAMPLE.md";

/// One evaluated episode.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Trial {
    /// Short instruction label, e.g. `1+1` or `two`.
    pub instruction: String,
    /// The answer the instruction asks for, e.g. `2`.
    pub expected: String,
    /// Evaluation seed.
    pub seed: u32,
    /// Episode number within the seed.
    pub episode: u32,
    /// What was entered: the digits, or `none`.
    pub output: String,
}

/// An instruction of the study.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Instruction {
    /// Short label, e.g. `one plus one`.
    pub label: String,
    /// Expected answer, e.g. `2`.
    pub expected: String,
    /// The full language instruction, when known.
    pub prompt: Option<String>,
}

/// The trials of a language study, as read from an evaluation tree or a tidy table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LanguageInput {
    /// Where they were read from.
    pub source: PathBuf,
    /// True when the input is marked as a made-up example (an `EXAMPLE.md` beside it).
    pub example: bool,
    /// The instructions, in the order they are shown.
    pub instructions: Vec<Instruction>,
    /// Every episode.
    pub trials: Vec<Trial>,
    /// Things worth knowing that did not stop the reading.
    pub warnings: Vec<String>,
}

/// The answer an instruction label asks for, when it is a number, a number word, or a
/// sum of those with `+` or `plus` (`1`, `two`, `1+1`, `one plus one`, `password_2+2`).
pub fn infer_expected(label: &str) -> Option<String> {
    const WORDS: [&str; 21] = [
        "zero",
        "one",
        "two",
        "three",
        "four",
        "five",
        "six",
        "seven",
        "eight",
        "nine",
        "ten",
        "eleven",
        "twelve",
        "thirteen",
        "fourteen",
        "fifteen",
        "sixteen",
        "seventeen",
        "eighteen",
        "nineteen",
        "twenty",
    ];
    let text = label.to_lowercase().replace(['_', '-'], " ");
    let text = text.trim();
    let text = text.strip_prefix("password").unwrap_or(text).trim();
    let text = text.replace(" plus ", "+");
    let mut sum: u64 = 0;
    for operand in text.split('+') {
        let operand = operand.trim();
        let value = if !operand.is_empty() && operand.bytes().all(|b| b.is_ascii_digit()) {
            operand.parse::<u64>().ok()?
        } else {
            WORDS.iter().position(|w| *w == operand)? as u64
        };
        sum = sum.checked_add(value)?;
    }
    Some(sum.to_string())
}

fn normalize_output(raw: &str) -> String {
    let t = raw.trim();
    if t.is_empty()
        || t.eq_ignore_ascii_case(NONE_OUTPUT)
        || t.eq_ignore_ascii_case("no_password_input")
    {
        NONE_OUTPUT.to_string()
    } else {
        t.to_string()
    }
}

impl LanguageInput {
    /// Reads an evaluation tree (a folder), a tidy CSV (`.csv`) or tidy JSON (`.json`).
    pub fn load(path: &Path) -> Result<Self, StatsError> {
        let mut input = if path.is_dir() {
            Self::from_tree(path)?
        } else {
            match path.extension().and_then(|e| e.to_str()) {
                Some(e) if e.eq_ignore_ascii_case("csv") => Self::from_csv(path)?,
                Some(e) if e.eq_ignore_ascii_case("json") => Self::from_json(path)?,
                _ if !path.exists() => {
                    return Err(StatsError::invalid(path, "no such file or folder"));
                }
                _ => {
                    return Err(StatsError::invalid(
                        path,
                        "expected an evaluation folder, a .csv or a .json file",
                    ));
                }
            }
        };
        let beside = if path.is_dir() {
            Some(path)
        } else {
            path.parent()
        };
        input.example = beside.is_some_and(|d| d.join(EXAMPLE_MARKER).is_file());
        Ok(input)
    }

    /// Reads an evaluation tree: `<root>/<config>/<task>_seed<s>/episode_XX_<outcome>[_<digits>|_no_password_input]/`.
    ///
    /// Each instruction config is the path of a run folder's parent below the root (the
    /// run folder's name without `_seed<s>` when it sits in the root). Labels and
    /// expected answers come from `instructions.csv` at the root when present, else the
    /// label is the config name and the expected answer is inferred from it
    /// ([`infer_expected`]). A success folder without digits counts as the expected
    /// answer; a failure folder without digits is an error.
    pub fn from_tree(root: &Path) -> Result<Self, StatsError> {
        let manifest = read_manifest(root)?;
        let runs = find_runs(root)?;
        if runs.is_empty() {
            return Err(StatsError::Empty {
                path: root.to_path_buf(),
                message: "no run folders (<task>_seed<s>/ holding episode_XX_* folders) found"
                    .into(),
            });
        }
        let mut warnings = Vec::new();
        let mut configs: Vec<String> = manifest.iter().map(|(c, _)| c.clone()).collect();
        let mut by_config: BTreeMap<String, Vec<&crate::evaltree::Run>> = BTreeMap::new();
        for run in &runs {
            let parent = run.relative.parent().unwrap_or(Path::new(""));
            let config = if parent.as_os_str().is_empty() {
                let name = &run.name;
                if name.regime == crate::evaltree::DEFAULT_REGIME {
                    name.task.clone()
                } else {
                    format!("{}_{}", name.task, name.regime)
                }
            } else {
                parent
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join("/")
            };
            if !configs.contains(&config) {
                configs.push(config.clone());
            }
            by_config.entry(config).or_default().push(run);
        }
        let mut instructions = Vec::new();
        let mut trials = Vec::new();
        for config in &configs {
            let instruction = match manifest.iter().find(|(c, _)| c == config) {
                Some((_, i)) => i.clone(),
                None => {
                    let expected = infer_expected(config).ok_or_else(|| {
                        StatsError::invalid(
                            root.join(config),
                            format!(
                                "cannot tell the expected answer of instruction config '{config}': \
                                 list it in {MANIFEST_FILE} (columns config,instruction,expected[,prompt])"
                            ),
                        )
                    })?;
                    Instruction {
                        label: config.clone(),
                        expected,
                        prompt: None,
                    }
                }
            };
            let Some(runs) = by_config.get(config) else {
                warnings.push(format!(
                    "{}: instruction '{}' is listed but has no runs; left out",
                    root.join(MANIFEST_FILE).display(),
                    instruction.label
                ));
                continue;
            };
            let mut seeds = BTreeSet::new();
            for run in runs {
                if !seeds.insert(run.name.seed) {
                    return Err(StatsError::invalid(
                        &run.dir,
                        format!(
                            "a second run of seed {} for instruction '{}'",
                            run.name.seed, instruction.label
                        ),
                    ));
                }
                if run.episodes.is_empty() {
                    warnings.push(format!(
                        "{}: a marker file but no episode folders; nothing to count",
                        run.dir.display()
                    ));
                }
                if let Some(w) = run.consistency_warning() {
                    warnings.push(w);
                }
                for e in &run.episodes {
                    let output = match &e.entered {
                        Entered::Digits(d) => d.clone(),
                        Entered::NoInput => NONE_OUTPUT.to_string(),
                        Entered::NotRecorded if e.success => instruction.expected.clone(),
                        Entered::NotRecorded => {
                            return Err(StatsError::invalid(
                                run.dir.join(format!("episode_{:02}_failure", e.index)),
                                "a failed episode without the digits entered: the language study needs \
                                 episode_XX_failure_<digits> or episode_XX_failure_no_password_input",
                            ));
                        }
                    };
                    if e.success != (output == instruction.expected) {
                        warnings.push(format!(
                            "{}: episode {} is marked {} but entered '{}' where '{}' is expected",
                            run.dir.display(),
                            e.index,
                            if e.success { "a success" } else { "a failure" },
                            output,
                            instruction.expected
                        ));
                    }
                    trials.push(Trial {
                        instruction: instruction.label.clone(),
                        expected: instruction.expected.clone(),
                        seed: run.name.seed,
                        episode: e.index,
                        output,
                    });
                }
            }
            instructions.push(instruction);
        }
        Self::finish(root, instructions, trials, warnings)
    }

    /// Reads a tidy CSV with a header: `instruction`, `expected` (or `expected_answer`),
    /// `seed`, `episode`, `output` (digits; empty or `none` when nothing was entered),
    /// and optionally `prompt`.
    pub fn from_csv(path: &Path) -> Result<Self, StatsError> {
        let csv_err = |source| StatsError::Csv {
            path: path.to_path_buf(),
            source,
        };
        let file = fs_err::File::open(path)?;
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(file);
        let headers = reader.headers().map_err(csv_err)?.clone();
        let column = |names: &[&str]| {
            headers
                .iter()
                .position(|h| names.iter().any(|n| h.eq_ignore_ascii_case(n)))
        };
        let need = |names: &[&str]| {
            column(names).ok_or_else(|| {
                StatsError::invalid(
                    path,
                    format!(
                        "no '{}' column (columns: instruction, expected, seed, episode, output[, prompt])",
                        names[0]
                    ),
                )
            })
        };
        let (ci, ce, cs, cp, co) = (
            need(&["instruction"])?,
            need(&["expected", "expected_answer"])?,
            need(&["seed"])?,
            need(&["episode"])?,
            need(&["output"])?,
        );
        let cprompt = column(&["prompt"]);
        let mut rows = Vec::new();
        for (i, record) in reader.records().enumerate() {
            let record = record.map_err(csv_err)?;
            let get = |c: usize| record.get(c).unwrap_or("").to_string();
            rows.push(RawRow {
                row: i + 1,
                instruction: get(ci),
                expected: get(ce),
                seed: get(cs),
                episode: get(cp),
                output: get(co),
                prompt: cprompt.map(get).filter(|p| !p.is_empty()),
            });
        }
        Self::from_rows(path, rows)
    }

    /// Reads tidy JSON: an array of objects with the fields of the CSV form (numbers or
    /// strings; `output` null when nothing was entered).
    pub fn from_json(path: &Path) -> Result<Self, StatsError> {
        let text = fs_err::read_to_string(path)?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|source| StatsError::Json {
                path: path.to_path_buf(),
                source,
            })?;
        let items = value
            .as_array()
            .ok_or_else(|| StatsError::invalid(path, "expected a JSON array of trials"))?;
        let mut rows = Vec::new();
        for (i, item) in items.iter().enumerate() {
            let row = i + 1;
            let field = |names: &[&str], required: bool| -> Result<String, StatsError> {
                let v = names.iter().find_map(|n| item.get(*n));
                match v {
                    Some(serde_json::Value::String(s)) => Ok(s.clone()),
                    Some(serde_json::Value::Number(n)) => Ok(n.to_string()),
                    None | Some(serde_json::Value::Null) if !required => Ok(String::new()),
                    _ => Err(StatsError::Invalid {
                        path: path.to_path_buf(),
                        row: Some(row),
                        message: format!(
                            "field '{}' is missing or not a string or number",
                            names[0]
                        ),
                    }),
                }
            };
            rows.push(RawRow {
                row,
                instruction: field(&["instruction"], true)?,
                expected: field(&["expected", "expected_answer"], true)?,
                seed: field(&["seed"], true)?,
                episode: field(&["episode"], true)?,
                output: field(&["output"], false)?,
                prompt: Some(field(&["prompt"], false)?).filter(|p| !p.is_empty()),
            });
        }
        Self::from_rows(path, rows)
    }

    fn from_rows(path: &Path, rows: Vec<RawRow>) -> Result<Self, StatsError> {
        let mut instructions: Vec<Instruction> = Vec::new();
        let mut trials = Vec::new();
        let mut seen = BTreeSet::new();
        for r in rows {
            let bad = |message: String| StatsError::Invalid {
                path: path.to_path_buf(),
                row: Some(r.row),
                message,
            };
            if r.instruction.is_empty() {
                return Err(bad("empty instruction".into()));
            }
            if r.expected.is_empty() {
                return Err(bad("empty expected answer".into()));
            }
            let seed: u32 = r
                .seed
                .parse()
                .map_err(|_| bad(format!("seed '{}' is not a whole number", r.seed)))?;
            let episode: u32 = r
                .episode
                .parse()
                .map_err(|_| bad(format!("episode '{}' is not a whole number", r.episode)))?;
            match instructions.iter_mut().find(|i| i.label == r.instruction) {
                Some(i) if i.expected != r.expected => {
                    return Err(bad(format!(
                        "instruction '{}' expects '{}' here but '{}' on an earlier row",
                        r.instruction, r.expected, i.expected
                    )));
                }
                Some(i) => {
                    if i.prompt.is_none() {
                        i.prompt = r.prompt.clone();
                    }
                }
                None => instructions.push(Instruction {
                    label: r.instruction.clone(),
                    expected: r.expected.clone(),
                    prompt: r.prompt.clone(),
                }),
            }
            if !seen.insert((r.instruction.clone(), seed, episode)) {
                return Err(bad(format!(
                    "instruction '{}', seed {seed}, episode {episode} appears twice",
                    r.instruction
                )));
            }
            trials.push(Trial {
                instruction: r.instruction,
                expected: r.expected,
                seed,
                episode,
                output: normalize_output(&r.output),
            });
        }
        Self::finish(path, instructions, trials, Vec::new())
    }

    fn finish(
        source: &Path,
        instructions: Vec<Instruction>,
        trials: Vec<Trial>,
        warnings: Vec<String>,
    ) -> Result<Self, StatsError> {
        if trials.is_empty() {
            return Err(StatsError::Empty {
                path: source.to_path_buf(),
                message: "no evaluated episodes".into(),
            });
        }
        Ok(Self {
            source: source.to_path_buf(),
            example: false,
            instructions,
            trials,
            warnings,
        })
    }
}

struct RawRow {
    row: usize,
    instruction: String,
    expected: String,
    seed: String,
    episode: String,
    output: String,
    prompt: Option<String>,
}

/// Reads `instructions.csv` of an evaluation tree, when there is one.
fn read_manifest(root: &Path) -> Result<Vec<(String, Instruction)>, StatsError> {
    let path = root.join(MANIFEST_FILE);
    if !path.is_file() {
        return Ok(Vec::new());
    }
    let csv_err = |source| StatsError::Csv {
        path: path.clone(),
        source,
    };
    let file = fs_err::File::open(&path)?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(file);
    let headers = reader.headers().map_err(csv_err)?.clone();
    let col = |n: &str| headers.iter().position(|h| h.eq_ignore_ascii_case(n));
    let (Some(cc), Some(ci)) = (col("config"), col("instruction")) else {
        return Err(StatsError::invalid(
            &path,
            "needs columns config,instruction,expected[,prompt]",
        ));
    };
    let ce = col("expected").or_else(|| col("expected_answer"));
    let cp = col("prompt");
    let mut out: Vec<(String, Instruction)> = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let record = record.map_err(csv_err)?;
        let get = |c: Option<usize>| c.and_then(|c| record.get(c)).unwrap_or("").to_string();
        let (config, label) = (get(Some(cc)), get(Some(ci)));
        let expected = Some(get(ce))
            .filter(|e| !e.is_empty())
            .or_else(|| infer_expected(&label))
            .ok_or_else(|| StatsError::Invalid {
                path: path.clone(),
                row: Some(i + 1),
                message: format!("no expected answer for '{label}', and none can be inferred"),
            })?;
        if config.is_empty() || label.is_empty() || out.iter().any(|(c, _)| *c == config) {
            return Err(StatsError::Invalid {
                path: path.clone(),
                row: Some(i + 1),
                message: "config and instruction must be given, and each config listed once".into(),
            });
        }
        out.push((
            config,
            Instruction {
                label,
                expected,
                prompt: Some(get(cp)).filter(|p| !p.is_empty()),
            },
        ));
    }
    Ok(out)
}

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

fn output_order(a: &String, b: &String) -> std::cmp::Ordering {
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

        let precision = instructions
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
            .collect();

        let chi = chi_square(&counts);
        let chi_square_dropped_outputs = chi
            .dropped_columns
            .iter()
            .map(|&j| outputs[j].clone())
            .collect();
        let nmi = normalized_mutual_information(&counts);

        let mut js_pairs = Vec::new();
        for a in 0..instructions.len() {
            for b in a + 1..instructions.len() {
                let p: Vec<f64> = counts[a].iter().map(|&c| c as f64).collect();
                let q: Vec<f64> = counts[b].iter().map(|&c| c as f64).collect();
                if let Some(d) = js_divergence(&p, &q, options.js_base) {
                    js_pairs.push(JsPair {
                        a: instructions[a].label.clone(),
                        b: instructions[b].label.clone(),
                        divergence: d,
                    });
                }
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expected_answers_are_inferred() {
        assert_eq!(infer_expected("1").as_deref(), Some("1"));
        assert_eq!(infer_expected("two").as_deref(), Some("2"));
        assert_eq!(infer_expected("1+1").as_deref(), Some("2"));
        assert_eq!(infer_expected("2 + 2").as_deref(), Some("4"));
        assert_eq!(infer_expected("one plus one").as_deref(), Some("2"));
        assert_eq!(
            infer_expected("password_one_plus_one").as_deref(),
            Some("2")
        );
        assert_eq!(infer_expected("banana"), None);
        assert_eq!(infer_expected(""), None);
    }

    #[test]
    fn outputs_are_ordered_numbers_then_words_then_none() {
        let mut v: Vec<String> = ["none", "12", "3", "x", "1"].map(String::from).to_vec();
        v.sort_by(output_order);
        assert_eq!(v, ["1", "3", "12", "x", "none"]);
    }
}
