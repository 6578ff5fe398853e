//! Success-rate tables: mean +- std over seeds per task x regime x policy, as the
//! DexJoCo paper's Table 2, from evaluation folders.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use dexjoco_core::TaskSpec;
use serde::{Deserialize, Serialize};

use crate::error::StatsError;
use crate::evaltree::{DEFAULT_REGIME, LeftOutRun, Run, find_runs};
use crate::measures::{MeanStd, mean_std};

mod progress;

pub use progress::SubtaskProgress;

/// The display name of a task: its spec's (the paper's) for DexJoCo tasks, else the id
/// in title case.
pub fn task_name(task: &str) -> String {
    TaskSpec::builtin(task).map_or_else(
        || {
            task.split('_')
                .filter(|w| !w.is_empty())
                .map(|w| {
                    let mut c = w.chars();
                    c.next()
                        .map_or_else(String::new, |f| f.to_uppercase().chain(c).collect())
                })
                .collect::<Vec<_>>()
                .join(" ")
        },
        |spec| spec.name.clone(),
    )
}

/// Where a task goes in tables: its spec's place in the paper's tables, unknown tasks
/// after the DexJoCo ones.
fn table_position(task: &str) -> u32 {
    TaskSpec::builtin(task)
        .and_then(|s| s.paper_order)
        .unwrap_or(u32::MAX)
}

/// The display name of a regime: `rand_full` -> `rand-full`.
pub fn regime_name(regime: &str) -> String {
    regime.replace('_', "-")
}

/// Success rate in percent and episodes, per seed.
type PerSeed = BTreeMap<u32, (f64, u32)>;

/// A shown value: mean, std and whether it is the best of its row and regime.
type Shown = (f64, Option<f64>, bool);

/// One cell: a policy's success rate on a task under a regime.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuccessCell {
    /// Policy (the folder that holds its runs).
    pub policy: String,
    /// Regime, e.g. `rand_obj`.
    pub regime: String,
    /// Task id.
    pub task: String,
    /// Success rate in percent and episodes, per seed.
    pub per_seed: BTreeMap<u32, (f64, u32)>,
    /// Mean and sample standard deviation (n - 1) over seeds, in percent.
    pub over_seeds: MeanStd,
}

/// The average row of one policy and regime: per seed the mean over tasks, then mean and
/// sample std of those over seeds (as the paper's "Avg." row).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AverageCell {
    /// Policy.
    pub policy: String,
    /// Regime.
    pub regime: String,
    /// Mean success rate over tasks, in percent, per seed (only seeds every task of this
    /// column has).
    pub per_seed: BTreeMap<u32, f64>,
    /// Mean and sample std over those seeds, in percent.
    pub over_seeds: Option<MeanStd>,
    /// Tasks averaged.
    pub tasks: usize,
    /// False when this column lacks some task of the table, or tasks have different seeds.
    pub complete: bool,
}

/// Success rates of several policies over tasks and regimes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SuccessTable {
    /// Where the runs were found.
    pub source: PathBuf,
    /// True for a made-up example input.
    pub example: bool,
    /// Policies (column groups), sorted.
    pub policies: Vec<String>,
    /// Regimes (columns within a group): `rand_obj`, `rand_full`, then others sorted.
    pub regimes: Vec<String>,
    /// Tasks (rows): the paper's order, then others sorted.
    pub tasks: Vec<String>,
    /// Every (policy, regime, task) that has runs.
    pub cells: Vec<SuccessCell>,
    /// The average row.
    pub averages: Vec<AverageCell>,
    /// Things worth knowing (gaps in the seeds).
    pub warnings: Vec<String>,
    /// Run folders that could not be read (a bad marker file...), each with its reason:
    /// left out of the table.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<LeftOutRun>,
    /// How far the episodes of each cell got through the task's subtasks (from the
    /// episodes' records, all seeds together), in table order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub progress: Vec<SubtaskProgress>,
}

