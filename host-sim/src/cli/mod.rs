//! The `host-sim` command line: dispatch to the commands, usage texts, and the error reporting
//! contract (one line on stderr, exit status 1 for bad input, 2 for a bad command line).

pub mod args;
pub mod demo;
pub mod dense;
pub mod egomotion;
pub mod flow;
pub mod motion;
pub mod stabilize;
pub mod synth;
pub mod synth_sequence;
pub mod track;

use std::ffi::OsString;
use std::fmt::Display;
use std::io::Write;
use std::process::ExitCode;

use args::UsageError;

use crate::commands::{self, CommandError};

/// Exit status for unreadable or malformed input, and outputs that cannot be written.
pub const EXIT_INPUT: u8 = 1;
/// Exit status for a bad command line.
pub const EXIT_USAGE: u8 = 2;

/// The usage text of `host-sim --help`.
pub const USAGE: &str = "\
host-sim: the Kestrel host simulator. Runs the library on recorded frames and writes CSV.

Usage: host-sim <COMMAND> [options]

Commands:
  demo            run the library on a built-in sequence and write pictures (start here)
  flow            track points from one frame to the next (sparse pyramidal Lucas-Kanade)
  track           follow corners through a sequence with the KLT tracker (tracks.csv, trail pictures)
  dense           flow at every node of a grid, as CSV, a Middlebury .flo field and picture
  motion          boxes around what moves in a sequence, the camera's own motion removed
  egomotion       camera motion between consecutive frames, and OPTICAL_FLOW_RAD for autopilots
  stabilize       write camera-motion-compensated frames (video stabilization)
  synth           write seeded synthetic frame pairs with exact ground truth
  synth-sequence  write a seeded synthetic flight with exact homographies and gyro

Options:
  -h, --help       print this help; 'host-sim <COMMAND> --help' describes a command
  -V, --version    print the version

Errors are one line on stderr, naming the file, frame or flag: 'host-sim: <what>: <problem>'.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

/// Why `host-sim` stopped early.
#[derive(Debug)]
enum Failure {
    Usage(UsageError),
    Command(CommandError),
}

/// What the command line asked for, once parsed.
#[derive(Debug)]
enum Request {
    /// Print a usage text to stdout.
    Print(&'static str),
    /// Print the version to stdout.
    Version,
    Demo(commands::demo::DemoOptions),
    Flow(commands::flow::FlowOptions),
    Track(commands::track::TrackOptions),
    Dense(commands::dense::DenseOptions),
    Motion(commands::motion::MotionOptions),
    Egomotion(commands::egomotion::EgomotionOptions),
    Stabilize(commands::stabilize::StabilizeOptions),
    Synth(commands::synth::SynthOptions),
    SynthSequence(commands::synth_sequence::SynthSequenceOptions),
}

/// Runs `host-sim` with `args` (the program name first, as from [`std::env::args_os`]) and
/// returns its exit status.
pub fn run(args: impl IntoIterator<Item = OsString>) -> ExitCode {
    let words: Vec<OsString> = args.into_iter().skip(1).collect();
    let outcome = request(&words)
        .map_err(Failure::Usage)
        .and_then(|request| execute(request).map_err(Failure::Command));
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(error)) => {
            report(&error);
            ExitCode::from(EXIT_USAGE)
        }
        Err(Failure::Command(error)) => {
            report(&error);
            ExitCode::from(EXIT_INPUT)
        }
    }
}

