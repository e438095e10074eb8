//! The `demo` command line: its one flag and its usage text.

use std::ffi::OsString;
use std::path::PathBuf;

use super::args::{parse, Flag, Matches, Parsed, UsageError};
use crate::commands::demo::DemoOptions;

/// The usage text of `host-sim demo --help`.
pub const USAGE: &str = "\
host-sim demo: run the library on a built-in sequence and write pictures and a summary.

Usage: host-sim demo [--out DIR]

Renders 60 frames of a seeded synthetic scene (320x240: the camera pans, turns and zooms
while a textured box crosses the view) with exact ground truth, runs each part of the demo on
it and prints a summary. Needs no input file.

Options:
  --out DIR     output directory, created if missing [default: demo-out]
  -h, --help    print this help

Files in DIR:
  summary.txt                   the summary printed on stdout
  tracks/contact_sheet.png      every 5th frame with the KLT tracks' trails
  tracks/trails/NNNNNN.png      every frame with the trails
  tracks/tracks.csv             the tracks, as 'host-sim track' writes them

Exit status: 0 success; 1 an output that cannot be written; 2 bad command line.
";

const FLAGS: &[Flag] = &[Flag::value("--out")];

/// Where the demo writes when `--out` is not given.
pub const DEFAULT_OUT: &str = "demo-out";

/// Parses the words after `demo`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<DemoOptions>, UsageError> {
    match parse(args, FLAGS, 0)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => Ok(Some(options(&matches)?)),
    }
}

fn options(matches: &Matches) -> Result<DemoOptions, UsageError> {
    let out = match matches.value("--out") {
        Some(value) if value.is_empty() => {
            return Err(UsageError::new("--out", "must not be empty"))
        }
        Some(value) => PathBuf::from(value),
        None => PathBuf::from(DEFAULT_OUT),
    };
    Ok(DemoOptions { out })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<DemoOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn the_output_directory_has_a_default() {
        assert_eq!(parsed("").unwrap().unwrap().out, PathBuf::from("demo-out"));
        assert_eq!(parsed("--out x").unwrap().unwrap().out, PathBuf::from("x"));
        assert_eq!(
            parsed("--out=").unwrap_err().to_string(),
            "--out: must not be empty"
        );
        assert!(parsed("extra").is_err());
        assert_eq!(parsed("-h"), Ok(None));
    }
}