impl SuccessTable {
    /// A Markdown table of the subtask progress of each cell (empty when no cell has
    /// episode folders): per subtask the episodes that completed it, and the mean number
    /// completed; cells whose folders carry no subtask records say so.
    pub fn progress_markdown(&self) -> String {
        use std::fmt::Write as _;
        if self.progress.is_empty() {
            return String::new();
        }
        let mut s = String::from(
            "Subtask progress (episodes that completed each subtask, all seeds together):\n\n\
             | Policy | Regime | Task | Episodes | Completed per subtask | Mean completed |\n\
             |---|---|---|---:|---|---:|\n",
        );
        for p in &self.progress {
            let (per, mean) = if p.episodes == 0 {
                (
                    "no subtask records (the folders have no `episode.json` of `dexjoco-data eval`: \
                     reference-made)"
                        .to_owned(),
                    "-".to_owned(),
                )
            } else {
                let per: Vec<String> = p
                    .subtasks
                    .iter()
                    .map(|st| {
                        format!(
                            "{} {} ({:.0} %)",
                            st.text,
                            st.completed,
                            100.0 * st.completed as f64 / p.episodes as f64
                        )
                    })
                    .collect();
                (
                    per.join("; "),
                    format!("{:.2} of {}", p.mean_completed, p.subtasks.len()),
                )
            };
            let missing = if p.without_record > 0 && p.episodes > 0 {
                format!(" (+{} without records)", p.without_record)
            } else if p.episodes == 0 {
                format!(" ({} without records)", p.without_record)
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {}{missing} | {per} | {mean} |",
                p.policy,
                regime_name(&p.regime),
                task_name(&p.task),
                p.episodes,
            );
        }
        s
    }
}

/// The policy of a run: the path of its parent below the root, or the root's own name
/// when the run sits directly in it (or is the root).
fn policy_of(root: &Path, run: &Run) -> String {
    let parents = run.parents();
    if parents.is_empty() {
        root.canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "policy".into())
    } else {
        parents
    }
}

