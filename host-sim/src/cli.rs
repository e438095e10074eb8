//! The `host-sim` command line: clap's parser over the commands' own flags, and the error
//! reporting contract (one line on stderr, exit status 1 for bad input, 2 for a bad command
//! line). Each command's flags, usage and run live in its module under [`crate::commands`].

use std::ffi::OsString;
use std::fmt::Display;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use crate::commands::{self, CommandError};

/// Exit status for unreadable or malformed input, and outputs that cannot be written.
pub const EXIT_INPUT: u8 = 1;
/// Exit status for a bad command line.
pub const EXIT_USAGE: u8 = 2;

/// The layout of every usage text: what the command does, how to call it, its flags, and the
/// files it writes.
pub const TEMPLATE: &str = "{before-help}{usage-heading} {usage}\n\n{all-args}{after-help}";

#[derive(Debug, Parser)]
#[command(
    name = "host-sim",
    version,
    about = "host-sim: the Kestrel host simulator. Runs the library on recorded frames and writes CSV.",
    help_template = "{about}\n\n{usage-heading} {usage}\n\n{all-args}{after-help}",
    subcommand_required = true,
    disable_help_subcommand = true,
    term_width = 100,
    after_help = concat!(
        "'host-sim <COMMAND> --help' describes a command.\n\n",
        "Errors are one line on stderr, naming the file, frame or flag: 'host-sim: <what>: <problem>'.\n\n",
        "Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;\n",
        "2 bad command line."
    )
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
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

/// Why `host-sim` stopped early.
#[derive(Debug)]
enum Failure {
    /// A bad command line, already worded as one line.
    Usage(String),
    Command(CommandError),
}

impl From<CommandError> for Failure {
    fn from(error: CommandError) -> Self {
        match error {
            CommandError::Usage(line) => Failure::Usage(line),
            error => Failure::Command(error),
        }
    }
}

/// Runs `host-sim` with `args` (the program name first, as from [`std::env::args_os`]) and
/// returns its exit status.
pub fn run(args: impl IntoIterator<Item = OsString>) -> ExitCode {
    let outcome = parse(args.into_iter().collect()).and_then(|parsed| match parsed {
        Some(command) => execute(command).map_err(Failure::from),
        None => Ok(()),
    });
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(line)) => {
            report(&line);
            ExitCode::from(EXIT_USAGE)
        }
        Err(Failure::Command(error)) => {
            report(&error);
            ExitCode::from(EXIT_INPUT)
        }
    }
}

/// The command asked for; `None` when help or the version was printed.
fn parse(mut words: Vec<OsString>) -> Result<Option<Command>, Failure> {
    // `-h` anywhere after the command asks for its help, whatever else is on the line (clap
    // would check the other flags first); both spellings print the same help.
    if words.iter().skip(1).any(|w| w == "-h" || w == "--help") {
        let command = words
            .get(1)
            .filter(|w| *w != "-h" && *w != "--help")
            .cloned();
        words.truncate(1);
        words.extend(command);
        words.push("-h".into());
    }
    let mut cli = Cli::command();
    let names: Vec<String> = cli.get_subcommands().map(|c| c.get_name().into()).collect();
    for name in names {
        // Negative values (`--bias -20`, `--epsilon -0.5`) are values, not flags: their range
        // check then names them.
        cli = cli.mut_subcommand(name, |c| {
            c.mut_args(|a| match a.get_action().takes_values() {
                true => a.allow_negative_numbers(true),
                false => a,
            })
        });
    }
    let matches = match cli.try_get_matches_from(words) {
        Ok(matches) => matches,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            let text = e.render().to_string();
            print_stdout(&format!("{}\n", text.trim_end()));
            return Ok(None);
        }
        Err(e) => return Err(Failure::Usage(usage_line(&e))),
    };
    let cli = Cli::from_arg_matches(&matches).map_err(|e| Failure::Usage(usage_line(&e)))?;
    Ok(Some(cli.command))
}

/// A clap error as `subject: problem`, e.g. `--window: must be an odd number from 3 to 63
/// (got 8)`: the flag, argument or command at fault first, as every host-sim error does.
fn usage_line(error: &clap::Error) -> String {
    let context = |kind| match error.get(kind) {
        Some(ContextValue::String(s)) => s.clone(),
        Some(ContextValue::Strings(s)) => s.join(", "),
        Some(other) => other.to_string(),
        None => String::new(),
    };
    // "--window <N>" is named "--window", "<INPUT>" "INPUT".
    let arg = context(ContextKind::InvalidArg);
    let flag = arg.split([' ', '=']).next().unwrap_or_default();
    let flag = flag.trim_matches(['<', '>']);
    let value = context(ContextKind::InvalidValue);
    match error.kind() {
        ErrorKind::ValueValidation => {
            let problem = std::error::Error::source(error).map(|s| s.to_string());
            format!("{flag}: {}", problem.unwrap_or_default())
        }
        ErrorKind::InvalidValue if value.is_empty() => format!("{flag}: needs a value"),
        ErrorKind::UnknownArgument if arg.starts_with('-') => format!("{arg}: unknown flag"),
        ErrorKind::UnknownArgument => {
            format!("'{arg}': unexpected argument (flags start with --)")
        }
        ErrorKind::ArgumentConflict => format!("{flag}: given more than once"),
        ErrorKind::TooManyValues => format!("{flag}: takes no value"),
        ErrorKind::MissingRequiredArgument => format!("{flag}: is required"),
        ErrorKind::InvalidSubcommand => {
            let command = context(ContextKind::InvalidSubcommand);
            format!("'{command}': unknown command (try 'host-sim --help')")
        }
        ErrorKind::MissingSubcommand | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            "missing command: try 'host-sim --help'".into()
        }
        _ => {
            let text = error.render().to_string();
            let first = text.lines().next().unwrap_or_default();
            first.trim_start_matches("error: ").to_owned()
        }
    }
}

