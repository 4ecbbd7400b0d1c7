//! The `rkwave` command line (see `rkwave --help`).

mod cli;

use clap::Parser;

fn main() {
    let parsed = cli::Cli::parse();
    if let Err(e) = cli::run(parsed) {
        eprintln!("error: {e}");
        std::process::exit(e.exit_code());
    }
}
