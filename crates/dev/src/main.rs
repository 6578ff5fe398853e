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
pub(crate) const USER: &str = "user";

fn main() -> ExitCode {
    if std::env::args_os().nth(1).is_some_and(|a| a == USER) {
        let rest = std::env::args_os().skip(2);
        return dexjoco_cli::main_from(std::iter::once("dexjoco-data".into()).chain(rest));
    }
    let cli = DevCli::parse();
    dexjoco_cli::start(&cli.global);
    let result = match &cli.command {
        DevCommand::Bench(DevBenchCommand::Convert(args)) => bench_convert::run(&cli.global, args),
        DevCommand::Bench(DevBenchCommand::Generate(args)) => {
            bench_generate::run(&cli.global, args)
        }
        DevCommand::Bench(DevBenchCommand::Fidelity(args)) => {
            bench_fidelity::run(&cli.global, args)
        }
    };
    dexjoco_cli::exit_code(result)
}