fn request(words: &[OsString]) -> Result<Request, UsageError> {
    let Some((command, rest)) = words.split_first() else {
        return Err(UsageError::new("missing command", "try 'host-sim --help'"));
    };
    match command.to_string_lossy().as_ref() {
        "-h" | "--help" => Ok(Request::Print(USAGE)),
        "-V" | "--version" => Ok(Request::Version),
        "demo" => Ok(match demo::parse_options(rest)? {
            Some(options) => Request::Demo(options),
            None => Request::Print(demo::USAGE),
        }),
        "flow" => Ok(match flow::parse_options(rest)? {
            Some(options) => Request::Flow(options),
            None => Request::Print(flow::USAGE),
        }),
        "track" => Ok(match track::parse_options(rest)? {
            Some(options) => Request::Track(options),
            None => Request::Print(track::USAGE),
        }),
        "dense" => Ok(match dense::parse_options(rest)? {
            Some(options) => Request::Dense(options),
            None => Request::Print(dense::USAGE),
        }),
        "motion" => Ok(match motion::parse_options(rest)? {
            Some(options) => Request::Motion(options),
            None => Request::Print(motion::USAGE),
        }),
        "egomotion" => Ok(match egomotion::parse_options(rest)? {
            Some(options) => Request::Egomotion(options),
            None => Request::Print(egomotion::USAGE),
        }),
        "stabilize" => Ok(match stabilize::parse_options(rest)? {
            Some(options) => Request::Stabilize(options),
            None => Request::Print(stabilize::USAGE),
        }),
        "synth" => Ok(match synth::parse_options(rest)? {
            Some(options) => Request::Synth(options),
            None => Request::Print(synth::USAGE),
        }),
        "synth-sequence" => Ok(match synth_sequence::parse_options(rest)? {
            Some(options) => Request::SynthSequence(options),
            None => Request::Print(synth_sequence::USAGE),
        }),
        other if other.starts_with('-') => Err(UsageError::new(
            other,
            "unknown flag; a command comes first (try 'host-sim --help')",
        )),
        other => Err(UsageError::new(
            format!("'{other}'"),
            "unknown command (try 'host-sim --help')",
        )),
    }
}

fn execute(request: Request) -> Result<(), CommandError> {
    match request {
        Request::Print(text) => {
            print_stdout(text);
            Ok(())
        }
        Request::Version => {
            print_stdout(&format!("host-sim {}\n", env!("CARGO_PKG_VERSION")));
            Ok(())
        }
        Request::Demo(options) => commands::demo::run(&options),
        Request::Flow(options) => commands::flow::run(&options),
        Request::Track(options) => commands::track::run(&options),
        Request::Dense(options) => commands::dense::run(&options),
        Request::Motion(options) => commands::motion::run(&options),
        Request::Egomotion(options) => commands::egomotion::run(&options),
        Request::Stabilize(options) => commands::stabilize::run(&options),
        Request::Synth(options) => commands::synth::run(&options),
        Request::SynthSequence(options) => commands::synth_sequence::run(&options),
    }
}

/// Writes to stdout, ignoring a closed pipe (`host-sim --help | head` is not an error).
fn print_stdout(text: &str) {
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

/// Prints `error` as the single stderr line the contract promises.
fn report(error: &dyn Display) {
    eprintln!("host-sim: {}", one_line(&error.to_string()));
}

/// `text` with line breaks (which some decoder messages contain) folded into spaces.
pub fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Replaces the panic message and backtrace with one line on stderr: a panic is a bug, but the
/// contract still promises scripts a single line.
pub fn install_panic_report() {
    std::panic::set_hook(Box::new(|info| {
        let location = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        eprintln!(
            "host-sim: internal error{location}: {} (please report this)",
            one_line(&message)
        );
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request_of(line: &str) -> Result<Request, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        request(&words)
    }

    #[test]
    fn help_and_version() {
        assert!(matches!(request_of("--help"), Ok(Request::Print(USAGE))));
        assert!(matches!(request_of("-h"), Ok(Request::Print(USAGE))));
        assert!(matches!(
            request_of("flow -h"),
            Ok(Request::Print(flow::USAGE))
        ));
        assert!(matches!(request_of("--version"), Ok(Request::Version)));
    }

    #[test]
    fn unknown_commands_and_missing_command() {
        let message = |line| request_of(line).unwrap_err().to_string();
        assert_eq!(
            message("fly"),
            "'fly': unknown command (try 'host-sim --help')"
        );
        assert_eq!(message(""), "missing command: try 'host-sim --help'");
        assert!(message("--window 3").starts_with("--window: unknown flag"));
    }

    #[test]
    fn messages_are_folded_to_one_line() {
        assert_eq!(one_line("bad\nthing  here\r\n"), "bad thing here");
    }
}
