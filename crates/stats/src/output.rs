//! Writing reports to a folder: JSON, CSV, Markdown, LaTeX and figures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::dataset::DatasetStats;
use crate::error::StatsError;
use crate::language::{LanguageReport, format_p};
use crate::plot;
use crate::success::SuccessTable;

/// `stats --dataset`'s normalization statistics of the source arrays as stored (openpi's
/// format). Not named `norm_stats.json`: that is the file `convert --norm-stats` writes
/// of the training columns, the one to hand to openpi (the README says how they differ).
pub const SOURCE_NORM_STATS: &str = "source_norm_stats.json";

/// The folder of per-task [`SOURCE_NORM_STATS`] files (`<task>.json`).
pub const SOURCE_NORM_STATS_DIR: &str = "source_norm_stats";

fn write_json(path: &Path, value: &impl Serialize) -> Result<(), StatsError> {
    let text = serde_json::to_string_pretty(value).map_err(|source| StatsError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    fs_err::write(path, text + "\n")?;
    Ok(())
}

fn csv_text(
    path: &Path,
    rows: impl IntoIterator<Item = Vec<String>>,
) -> Result<String, StatsError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.write_record(&r).map_err(|source| StatsError::Csv {
            path: path.to_path_buf(),
            source,
        })?;
    }
    let bytes = w.into_inner().map_err(|e| StatsError::Io(e.into_error()))?;
    Ok(String::from_utf8(bytes).expect("UTF-8 strings"))
}

fn fmt_std(s: Option<f64>) -> String {
    s.map_or_else(|| "n/a".into(), |s| format!("{s:.1}"))
}

