//! Reading a language study: the reference evaluator's folders
//! (`<config>/<task>_seed<s>/episode_XX_{success|failure}_{digits|no_password_input}/`
//! with `instructions.csv`) or a tidy CSV/JSON of trials.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::StatsError;
use crate::evaltree::{Entered, LeftOutRun, Run, find_runs};

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
    /// Run folders of an evaluation tree that could not be read, each with its reason
    /// (left out of the analysis).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<LeftOutRun>,
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
        let (runs, left_out) = find_runs(root)?;
        if runs.is_empty() {
            return Err(StatsError::Empty {
                path: root.to_path_buf(),
                message: format!(
                    "no run folders (<task>_seed<s>/ holding episode_XX_* folders) found{}",
                    crate::evaltree::left_out_note(&left_out)
                ),
            });
        }
        let mut warnings = Vec::new();
        let (configs, by_config) = group_by_config(&manifest, &runs);
        let mut instructions = Vec::new();
        let mut trials = Vec::new();
        for config in &configs {
            let instruction = instruction_of(root, &manifest, config)?;
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
                run_trials(run, &instruction, &mut warnings, &mut trials)?;
            }
            instructions.push(instruction);
        }
        let mut input = Self::finish(root, instructions, trials, warnings)?;
        input.left_out = left_out;
        Ok(input)
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
        if rows.is_empty() {
            return Err(StatsError::Empty {
                path: path.to_path_buf(),
                message: "no data rows: no evaluated episodes after the header".into(),
            });
        }
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
            left_out: Vec::new(),
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

/// The instruction configs of an evaluation tree, in order (those of the manifest, then
/// new ones as their runs come), and the runs of each. A config is the path of a run
/// folder's parent below the root, or the run folder's name without `_seed<s>` when it
/// sits in the root.
fn group_by_config<'r>(
    manifest: &[(String, Instruction)],
    runs: &'r [Run],
) -> (Vec<String>, BTreeMap<String, Vec<&'r Run>>) {
    let mut configs: Vec<String> = manifest.iter().map(|(c, _)| c.clone()).collect();
    let mut by_config: BTreeMap<String, Vec<&Run>> = BTreeMap::new();
    for run in runs {
        let parents = run.parents();
        let config = if parents.is_empty() {
            let name = &run.name;
            if name.regime == crate::evaltree::DEFAULT_REGIME {
                name.task.clone()
            } else {
                format!("{}_{}", name.task, name.regime)
            }
        } else {
            parents
        };
        if !configs.contains(&config) {
            configs.push(config.clone());
        }
        by_config.entry(config).or_default().push(run);
    }
    (configs, by_config)
}

/// The instruction of a config: the manifest's, else labelled by the config name with
/// the expected answer inferred from it.
fn instruction_of(
    root: &Path,
    manifest: &[(String, Instruction)],
    config: &str,
) -> Result<Instruction, StatsError> {
    Ok(match manifest.iter().find(|(c, _)| c == config) {
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
                label: config.to_owned(),
                expected,
                prompt: None,
            }
        }
    })
}

/// The trials of one run's episodes, added to `trials`; a warning for each episode
/// whose outcome disagrees with its answer.
fn run_trials(
    run: &Run,
    instruction: &Instruction,
    warnings: &mut Vec<String>,
    trials: &mut Vec<Trial>,
) -> Result<(), StatsError> {
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
    Ok(())
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
