//! `rkwave report`: the local-vs-global report of docs/design.md §5.

use rkwave::report::local_vs_global;

use super::report_args::ReportArgs;
use super::CliError;

/// Runs `rkwave report`.
pub fn run(args: &ReportArgs) -> Result<(), CliError> {
    let setting = args.setting()?;
    let report = local_vs_global(&setting)?;
    if args.json {
        super::print_json(&report);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}