impl LanguageReport {
    /// A Markdown report: distribution, precision, tests and the verdict.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        if self.example {
            s.push_str(
                "> EXAMPLE INPUT (synthetic, made by a script): these numbers are not results.\n\n",
            );
        }
        let episodes: u64 = self.counts.iter().flatten().sum();
        let _ = writeln!(
            s,
            "Language evaluation of `{}`: {} instructions, {} episodes, seeds {:?}.\n",
            self.source.display(),
            self.instructions.len(),
            episodes,
            self.seeds
        );
        self.markdown_distribution(&mut s);
        self.markdown_precision(&mut s);
        self.markdown_tests(&mut s);
        let _ = writeln!(s, "\nVerdict: {}", self.verdict);
        for w in &self.warnings {
            let _ = writeln!(s, "\nwarning: {w}");
        }
        s
    }

    /// The output distribution table: each instruction's share of episodes per output.
    fn markdown_distribution(&self, s: &mut String) {
        s.push_str("Output distribution (share of each instruction's episodes; expected answer in bold):\n\n| Instruction | Expected |");
        for o in &self.outputs {
            let _ = write!(s, " {o} |");
        }
        s.push_str(" Episodes |\n|---|---|");
        s.push_str(&"---:|".repeat(self.outputs.len() + 1));
        s.push('\n');
        for (i, ins) in self.instructions.iter().enumerate() {
            let _ = write!(s, "| {} | {} |", ins.label, ins.expected);
            for (j, o) in self.outputs.iter().enumerate() {
                let p = format!("{:.3}", self.proportions[i][j]);
                if *o == ins.expected {
                    let _ = write!(s, " **{p}** |");
                } else {
                    let _ = write!(s, " {p} |");
                }
            }
            let _ = writeln!(s, " {} |", self.counts[i].iter().sum::<u64>());
        }
    }

    /// The precision table: mean ± sample std over seeds, and each seed's.
    fn markdown_precision(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "\nPrecision (% of episodes entering the expected answer), mean ± sample std (n - 1) over {} seed(s):\n",
            self.seeds.len()
        );
        s.push_str("| Instruction | Precision % | Per seed |\n|---|---:|---|\n");
        for p in &self.precision {
            let per = p
                .per_seed
                .iter()
                .map(|(k, v)| format!("{k}: {v:.1}"))
                .collect::<Vec<_>>()
                .join(", ");
            let _ = writeln!(
                s,
                "| {} | {:.1} ± {} | {per} |",
                p.instruction,
                p.over_seeds.mean,
                fmt_std(p.over_seeds.std)
            );
        }
    }

    /// The tests: chi-square, normalized mutual information, Jensen-Shannon divergence.
    fn markdown_tests(&self, s: &mut String) {
        let c = &self.chi_square;
        s.push_str("\nTests (all seeds pooled):\n\n");
        let _ = writeln!(
            s,
            "- Chi-square test of independence (Pearson, no continuity correction): statistic {:.4}, dof {}, p = {}",
            c.statistic,
            c.dof,
            format_p(c.p_value)
        );
        if !self.chi_square_dropped_outputs.is_empty() {
            let _ = writeln!(
                s,
                "  (outputs never entered, left out of the test: {})",
                self.chi_square_dropped_outputs.join(", ")
            );
        }
        if !c.dropped_rows.is_empty() {
            let names: Vec<&str> = c
                .dropped_rows
                .iter()
                .map(|&i| self.instructions[i].label.as_str())
                .collect();
            let _ = writeln!(
                s,
                "  (instructions without episodes, left out: {})",
                names.join(", ")
            );
        }
        let _ = writeln!(
            s,
            "- Normalized mutual information (arithmetic-mean normalization): {:.4}",
            self.nmi
        );
        match (&self.js_mean, &self.js_max) {
            (Some(m), Some(x)) => {
                let _ = writeln!(
                    s,
                    "- Jensen-Shannon divergence (log base {}, {}) over {} instruction pairs: mean {:.4}, max {:.4} (\"{}\" vs \"{}\")",
                    self.options.js_base.name(),
                    self.js_unit(),
                    self.js_pairs.len(),
                    m,
                    x.divergence,
                    x.a,
                    x.b
                );
            }
            _ => s.push_str(
                "- Jensen-Shannon divergence: fewer than two instructions with episodes\n",
            ),
        }
    }

    /// Writes `language_eval.json`, `summary.md`, `distribution.csv`, `precision.csv`,
    /// `js_divergence.csv` and `heatmap.{png,svg}` into `dir` (created). Returns the files.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, StatsError> {
        fs_err::create_dir_all(dir)?;
        let mut files = Vec::new();
        let json = dir.join("language_eval.json");
        write_json(&json, self)?;
        files.push(json);
        let md = dir.join("summary.md");
        fs_err::write(&md, self.to_markdown())?;
        files.push(md);

        let path = dir.join("distribution.csv");
        let mut rows = vec![
            vec!["instruction", "expected", "output", "count", "proportion"]
                .into_iter()
                .map(String::from)
                .collect(),
        ];
        for (i, ins) in self.instructions.iter().enumerate() {
            for (j, o) in self.outputs.iter().enumerate() {
                rows.push(vec![
                    ins.label.clone(),
                    ins.expected.clone(),
                    o.clone(),
                    self.counts[i][j].to_string(),
                    format!("{:.6}", self.proportions[i][j]),
                ]);
            }
        }
        fs_err::write(&path, csv_text(&path, rows)?)?;
        files.push(path);

        let path = dir.join("precision.csv");
        let mut header: Vec<String> = [
            "instruction",
            "expected",
            "episodes",
            "correct",
            "mean_pct",
            "std_pct",
        ]
        .map(String::from)
        .to_vec();
        header.extend(self.seeds.iter().map(|s| format!("seed{s}_pct")));
        let mut rows = vec![header];
        for p in &self.precision {
            let mut r = vec![
                p.instruction.clone(),
                p.expected.clone(),
                p.episodes.to_string(),
                p.correct.to_string(),
                format!("{:.6}", p.over_seeds.mean),
                p.over_seeds
                    .std
                    .map_or_else(String::new, |s| format!("{s:.6}")),
            ];
            r.extend(self.seeds.iter().map(|s| {
                p.per_seed
                    .get(s)
                    .map_or_else(String::new, |v| format!("{v:.6}"))
            }));
            rows.push(r);
        }
        fs_err::write(&path, csv_text(&path, rows)?)?;
        files.push(path);

        let path = dir.join("js_divergence.csv");
        let mut rows = vec![vec![
            "a".to_string(),
            "b".into(),
            format!("js_divergence_base_{}", self.options.js_base.name()),
        ]];
        rows.extend(
            self.js_pairs
                .iter()
                .map(|p| vec![p.a.clone(), p.b.clone(), format!("{:.9}", p.divergence)]),
        );
        fs_err::write(&path, csv_text(&path, rows)?)?;
        files.push(path);

        let (png, svg) = (dir.join("heatmap.png"), dir.join("heatmap.svg"));
        plot::heatmap(self, &png, &svg)?;
        files.push(png);
        files.push(svg);
        Ok(files)
    }
}

