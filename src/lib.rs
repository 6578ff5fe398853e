//! The `dexjoco-data` command line as a library: a thin layer that turns arguments into
//! settings, runs a stage from the library crates, and reports errors with documented exit
//! codes. The `dexjoco-data` binary is [`main`]; the developer binary (`crates/dev`,
//! `dexjoco-dev`) reuses the global options, settings, progress bars and error reporting.

#[macro_use]
pub mod out;
pub mod cli;
pub mod commands;
pub mod exit;
pub mod locate;
pub mod progress;
pub mod settings;

use std::process::ExitCode;

use clap::Parser;

use crate::cli::{Cli, Command};
use crate::exit::{CliError, ExitStatus};

/// The `dexjoco-data` binary: parses the command line and runs the subcommand.
pub fn main() -> ExitCode {
    main_from(std::env::args_os())
}

/// [`main`] on the given command line (its first item is the program name).
pub fn main_from<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = Cli::parse_from(args);
    start(&cli.global);
    let result = match cli.command {
        Command::Doctor(args) => {
            commands::doctor::run(settings::DoctorSettings::resolve(&args, &cli.global))
        }
        Command::Render(args) => settings::RenderCommandSettings::resolve(&args, &cli.global)
            .and_then(|s| commands::render::run(&s)),
        Command::Bench(cmd) => commands::bench::run(&cli.global, &cmd),
        Command::Ingest(args) => commands::ingest::run(&cli.global, args),
        Command::Export(args) => commands::export::run(&cli.global, args),
        Command::Augment(args) => commands::augment::run(&cli.global, args),
        Command::AugmentWorker(_) => commands::augment::run_worker(),
        Command::Cameras(args) => commands::cameras::run(&cli.global, args),
        Command::Convert(args) => commands::convert::run(&cli.global, args),
        Command::Stats(args) => commands::stats::run(&cli.global, args),
        Command::Eval(args) => commands::eval::run(&cli.global, args),
        Command::EvalWorker(_) => commands::eval::run_worker(),
        Command::Scripted(args) => settings::ScriptedSettings::resolve(&args, &cli.global)
            .and_then(commands::scripted::run),
        Command::Generate(args) => commands::generate::run(&cli.global, args),
        Command::Dataset(cmd) => commands::dataset::run(&cli.global, cmd),
    };
    exit_code(result)
}

/// What every command of either binary does first: logging at the level asked for,
/// MuJoCo's warnings into it, and the worker pool of `-j` threads.
pub fn start(global: &cli::GlobalArgs) {
    init_logging(global.verbose, global.quiet);
    dexjoco_sim::route_mujoco_warnings();
    init_worker_pool(global.jobs);
}

/// A command's result as the process's exit code, its error reported first.
pub fn exit_code(result: anyhow::Result<ExitStatus>) -> ExitCode {
    match result {
        Ok(status) => status.into(),
        Err(err) => report(&err).into(),
    }
}

/// The one worker pool of the process (rayon's global pool): `--jobs` threads (default:
/// all cores) named `worker-N`. Every stage's parallel work runs on it; results never
/// depend on its size.
fn init_worker_pool(jobs: Option<usize>) {
    let mut b = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("worker-{i}"));
    if let Some(j) = jobs {
        b = b.num_threads(j);
    }
    if let Err(e) = b.build_global() {
        tracing::warn!("cannot start the worker pool: {e}");
    }
}

/// Prints an error as `error:` / `Caused by:` / `hint:` and picks the exit status.
fn report(err: &anyhow::Error) -> ExitStatus {
    let cli_error = err.chain().find_map(|e| e.downcast_ref::<CliError>());
    errln!("error: {err}");
    let causes: Vec<String> = exit::messages(err).into_iter().skip(1).collect();
    if !causes.is_empty() {
        errln!("Caused by:");
        for c in causes {
            errln!("  {c}");
        }
    }
    if let Some(hint) = cli_error.and_then(|e| e.hint.as_deref()) {
        errln!("hint: {hint}");
    } else if exit::is_locked(err) {
        errln!("hint: another run is writing this folder: wait for it to end, or write elsewhere");
    }
    cli_error.map_or(ExitStatus::Failure, |e| e.status)
}

/// Logs to stderr at the level `-v`/`-q` ask for (`DEXJOCO_LOG` overrides it).
fn init_logging(verbose: u8, quiet: bool) {
    use tracing_subscriber::EnvFilter;
    let default = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "info",
        (false, 1) => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_env("DEXJOCO_LOG").unwrap_or_else(|_| EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(verbose > 0)
        .without_time()
        .init();
}
