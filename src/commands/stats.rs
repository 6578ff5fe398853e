//! `dexjoco-data stats`: the language-generalization analysis and success-rate tables.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_stats::{LanguageInput, LanguageOptions, LanguageReport, LogBase, SuccessTable};

use crate::cli::{GlobalArgs, JsBaseArg, StatsArgs};
use crate::exit::{CliError, ExitStatus};

/// Where the example inputs live in the repository.
const EXAMPLES: &str = "datasets/examples";

/// An example input shipped in `datasets/examples/`: looked up from the current folder,
/// then from the source checkout the binary was built from.
fn example_input(name: &str) -> anyhow::Result<PathBuf> {
    let candidates = [
        PathBuf::from(EXAMPLES).join(name),
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(EXAMPLES)
            .join(name),
    ];
    candidates
        .iter()
        .find(|p| p.is_dir())
        .cloned()
        .ok_or_else(|| {
            CliError {
                message: format!("the example input {EXAMPLES}/{name} is not here"),
                hint: Some(format!(
                    "run from the repository root, or pass your own input (see `dexjoco-data stats --help`); \
                     `python3 {EXAMPLES}/generate_examples.py` recreates the examples"
                )),
                status: ExitStatus::Failure,
            }
            .into()
        })
}

fn usage(message: String, hint: &str) -> anyhow::Error {
    CliError {
        message,
        hint: Some(hint.into()),
        status: ExitStatus::Usage,
    }
    .into()
}

/// Runs `stats`.
pub fn run(global: &GlobalArgs, args: &StatsArgs) -> anyhow::Result<ExitStatus> {
    if args.language_eval.is_none() && args.success_table.is_none() {
        return Err(usage(
            "nothing to do: say which statistics to make".into(),
            "`dexjoco-data stats --language-eval` or `--success-table` (each on the shipped example input \
             without a path); dataset statistics of stored episodes come with the ingest stage",
        ));
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(usage(
            format!("--alpha {} is not in (0, 1)", args.alpha),
            "for example --alpha 0.01",
        ));
    }
    if !(0.0..=1.0).contains(&args.nmi_weak) {
        return Err(usage(
            format!("--nmi-weak {} is not in [0, 1]", args.nmi_weak),
            "for example --nmi-weak 0.1",
        ));
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("stats"));
    let mut json = serde_json::Map::new();
    let mut summaries = Vec::new();

    if let Some(input) = &args.language_eval {
        let path = match input {
            Some(p) => p.clone(),
            None => example_input("language-eval")?,
        };
        let input = LanguageInput::load(&path)
            .with_context(|| format!("reading the language evaluation {}", path.display()))?;
        if input.example {
            tracing::warn!(
                "{} is a made-up EXAMPLE input: its numbers are not results",
                path.display()
            );
        }
        for w in &input.warnings {
            tracing::warn!("{w}");
        }
        let options = LanguageOptions {
            alpha: args.alpha,
            nmi_weak: args.nmi_weak,
            js_base: match args.js_base {
                JsBaseArg::Two => LogBase::Two,
                JsBaseArg::E => LogBase::E,
            },
        };
        let report = LanguageReport::analyze(&input, options);
        let dir = out.join("language-eval");
        let files = report
            .write(&dir)
            .with_context(|| format!("writing the language evaluation to {}", dir.display()))?;
        tracing::info!("wrote {} files to {}", files.len(), dir.display());
        json.insert("language_eval".into(), serde_json::to_value(&report)?);
        summaries.push(format!(
            "## Language evaluation\n\n{}",
            report.to_markdown()
        ));
    }

    if let Some(input) = &args.success_table {
        let path = match input {
            Some(p) => p.clone(),
            None => example_input("success-table")?,
        };
        let table = SuccessTable::load(&path)
            .with_context(|| format!("reading the evaluation runs under {}", path.display()))?;
        if table.example {
            tracing::warn!(
                "{} is a made-up EXAMPLE input: its numbers are not results",
                path.display()
            );
        }
        for w in &table.warnings {
            tracing::warn!("{w}");
        }
        let dir = out.join("success-table");
        let files = table
            .write(&dir)
            .with_context(|| format!("writing the success table to {}", dir.display()))?;
        tracing::info!("wrote {} files to {}", files.len(), dir.display());
        json.insert("success_table".into(), serde_json::to_value(&table)?);
        let mut md = format!(
            "## Success rates (%) of {} polic{}, mean ± sample std over seeds\n\n",
            table.policies.len(),
            if table.policies.len() == 1 {
                "y"
            } else {
                "ies"
            }
        );
        if table.example {
            md.push_str(
                "> EXAMPLE INPUT (synthetic, made by a script): these numbers are not results.\n\n",
            );
        }
        md.push_str(&table.to_markdown());
        summaries.push(md);
    }

    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::Value::Object(json))?
        );
    } else {
        println!("{}", summaries.join("\n"));
    }
    Ok(ExitStatus::Success)
}
