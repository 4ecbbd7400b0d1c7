//! The `rkwave` command line (see `rkwave --help`).

mod cli;

use clap::Parser;

fn main() {
    retain_freed_memory();
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

/// Keeps freed memory in the heap for reuse instead of returning it to the system (glibc):
/// blocks up to 32 MB come from the heap instead of a fresh `mmap` each, and the heap's top is
/// never trimmed. The PCG iterations allocate and free vectors of 8-112 MB (a channel's
/// coefficients, the samples' values); from fresh mappings each one paid its page faults
/// again. The price is a higher peak resident size (freed memory is held until the process
/// ends); both figures: docs/measurements/plan-speed.md, "Adaptive image sampling: speed and
/// memory".
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn retain_freed_memory() {
    // SAFETY: `mallopt` only sets the allocator's parameters; it runs before any other thread
    // exists and its failure (a 0 return) leaves glibc's defaults, which are still correct.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Elsewhere the system allocator keeps its defaults.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn retain_freed_memory() {}
