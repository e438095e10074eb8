//! `host-sim`: see `host-sim --help`, and `host_sim::cli` for the implementation.

use std::process::ExitCode;

fn main() -> ExitCode {
    host_sim::cli::install_panic_report();
    host_sim::cli::run(std::env::args_os())
}
