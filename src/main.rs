//! The `rkwave` command line (see `rkwave --help`).

mod cli;

use clap::Parser;

fn main() {
    // A closed stdout (`rkwave ... | head`) ends the program quietly, as SIGPIPE would,
    // instead of a panic report; every other panic keeps the default report.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.contains("failed printing to stdout") {
            std::process::exit(141);
        }
        default_hook(info);
    }));
    let parsed = cli::Cli::parse();
    if let Err(e) = cli::run(parsed) {
        eprintln!("error: {}", cli::hints::in_flags(&e.to_string()));
        std::process::exit(e.exit_code());
    }
}