impl SuccessTable {
    /// Writes `success_table.{md,tex,csv,json}` into `dir` (created). Returns the files.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, StatsError> {
        fs_err::create_dir_all(dir)?;
        let mut md = String::new();
        if self.example {
            md.push_str(
                "> EXAMPLE INPUT (synthetic, made by a script): these numbers are not results.\n\n",
            );
        }
        md.push_str(&self.to_markdown());
        md.push_str("\nSuccess rate (%), mean ± sample std (n - 1) over seeds; the average row averages the tasks per seed first.\n");
        let progress = self.progress_markdown();
        if !progress.is_empty() {
            md.push('\n');
            md.push_str(&progress);
        }
        let files = [
            ("success_table.md", md),
            ("success_table.tex", self.to_latex()),
            ("success_table.csv", self.to_csv()?),
        ];
        let mut out = Vec::new();
        for (name, text) in files {
            let p = dir.join(name);
            fs_err::write(&p, text)?;
            out.push(p);
        }
        let json = dir.join("success_table.json");
        write_json(&json, self)?;
        out.push(json);
        Ok(out)
    }
}

impl DatasetStats {
    /// Writes `dataset_stats.json`, `summary.md`, `source_norm_stats.json` (openpi's
    /// format, of the source arrays as stored, dataset-wide; per task under
    /// `source_norm_stats/<task>.json`) and the figures `episode_lengths.{png,svg}`
    /// and `<array>_distribution.{png,svg}` into `dir` (created). Returns the files.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, StatsError> {
        fs_err::create_dir_all(dir)?;
        let mut files = Vec::new();
        let p = dir.join("dataset_stats.json");
        write_json(&p, self)?;
        files.push(p);
        let p = dir.join("summary.md");
        fs_err::write(&p, self.to_markdown())?;
        files.push(p);
        let p = dir.join(SOURCE_NORM_STATS);
        write_json(&p, &self.norm_stats)?;
        files.push(p);
        let per_task = dir.join(SOURCE_NORM_STATS_DIR);
        fs_err::create_dir_all(&per_task)?;
        for t in &self.tasks {
            let p = per_task.join(format!("{}.json", t.task));
            write_json(&p, &t.norm_stats)?;
            files.push(p);
        }
        let (png, svg) = (
            dir.join("episode_lengths.png"),
            dir.join("episode_lengths.svg"),
        );
        plot::length_histogram(&self.lengths, &png, &svg)?;
        files.extend([png, svg]);
        for (name, s) in &self.arrays {
            let (png, svg) = (
                dir.join(format!("{name}_distribution.png")),
                dir.join(format!("{name}_distribution.svg")),
            );
            plot::array_histograms(name, s, &png, &svg)?;
            files.extend([png, svg]);
        }
        Ok(files)
    }
}
