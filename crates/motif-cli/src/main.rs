//! `motif`: structure-aware 3D content creation from the command line.
//!
//! A thin front end: it parses arguments, calls the library crates, prints results, and maps
//! errors to exit codes (0 success, 1 failure, 2 bad usage or bad input).

/// `eprintln!` for this crate: std's panics when stderr cannot be written (`2>/dev/full`: the
/// retargeted model was written, then a warning took the process down with exit 101). A warning
/// or note that cannot be shown is dropped; the work and its exit status go on. Defined before
/// the modules, so it shadows std's in all of them.
macro_rules! eprintln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// `eprint!` likewise (see `eprintln!`).
#[allow(unused_macros)]
macro_rules! eprint {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stderr(), $($arg)*);
    }};
}

mod cli;
mod commands;
mod output;
mod progress;

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches};

/// Exit quietly, like other Unix tools killed by SIGPIPE (status 141), when stdout is closed by a
/// reader such as `head`: Rust ignores SIGPIPE and `println!` then panics on the broken pipe.
/// Other failures to write stdout exit 1 with an error line.
/// (Restoring the default signal handler would need `unsafe`, which the workspace forbids.)
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let text = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        // The outputs written so far wait for their rename (`motif_core::io::defer_renames`): a
        // reader that stops reading (`| head`) is no failure of the work, so the finished ones
        // are put in place, as they were before renames were deferred; every other way out
        // removes them, as a failed command does.
        if text.contains("Broken pipe") {
            let _ = motif_core::io::commit_deferred();
            std::process::exit(141);
        }
        motif_core::io::discard_deferred();
        // Any other failure to print results (a full disk, `> /dev/full`): an error line and
        // exit 1, not a panic with a backtrace.
        if let Some(reason) = text.strip_prefix("failed printing to stdout: ") {
            eprintln!("error: writing to standard output failed: {reason}");
            std::process::exit(1);
        }
        // A dependency printing to a stderr that cannot be written: nothing can be said.
        if text.starts_with("failed printing to stderr") {
            std::process::exit(1);
        }
        default(info);
    }));
}

/// Ctrl-C (SIGINT), SIGTERM and SIGHUP end the process without unwinding: the writes in progress
/// would leave their hidden temporary files (`.OUT.PID.N.tmp`, a megabyte for a large PLY)
/// beside the outputs. A thread waits for those signals, removes the files, and then dies of the
/// same signal (the default action, re-raised), so a shell sees a death by signal as before and
/// a loop of commands stops at Ctrl-C. Signals the parent ignores (`nohup`, `cmd &` in a script)
/// stay ignored. The files being replaced are untouched; outputs finished but not yet renamed into
/// place (`motif_core::io::defer_renames`) are removed with the rest, so an interrupted command
/// leaves none of its outputs, unless the interrupt comes while they are being renamed at the
/// end: then each file is whole, old or new.
#[cfg(unix)]
fn remove_temporary_files_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let watched: Vec<i32> = [SIGINT, SIGTERM, SIGHUP].into_iter().filter(|&s| !ignored(s)).collect();
    let Ok(mut signals) = signal_hook::iterator::Signals::new(&watched) else { return };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            motif_core::io::remove_temporary_files_and(|| {
                let _ = signal_hook::low_level::emulate_default_handler(signal);
            });
        }
    });
}

#[cfg(not(unix))]
fn remove_temporary_files_on_signals() {}

/// Whether `signal`'s disposition is "ignore" (inherited from the parent), read from the
/// `SigIgn` mask of `/proc/self/status` (Linux; elsewhere no signal counts as ignored).
#[cfg(unix)]
fn ignored(signal: i32) -> bool {
    let Ok(status) = std::fs::read_to_string("/proc/self/status") else { return false };
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigIgn:"))
        .and_then(|mask| u64::from_str_radix(mask.trim(), 16).ok())
        .is_some_and(|mask| (1..=64).contains(&signal) && mask >> (signal - 1) & 1 == 1)
}

/// The arguments, with negative numbers taken as values everywhere: `--tau -1` is then refused
/// by the option's own range check, which says what the range is, rather than read as an
/// unknown flag `-1`.
fn parse_arguments() -> cli::Cli {
    fn negatives(cmd: clap::Command) -> clap::Command {
        cmd.mut_args(|a| if a.get_action().takes_values() { a.allow_negative_numbers(true) } else { a })
            .mut_subcommands(negatives)
    }
    let mut cmd = negatives(cli::Cli::command());
    let matches = cmd.try_get_matches_from_mut(std::env::args_os()).unwrap_or_else(|e| {
        plain_number_error(&e);
        picture_flag_error(&cmd, &e).unwrap_or(e).exit();
    });
    // The subcommand path (`baseline rigid-icp`), so that errors name its own flags.
    let mut path = Vec::new();
    let mut m = &matches;
    while let Some((name, sub)) = m.subcommand() {
        path.push(name.to_string());
        m = sub;
    }
    output::set_command_path(path.clone());
    let parsed = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // A report's file that holds one of the documents Motif reads (`cli::json_report_clash`),
    // refused as clap refuses a value (exit 2), unless --force.
    if !parsed.global.force
        && let Ok(Some(report)) = m.try_get_one::<std::path::PathBuf>("json")
        && report.as_os_str() != "-"
        && let Some(why) = cli::json_report_clash(report)
    {
        let mut sub = &mut cmd;
        for name in &path {
            sub = sub.find_subcommand_mut(name).expect("the parsed subcommand exists");
        }
        let e = clap::Error::raw(
            clap::error::ErrorKind::ValueValidation,
            format!("invalid value '{}' for '--json [<FILE>]': {why}", report.display()),
        );
        e.format(sub).exit();
    }
    parsed
}