fn execute(command: Command) -> Result<(), CommandError> {
    match command {
        Command::Demo(options) => commands::demo::run(&options),
        Command::Flow(options) => commands::flow::run(&options),
        Command::Track(options) => commands::track::run(&options),
        Command::Dense(options) => commands::dense::run(&options),
        Command::Motion(options) => commands::motion::run(&options),
        Command::Egomotion(options) => commands::egomotion::run(&options),
        Command::Stabilize(options) => commands::stabilize::run(&options),
        Command::Synth(options) => commands::synth::run(&options),
        Command::SynthSequence(options) => commands::synth_sequence::run(&options),
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

/// Value parsers: each checks a flag's value and words the problem as the rest of
/// `--flag: ...`, with the value given.
pub mod values {
    use super::PathBuf;

    /// A whole number that `accepts` takes; `says` words the rule ("must be at least 1").
    pub fn whole(text: &str, accepts: impl Fn(i64) -> bool, says: &str) -> Result<i64, String> {
        let value: i64 = text
            .trim()
            .parse()
            .map_err(|_| format!("expected a whole number (got \"{text}\")"))?;
        check(value, accepts(value), says)
    }

    /// A decimal number that `accepts` takes.
    pub fn number(text: &str, accepts: impl Fn(f64) -> bool, says: &str) -> Result<f64, String> {
        let value: f64 = text
            .trim()
            .parse()
            .map_err(|_| format!("expected a number (got \"{text}\")"))?;
        check(value, accepts(value), says)
    }

    fn check<T: std::fmt::Display>(value: T, accepted: bool, says: &str) -> Result<T, String> {
        match accepted {
            true => Ok(value),
            false => Err(format!("{says} (got {value})")),
        }
    }

    /// One of the named `choices`: "must be a, b or c (got x)" otherwise.
    ///
    /// ```
    /// use host_sim::cli::values::choice;
    /// assert_eq!(choice("b", &[("a", 0), ("b", 1)]), Ok(1));
    /// let e = choice("d", &[("a", 0), ("b", 1), ("c", 2)]).unwrap_err();
    /// assert_eq!(e, "must be a, b or c (got d)");
    /// ```
    pub fn choice<T: Copy>(text: &str, choices: &[(&str, T)]) -> Result<T, String> {
        if let Some(&(_, value)) = choices.iter().find(|(name, _)| *name == text) {
            return Ok(value);
        }
        let names: Vec<&str> = choices.iter().map(|(name, _)| *name).collect();
        let listed = match names.split_last() {
            Some((last, [])) => (*last).to_string(),
            Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
            None => String::new(),
        };
        Err(format!("must be {listed} (got {text})"))
    }

    /// A path, which must not be empty.
    pub fn path(text: &str) -> Result<PathBuf, String> {
        match text.is_empty() {
            true => Err("must not be empty".into()),
            false => Ok(PathBuf::from(text)),
        }
    }

    /// An LK window side for the commands that match OpenCV's LK flags.
    pub fn window(text: &str) -> Result<usize, String> {
        let odd = |n: i64| (3..=63).contains(&n) && n % 2 == 1;
        whole(text, odd, "must be odd and between 3 and 63").map(|n| n as usize)
    }

    /// A coarsest pyramid level.
    pub fn levels(text: &str) -> Result<usize, String> {
        let range = |n| (0..=7).contains(&n);
        whole(text, range, "must be between 0 and 7").map(|n| n as usize)
    }

    /// A repeat count.
    pub fn repeat(text: &str) -> Result<usize, String> {
        whole(text, |n| n >= 1, "must be at least 1").map(|n| n as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(text: &str) -> String {
        let words = std::iter::once("host-sim").chain(text.split_whitespace());
        match parse(words.map(OsString::from).collect()) {
            Err(Failure::Usage(line)) => line,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn unknown_commands_and_missing_command() {
        assert_eq!(
            line("fly"),
            "'fly': unknown command (try 'host-sim --help')"
        );
        assert_eq!(line(""), "missing command: try 'host-sim --help'");
        assert!(line("--window 3").starts_with("--window: unknown flag"));
    }

    #[test]
    fn flag_errors_name_the_flag() {
        let track = "track clip.y4m --out t.csv";
        assert_eq!(
            line(&format!("{track} --max-tracks 0")),
            "--max-tracks: must be between 1 and 1000 (got 0)"
        );
        assert_eq!(line("track clip.y4m"), "--out: is required");
        assert_eq!(line("track --out t.csv"), "INPUT: is required");
        assert!(line("track a b --out t.csv").starts_with("'b': unexpected argument"));
        assert_eq!(
            line(&format!("{track} --window")),
            "--window: needs a value"
        );
        assert_eq!(
            line(&format!("{track} --window 9 --window 7")),
            "--window: given more than once"
        );
        let flow = "flow --prev a --next b --points p --out o";
        assert_eq!(
            line(&format!("{flow} --reference=1")),
            "--reference: takes no value"
        );
    }

    #[test]
    fn help_is_not_an_error() {
        let words = ["host-sim", "track", "--max-tracks", "0", "-h"];
        assert!(matches!(
            parse(words.map(OsString::from).to_vec()),
            Ok(None)
        ));
    }

    #[test]
    fn messages_are_folded_to_one_line() {
        assert_eq!(one_line("bad\nthing  here\r\n"), "bad thing here");
    }
}
