//! `dexjoco-data ingest`: validate MCAP teleop logs and DexJoCo raw folders into the
//! episode store; rejected inputs are quarantined and the exit code says so.

use std::path::Path;

use anyhow::Context;
use dexjoco_ingest::{IngestSummary, Outcome, Store};

use crate::cli::{GlobalArgs, IngestArgs};
use crate::exit::{CliError, ExitStatus};
use crate::progress::Bar;
use crate::settings::{IngestSettings, must_exist};

/// Runs `ingest`.
pub fn run(global: &GlobalArgs, args: IngestArgs) -> anyhow::Result<ExitStatus> {
    let IngestSettings {
        inputs,
        store: store_dir,
        options,
        json,
    } = IngestSettings::resolve(args, global)?;
    for input in &inputs {
        must_exist(
            input,
            "give MCAP files or folders holding DexJoCo raw episodes",
        )?;
    }
    let mut store = Store::open(&store_dir)
        .with_context(|| format!("opening the episode store '{}'", store_dir.display()))?;
    let sources = dexjoco_formats::discover(&inputs, Some(&store_dir)).context("finding inputs")?;
    if sources.is_empty() {
        return Err(CliError {
            message: "no inputs found".into(),
            hint: Some(
                "inputs are *.mcap files and folders holding replay.zarr (searched recursively)"
                    .into(),
            ),
            status: ExitStatus::Failure,
        }
        .into());
    }
    tracing::info!(
        inputs = sources.len(),
        store = %store_dir.display(),
        "ingesting"
    );
    let bar = Bar::new("ingest", global.quiet);
    let summary = store.ingest(&sources, &options, &bar)?;
    bar.finish();

    if json {
        outln!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary, &store_dir);
    }
    if summary.rejected() > 0 {
        errln!(
            "{} input(s) rejected: see {} and {}",
            summary.rejected(),
            store_dir.join(dexjoco_formats::MANIFEST).display(),
            store_dir.join(dexjoco_ingest::QUARANTINE).display()
        );
        Ok(ExitStatus::Partial)
    } else {
        Ok(ExitStatus::Success)
    }
}

fn print_summary(summary: &IngestSummary, store: &Path) {
    outln!("| input | id | outcome | where | first problem |\n|---|---|---|---|---|");
    for s in &summary.sources {
        let outcome = match s.outcome {
            Outcome::Landed => "landed",
            Outcome::Replaced => "replaced",
            Outcome::AlreadyPresent => "already stored",
            Outcome::Duplicate => "duplicate",
            Outcome::Quarantined => "QUARANTINED",
            Outcome::RecheckFailed => "RE-CHECK FAILED (kept as stored)",
        };
        outln!(
            "| {} | {} | {} | {} | {} |",
            s.source.display(),
            s.id,
            outcome,
            s.path.display(),
            s.problems
                .first()
                .map(ToString::to_string)
                .unwrap_or_default()
        );
    }
    outln!();
    outln!(
        "{} landed, {} replaced, {} already stored, {} duplicate, {} rejected; {:.1} MB read in {:.2} s; store: {}",
        summary.count(Outcome::Landed),
        summary.count(Outcome::Replaced),
        summary.count(Outcome::AlreadyPresent),
        summary.count(Outcome::Duplicate),
        summary.rejected(),
        summary.bytes_read as f64 / 1e6,
        summary.seconds,
        store.display()
    );
}
