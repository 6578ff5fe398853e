//! `dexjoco-data eval`: a trained policy, served by openpi's websocket policy server,
//! evaluated in the task environments; the output is laid out as the reference client
//! lays it out, so `stats --success-table` and `--language-eval` read it.

use dexjoco_eval::{EvalError, EvalSummary};

use crate::cli::{EvalArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::settings::EvalSettings;

/// Runs `eval`.
pub fn run(global: &GlobalArgs, args: EvalArgs) -> anyhow::Result<ExitStatus> {
    let EvalSettings { config, executor } = EvalSettings::resolve(args, global)?;
    let executor = match executor {
        Some(w) => dexjoco_eval::Executor::Processes(dexjoco_eval::WorkerProcesses {
            program: std::env::current_exe()?,
            args: crate::commands::augment::worker_args(global, "eval-worker"),
            ..w
        }),
        None => dexjoco_eval::Executor::InProcess,
    };
    let bar = crate::progress::Bar::new("eval", global.quiet);
    let result = dexjoco_eval::evaluate(&config, &executor, &bar);
    bar.finish();
    let summary = result.map_err(cli_error)?;
    report(&summary, &config.task.task);
    Ok(ExitStatus::Success)
}

fn report(s: &EvalSummary, task: &str) {
    let n = s.episodes.len();
    let ok = s.successes();
    errln!(
        "{task}: {ok}/{n} episodes successful ({:.1}%), {} evaluated now, in {}",
        100.0 * ok as f64 / n.max(1) as f64,
        s.evaluated_now,
        s.out.display()
    );
    if let Some(m) = &s.marker {
        outln!("{}", m.display());
    }
}

/// An evaluation error with its exit status and hint.
fn cli_error(e: EvalError) -> anyhow::Error {
    let status = match e {
        EvalError::Usage(_) | EvalError::Config { .. } => ExitStatus::Usage,
        _ => ExitStatus::Failure,
    };
    let hint = e.hint().map(str::to_owned);
    let message = dexjoco_eval::one_line(&e);
    CliError {
        message: match hint {
            Some(h) => message
                .trim_end_matches(&format!(" (hint: {h})"))
                .to_owned(),
            None => message,
        },
        hint: e.hint().map(str::to_owned),
        status,
    }
    .into()
}

/// Runs `eval-worker` (started by `eval -j N`).
pub fn run_worker() -> anyhow::Result<ExitStatus> {
    let (input, output) = crate::commands::augment::worker_channel()?;
    dexjoco_eval::serve_worker(input, output).map_err(cli_error)?;
    Ok(ExitStatus::Success)
}
