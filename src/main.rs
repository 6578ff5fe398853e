//! The `dexjoco-data` binary (the command line lives in the `dexjoco_cli` library).

fn main() -> std::process::ExitCode {
    dexjoco_cli::main()
}
