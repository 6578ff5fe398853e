//! `dexjoco-dev`: the developer tools of dexjoco-data, apart from the user binary
//! (`bench convert`, `bench generate`, `bench fidelity`; see docs/contributing.md).

#[macro_use]
extern crate dexjoco_cli;

mod bench_convert;
mod bench_fidelity;
mod bench_generate;
mod cli;

use std::process::ExitCode;

use clap::Parser;

use crate::cli::{DevBenchCommand, DevCli, DevCommand};

/// The hidden first argument that runs the user binary's command line in this process
/// (`dexjoco-dev user convert ...`): what `bench convert` times as a child process.
const USER: &str = "user";

fn main() -> ExitCode {
    if std::env::args_os().nth(1).is_some_and(|a| a == USER) {
        let rest = std::env::args_os().skip(2);
        return dexjoco_cli::main_from(std::iter::once("dexjoco-data".into()).chain(rest));
    }
    let cli = DevCli::parse();
    dexjoco_cli::init_logging(cli.global.verbose, cli.global.quiet);
    dexjoco_sim::route_mujoco_warnings();
    dexjoco_cli::init_worker_pool(cli.global.jobs);
    let result = match &cli.command {
        DevCommand::Bench(DevBenchCommand::Convert(args)) => bench_convert::run(&cli.global, args),
        DevCommand::Bench(DevBenchCommand::Generate(args)) => {
            bench_generate::run(&cli.global, args)
        }
        DevCommand::Bench(DevBenchCommand::Fidelity(args)) => {
            bench_fidelity::run(&cli.global, args)
        }
    };
    match result {
        Ok(status) => status.into(),
        Err(err) => dexjoco_cli::report(&err).into(),
    }
}

/// This program and the first argument that runs the user binary's command line in it.
fn user_binary() -> anyhow::Result<(std::path::PathBuf, &'static str)> {
    Ok((std::env::current_exe()?, USER))
}