impl SuccessTable {
    /// Reads every run folder `<task>[_rand_<x>]_seed<s>` below `root`. The policy of a
    /// run is the path of its parent below the root (the root's own name when runs sit
    /// directly in it). Each run's rate comes from its `success_rate_<n>_<episodes>.txt`
    /// marker when present, else from counting its success and failure episode folders.
    pub fn load(root: &Path) -> Result<Self, StatsError> {
        let (runs, left_out) = find_runs(root)?;
        if runs.is_empty() {
            return Err(StatsError::Empty {
                path: root.to_path_buf(),
                message: format!(
                    "no run folders (<task>[_rand_full]_seed<s>/ with episode folders or a \
                     success_rate_<n>_<episodes>.txt marker) found{}",
                    crate::evaltree::left_out_note(&left_out)
                ),
            });
        }
        let mut warnings = Vec::new();
        let rates = Self::rates(root, &runs)?;
        let policies: Vec<String> = rates
            .keys()
            .map(|k| k.0.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        let mut regimes: Vec<String> = rates
            .keys()
            .map(|k| k.1.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        regimes.sort_by_key(|r| (r != DEFAULT_REGIME, r != "rand_full", r.clone()));
        let mut tasks: Vec<String> = rates
            .keys()
            .map(|k| k.2.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        tasks.sort_by_key(|t| (table_position(t), t.clone()));
        let cells = Self::cells(rates, &policies, &regimes, &tasks);
        let averages = Self::averages(&cells, &policies, &regimes, &tasks, &mut warnings);
        let progress = SubtaskProgress::of_runs(root, &runs, &cells);
        Ok(Self {
            source: root.to_path_buf(),
            example: root.join(crate::language::EXAMPLE_MARKER).is_file(),
            policies,
            regimes,
            tasks,
            cells,
            averages,
            warnings,
            left_out,
            progress,
        })
    }

    /// The success rate (%) and episode count of every run by (policy, regime, task) and
    /// seed.
    fn rates(
        root: &Path,
        runs: &[Run],
    ) -> Result<BTreeMap<(String, String, String), PerSeed>, StatsError> {
        let mut rates: BTreeMap<(String, String, String), PerSeed> = BTreeMap::new();
        for run in runs {
            let policy = policy_of(root, run);
            let Some((rate, episodes)) = run.success_rate() else {
                continue;
            };
            let key = (policy, run.name.regime.clone(), run.name.task.clone());
            let per_seed = rates.entry(key.clone()).or_default();
            if per_seed
                .insert(run.name.seed, (100.0 * rate, episodes))
                .is_some()
            {
                return Err(StatsError::invalid(
                    &run.dir,
                    format!(
                        "a second run of policy '{}', task '{}', regime '{}', seed {}",
                        key.0, key.2, key.1, run.name.seed
                    ),
                ));
            }
        }
        Ok(rates)
    }

    /// One cell per (policy, regime, task), in table order.
    fn cells(
        rates: BTreeMap<(String, String, String), PerSeed>,
        policies: &[String],
        regimes: &[String],
        tasks: &[String],
    ) -> Vec<SuccessCell> {
        let cells: Vec<SuccessCell> = rates
            .into_iter()
            .map(|((policy, regime, task), per_seed)| {
                let values: Vec<f64> = per_seed.values().map(|v| v.0).collect();
                SuccessCell {
                    policy,
                    regime,
                    task,
                    over_seeds: mean_std(&values).expect("every cell has a seed"),
                    per_seed,
                }
            })
            .collect();

        let mut cells = cells;
        let rank = |list: &[String], x: &String| list.iter().position(|y| y == x);
        cells.sort_by_key(|c| {
            (
                rank(policies, &c.policy),
                rank(regimes, &c.regime),
                rank(tasks, &c.task),
            )
        });
        cells
    }

    /// The average of each policy and regime over its tasks (over the seeds every task
    /// has), a warning added to `warnings` for each incomplete one.
    fn averages(
        cells: &[SuccessCell],
        policies: &[String],
        regimes: &[String],
        tasks: &[String],
        warnings: &mut Vec<String>,
    ) -> Vec<AverageCell> {
        let mut averages = Vec::new();
        for policy in policies {
            for regime in regimes {
                let column: Vec<&SuccessCell> = cells
                    .iter()
                    .filter(|c| &c.policy == policy && &c.regime == regime)
                    .collect();
                if column.is_empty() {
                    continue;
                }
                let seed_sets: Vec<BTreeSet<u32>> = column
                    .iter()
                    .map(|c| c.per_seed.keys().copied().collect())
                    .collect();
                let common: BTreeSet<u32> = seed_sets
                    .iter()
                    .skip(1)
                    .fold(seed_sets[0].clone(), |acc, s| {
                        acc.intersection(s).copied().collect()
                    });
                let same_seeds = seed_sets.iter().all(|s| *s == common);
                let per_seed: BTreeMap<u32, f64> = common
                    .iter()
                    .map(|s| {
                        let sum: f64 = column.iter().map(|c| c.per_seed[s].0).sum();
                        (*s, sum / column.len() as f64)
                    })
                    .collect();
                let complete = column.len() == tasks.len() && same_seeds;
                if !complete {
                    warnings.push(format!(
                        "average of {policy} / {regime}: over {} of {} tasks{}",
                        column.len(),
                        tasks.len(),
                        if same_seeds {
                            ""
                        } else {
                            ", and only the seeds every task has"
                        }
                    ));
                }
                averages.push(AverageCell {
                    policy: policy.clone(),
                    regime: regime.clone(),
                    over_seeds: mean_std(&per_seed.values().copied().collect::<Vec<_>>()),
                    per_seed,
                    tasks: column.len(),
                    complete,
                });
            }
        }
        averages
    }

    /// The cell of a policy, regime and task.
    pub fn cell(&self, policy: &str, regime: &str, task: &str) -> Option<&SuccessCell> {
        self.cells
            .iter()
            .find(|c| c.policy == policy && c.regime == regime && c.task == task)
    }

    /// The average of a policy and regime.
    pub fn average(&self, policy: &str, regime: &str) -> Option<&AverageCell> {
        self.averages
            .iter()
            .find(|c| c.policy == policy && c.regime == regime)
    }

    /// Whether a mean is the best of its row and regime over policies (bold in the
    /// tables; only where two or more policies have a value).
    fn is_best(&self, mean: f64, row: impl Fn(&str) -> Option<f64>) -> bool {
        let values: Vec<f64> = self.policies.iter().filter_map(|p| row(p)).collect();
        if values.len() < 2 {
            return false;
        }
        let best = values.into_iter().fold(f64::NEG_INFINITY, f64::max);
        (mean - best).abs() < 1e-9
    }

    /// Every row: (task name, then per policy and regime the mean/std when present).
    fn rows(&self) -> Vec<(String, Vec<Option<Shown>>)> {
        let mut rows = Vec::new();
        for task in &self.tasks {
            let mut values = Vec::new();
            for policy in &self.policies {
                for regime in &self.regimes {
                    values.push(self.cell(policy, regime, task).map(|c| {
                        let best = self.is_best(c.over_seeds.mean, |p| {
                            self.cell(p, regime, task).map(|c| c.over_seeds.mean)
                        });
                        (c.over_seeds.mean, c.over_seeds.std, best)
                    }));
                }
            }
            rows.push((task_name(task), values));
        }
        let mut values = Vec::new();
        for policy in &self.policies {
            for regime in &self.regimes {
                values.push(self.average(policy, regime).and_then(|a| {
                    let m = a.over_seeds?;
                    let best = self.is_best(m.mean, |p| {
                        self.average(p, regime)
                            .and_then(|a| a.over_seeds)
                            .map(|m| m.mean)
                    });
                    Some((m.mean, m.std, best))
                }));
            }
        }
        rows.push(("Avg.".into(), values));
        rows
    }

    /// A Markdown table: one row per task and the average, one column per policy and
    /// regime, `mean ± std` in percent (best of a row and regime in bold).
    pub fn to_markdown(&self) -> String {
        let mut s = String::from("| Task |");
        for policy in &self.policies {
            for regime in &self.regimes {
                let _ = write!(s, " {policy} {} |", regime_name(regime));
            }
        }
        s.push_str("\n|---|");
        s.push_str(&"---:|".repeat(self.policies.len() * self.regimes.len()));
        s.push('\n');
        for (name, values) in self.rows() {
            let _ = write!(s, "| {name} |");
            for v in values {
                match v {
                    Some((m, sd, best)) => {
                        let text = format!(
                            "{m:.1} ± {}",
                            sd.map_or_else(|| "n/a".into(), |sd| format!("{sd:.1}"))
                        );
                        if best {
                            let _ = write!(s, " **{text}** |");
                        } else {
                            let _ = write!(s, " {text} |");
                        }
                    }
                    None => s.push_str(" – |"),
                }
            }
            s.push('\n');
        }
        s
    }

    /// A LaTeX table in the layout of the paper's Table 2 (needs the booktabs, multirow
    /// and array packages): per policy a group of regime columns, each `mean` with a
    /// small `±std`, the best of a row and regime in bold.
    pub fn to_latex(&self) -> String {
        let nreg = self.regimes.len();
        let group = (0..nreg)
            .map(|k| {
                let sep = if k + 1 < nreg { "@{\\hspace{3pt}}" } else { "" };
                format!("r@{{\\tiny$\\pm$}}>{{\\tiny}}l{sep}")
            })
            .collect::<String>();
        let spec = std::iter::once("r".to_string())
            .chain(self.policies.iter().map(|_| group.clone()))
            .collect::<Vec<_>>()
            .join(" | ");
        let mut s = String::new();
        s.push_str(
            "% Generated by dexjoco-data stats; needs \\usepackage{booktabs,multirow,array}.\n",
        );
        if self.example {
            s.push_str("% EXAMPLE INPUT (synthetic numbers), not results.\n");
        }
        s.push_str("\\begin{table}[htbp]\n    \\centering\n    \\scriptsize\n    \\setlength{\\tabcolsep}{3pt}\n");
        let _ = writeln!(s, "    \\begin{{tabular}}{{{spec}}}");
        s.push_str("        \\toprule\n");
        let np = self.policies.len();
        let mut head = String::from("        \\multicolumn{1}{c|}{\\multirow{2}{*}{Task}}");
        for (i, policy) in self.policies.iter().enumerate() {
            let bar = if i + 1 < np { "|" } else { "" };
            let _ = write!(
                head,
                " & \\multicolumn{{{}}}{{c{bar}}}{{{}}}",
                2 * nreg,
                latex_escape(policy)
            );
        }
        s.push_str(&head);
        s.push_str(" \\\\\n        ");
        for (i, _) in self.policies.iter().enumerate() {
            for (k, regime) in self.regimes.iter().enumerate() {
                let bar = if k + 1 == nreg && i + 1 < np { "|" } else { "" };
                let _ = write!(
                    s,
                    "& \\multicolumn{{2}}{{c{bar}}}{{{}}}",
                    latex_escape(&regime_name(regime))
                );
            }
            s.push(' ');
        }
        s.push_str("\\\\\n        \\midrule\n");
        for (name, values) in self.rows() {
            if name == "Avg." {
                s.push_str("        \\midrule\n");
            }
            let _ = write!(s, "        {:<15}", latex_escape(&name));
            for v in values {
                match v {
                    Some((m, sd, best)) => {
                        let mean = if best {
                            format!("\\textbf{{{m:.1}}}")
                        } else {
                            format!("{m:.1}")
                        };
                        let sd = sd.map_or_else(|| "--".into(), |sd| format!("{sd:.1}"));
                        let _ = write!(s, " & {mean:>5}&{sd:<4}");
                    }
                    None => s.push_str(" & --&"),
                }
            }
            s.push_str(" \\\\\n");
        }
        s.push_str("        \\bottomrule\n    \\end{tabular}\n");
        let seeds: BTreeSet<usize> = self.cells.iter().map(|c| c.per_seed.len()).collect();
        let seeds = seeds
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("/");
        let _ = writeln!(
            s,
            "    \\caption{{Success rate (\\%), mean $\\pm$ sample std over {seeds} seeds. ``/B'': bimanual tasks.{}}}",
            if self.example {
                " EXAMPLE INPUT, not results."
            } else {
                ""
            }
        );
        s.push_str("\\end{table}\n");
        s
    }

    /// Tidy CSV: one line per policy, regime and task (and the averages, task `average`):
    /// `policy,regime,task,task_name,seeds,mean_pct,std_pct,per_seed_pct`, the last as
    /// `seed:rate` pairs separated by `;`.
    pub fn to_csv(&self) -> Result<String, StatsError> {
        let mut w = csv::Writer::from_writer(Vec::new());
        let err = |source| StatsError::Csv {
            path: PathBuf::from("<success table>"),
            source,
        };
        w.write_record([
            "policy",
            "regime",
            "task",
            "task_name",
            "seeds",
            "mean_pct",
            "std_pct",
            "per_seed_pct",
        ])
        .map_err(err)?;
        let fmt_std = |s: Option<f64>| s.map_or_else(String::new, |s| format!("{s:.6}"));
        for c in &self.cells {
            let per = c
                .per_seed
                .iter()
                .map(|(s, (r, _))| format!("{s}:{r:.6}"))
                .collect::<Vec<_>>()
                .join(";");
            w.write_record([
                c.policy.clone(),
                c.regime.clone(),
                c.task.clone(),
                task_name(&c.task),
                c.per_seed.len().to_string(),
                format!("{:.6}", c.over_seeds.mean),
                fmt_std(c.over_seeds.std),
                per,
            ])
            .map_err(err)?;
        }
        for a in &self.averages {
            let Some(m) = a.over_seeds else { continue };
            let per = a
                .per_seed
                .iter()
                .map(|(s, r)| format!("{s}:{r:.6}"))
                .collect::<Vec<_>>()
                .join(";");
            w.write_record([
                a.policy.clone(),
                a.regime.clone(),
                "average".into(),
                "Avg.".into(),
                a.per_seed.len().to_string(),
                format!("{:.6}", m.mean),
                fmt_std(m.std),
                per,
            ])
            .map_err(err)?;
        }
        let bytes = w.into_inner().map_err(|e| StatsError::Io(e.into_error()))?;
        Ok(String::from_utf8(bytes).expect("CSV of UTF-8 strings"))
    }
}

/// Escapes the characters LaTeX treats specially in text.
pub fn latex_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\textbackslash{}"),
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(task_name("bimanual_unlock_ipad"), "Unlock iPad /B");
        assert_eq!(task_name("stack_cups"), "Stack Cups");
        assert_eq!(regime_name("rand_full"), "rand-full");
        assert_eq!(latex_escape("a_b & 50%"), "a\\_b \\& 50\\%");
    }
}