/// A count given as `-1` or `1.5` (`--seed -1`, `--dims 2,-2,2`): Rust's own words, "invalid
/// digit found in string", said as what the option takes; exits 2 as clap does.
fn plain_number_error(e: &clap::Error) {
    if e.kind() != clap::error::ErrorKind::ValueValidation {
        return;
    }
    let text = e.to_string();
    let rust = "invalid digit found in string";
    if !text.contains(rust) {
        return;
    }
    let negative = text.contains("invalid value '-");
    let said = if negative {
        "negative, but it takes a whole number (of the range its help gives)"
    } else {
        "not a whole number (it takes one such as 0, 1, 2)"
    };
    eprint!("{}", text.replace(rust, said));
    std::process::exit(2);
}

/// `motif retarget` draws its picture with `--preview`, every other command with `--plot`: an
/// unknown `--plot` (or `--preview`) on a command that has the other gets a tip naming it, and on
/// a command that draws nothing a tip saying so, instead of clap's generic "to pass '--plot' as a
/// value, use '-- --plot'".
fn picture_flag_error(cmd: &clap::Command, e: &clap::Error) -> Option<clap::Error> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if e.kind() != ErrorKind::UnknownArgument {
        return None;
    }
    let Some(ContextValue::String(arg)) = e.get(ContextKind::InvalidArg) else { return None };
    let typed = arg.split('=').next().unwrap_or(arg);
    let other = match typed {
        "--plot" => "preview",
        "--preview" => "plot",
        _ => return None,
    };
    // The subcommand the arguments name (nested: `motif bench detect`).
    let mut path = vec![cmd.get_name().to_string()];
    // (Words that name no subcommand, such as option values and files, are passed over; an
    // argument that is not UTF-8 cannot name one.)
    let mut sub = cmd;
    for a in std::env::args_os().skip(1) {
        let Some(a) = a.to_str().filter(|a| !a.starts_with('-')) else { continue };
        if let Some(s) = sub.find_subcommand(a) {
            path.push(a.to_string());
            sub = s;
        }
    }
    if path.len() < 2 || sub.has_subcommands() {
        return None;
    }
    let name = path.join(" ");
    let tip = if sub.get_arguments().any(|x| x.get_long() == Some(other)) {
        format!("`{name}` draws its picture with '--{other} PNG'")
    } else {
        format!("`{name}` draws no picture")
    };
    let mut sub = sub.clone().bin_name(&name);
    Some(
        sub.error(ErrorKind::UnknownArgument, format!("unexpected argument '{typed}' found\n\n  tip: {tip}")),
    )
}

/// `--threads` beyond this many per core only costs time (thousands of threads take seconds to
/// start and contend for the cores).
const MAX_THREADS_PER_CORE: usize = 8;

fn main() -> ExitCode {
    quiet_on_broken_pipe();
    remove_temporary_files_on_signals();
    let cli = parse_arguments();
    output::set_quiet(cli.global.quiet);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if let Some(threads) = cli.global.threads.filter(|&t| t > MAX_THREADS_PER_CORE * cores) {
        eprintln!(
            "error: --threads {threads}: more than {} ({MAX_THREADS_PER_CORE} per core on this machine's {cores})",
            MAX_THREADS_PER_CORE * cores
        );
        return ExitCode::from(2);
    }
    if let Some(threads) = cli.global.threads {
        // A second initialisation can only fail if something already built the pool; ignore.
        let _ = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build_global();
    }
    // A command's outputs are replaced together when it succeeds, and none when it fails
    // (`motif_core::io::defer_renames`). Not for the commands that read back what they wrote
    // (the benchmarks' scenes, the demo's walk through its files) or keep running (the studio).
    let defer =
        !matches!(cli.command, cli::Command::Bench(_) | cli::Command::Demo(_) | cli::Command::Studio(_));
    if defer {
        motif_core::io::defer_renames();
    }
    let result = commands::run(cli).and_then(|()| {
        if defer {
            motif_core::io::commit_deferred()?;
        }
        Ok(())
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            motif_core::io::discard_deferred();
            eprintln!("error: {}", output::describe(&err));
            ExitCode::from(output::exit_code(&err))
        }
    }
}
