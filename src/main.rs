//! The `rkwave` command line (see `rkwave --help`).

mod cli;
mod heap;

use clap::Parser;

/// glibc's allocator, its heap on transparent huge pages ([`heap`]).
#[global_allocator]
static HEAP: heap::Heap = heap::Heap;

fn main() {
    heap::configure();
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
    // The whole command with flags as the spelling of every typed fix: a message the library
    // formats while the command runs (a refusal's advice, a note) names flags, not fields.
    if let Err(e) = cli::hints::in_flags(|| cli::run(parsed)) {
        eprintln!("error: {}", cli::hints::in_flags(|| e.to_string()));
        std::process::exit(e.exit_code());
    }
}
