//! `dexjoco-data ingest`: validate MCAP teleop logs and DexJoCo raw folders into the
//! episode store; rejected inputs are quarantined and the exit code says so.

use std::path::Path;

use anyhow::Context;
use dexjoco_ingest::{
    IngestOptions, IngestSummary, Outcome, Reporter, Store, ValidationOptions, discover,
};
use indicatif::ProgressBar;

use crate::cli::{GlobalArgs, IngestArgs};
use crate::exit::{CliError, ExitStatus};

/// Draws the library's progress callbacks as a bar.
pub struct BarReporter(pub ProgressBar);

impl Reporter for BarReporter {
    fn start(&self, total: usize) {
        self.0.set_length(total as u64);
    }

    fn source_done(&self, source: &Path) {
        self.0.set_message(
            source
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
        );
        self.0.inc(1);
    }
}

/// Runs `body` on a rayon pool of `--jobs` threads (all cores by default).
pub fn with_pool<T: Send>(
    global: &GlobalArgs,
    body: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    let mut b = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("ingest-{i}"));
    if let Some(j) = global.jobs {
        b = b.num_threads(j);
    }
    Ok(b.build().context("starting worker threads")?.install(body))
}

/// Runs `ingest`.
pub fn run(global: &GlobalArgs, args: &IngestArgs) -> anyhow::Result<ExitStatus> {
    let store_dir = args
        .store
        .clone()
        .unwrap_or_else(|| global.work_dir.join("ingest"));
    if let Some(t) = args
        .task
        .as_deref()
        .filter(|t| dexjoco_core::task_info(t).is_none())
    {
        let known: Vec<&str> = dexjoco_core::TASKS.iter().map(|t| t.id).collect();
        return Err(CliError {
            message: format!("unknown task '{t}'"),
            hint: Some(format!("known tasks: {}", known.join(", "))),
            status: ExitStatus::Usage,
        }
        .into());
    }
    for input in &args.inputs {
        if std::fs::symlink_metadata(input).is_err() {
            return Err(CliError {
                message: format!("input '{}' does not exist", input.display()),
                hint: Some("give MCAP files or folders holding DexJoCo raw episodes".into()),
                status: ExitStatus::Failure,
            }
            .into());
        }
    }
    let mut store = Store::open(&store_dir)
        .with_context(|| format!("opening the episode store '{}'", store_dir.display()))?;
    let sources = discover(&args.inputs, &store_dir).context("finding inputs")?;
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
    let opts = IngestOptions {
        force: args.force,
        task: args.task.clone(),
        validation: ValidationOptions {
            quat_norm_tolerance: args.quat_tolerance,
            timestep_tolerance: args.timestep_tolerance,
            ..ValidationOptions::default()
        },
    };
    let pb = crate::progress::bar(sources.len() as u64, "ingest", global.quiet);
    let reporter = BarReporter(pb.clone());
    let summary = with_pool(global, || store.ingest(&sources, &opts, &reporter))??;
    pb.finish_and_clear();

    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary, &store_dir);
    }
    if summary.rejected() > 0 {
        eprintln!(
            "{} input(s) rejected: see {} and {}",
            summary.rejected(),
            store_dir.join(dexjoco_ingest::MANIFEST).display(),
            store_dir.join(dexjoco_ingest::QUARANTINE).display()
        );
        Ok(ExitStatus::Partial)
    } else {
        Ok(ExitStatus::Success)
    }
}

fn print_summary(summary: &IngestSummary, store: &Path) {
    println!("| input | id | outcome | where | first problem |\n|---|---|---|---|---|");
    for s in &summary.sources {
        let outcome = match s.outcome {
            Outcome::Landed => "landed",
            Outcome::Replaced => "replaced",
            Outcome::AlreadyPresent => "already stored",
            Outcome::Duplicate => "duplicate",
            Outcome::Quarantined => "QUARANTINED",
        };
        println!(
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
    println!();
    println!(
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
