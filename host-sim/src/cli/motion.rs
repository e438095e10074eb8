//! The `motion` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use kestrel::dense::mask::Structure;
use kestrel::dense::motion::MotionParams;
use kestrel::dense::regions::BoxRules;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use super::dense::dense_params;
use crate::commands::motion::MotionOptions;
use crate::dense::MotionSettings;

/// The usage text of `host-sim motion --help`.
pub const USAGE: &str = "\
host-sim motion: moving objects in a sequence. Between each frame and the one before it: the
library's grid flow, the camera's motion fitted to it and removed (a still camera needs no
flag: its motion fits to nearly zero), the nodes that still move, their connected regions,
and a box around each.

Usage: host-sim motion INPUT --out boxes.csv [options]

INPUT is a directory of frames (PNG, JPEG, PGM or BMP, in file-name order), a .y4m file, or -
for y4m on standard input (ffmpeg -i clip.mp4 -f yuv4mpegpipe - | host-sim motion - ...).

Files:
  --out boxes.csv   one row per box (see below)
  --viz DIR         one PNG per frame from the second on, frame_NNNNNN.png: the frame with
                    the moving grid cells tinted red and the boxes outlined in green
  --stats S.json    write {\"frames\": n, \"median_frame_seconds\": t}: the library's time per
                    frame (pyramid, grid flow, camera motion, mask, boxes), decoding excluded

Options:
  --cell N          grid spacing in px, 1 to the frame's smaller side [default: 8]
  --window N        LK window side in px, odd, 3 to 63 [default: 9]
  --levels L        coarsest pyramid level, 0 to 7 [default: 3]
  --threshold PX    a node moves when its flow differs from the camera's by more than PX,
                    finite and > 0 [default: 0.8]
  --min-nodes N     smallest region reported, in grid nodes, N >= 1 [default: 3]
  --close N         close the mask with an N x N square first: 0 (no closing), 2 or 3
                    [default: 0]
  --open N          then open it with an N x N square: 0 (no opening), 2 or 3 [default: 0]
  -h, --help        print this help

boxes.csv columns:
  frame      the later frame of the pair, counted from 0 (so the first row has frame 1 or
             more)
  x,y,w,h    the box in that frame: left column, top row, width and height in whole pixels
  nodes      the region's size in grid nodes

A bad frame stops the run: the boxes of the frames before it are written, and the error names
the frame. Progress is shown on stderr when it is a terminal.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--viz"),
    Flag::value("--stats"),
    Flag::value("--cell"),
    Flag::value("--window"),
    Flag::value("--levels"),
    Flag::value("--threshold"),
    Flag::value("--min-nodes"),
    Flag::value("--close"),
    Flag::value("--open"),
];

const THRESHOLD: Rule<f64> = Rule {
    accepts: |v| v.is_finite() && v > 0.0,
    says: "must be a finite number > 0",
};
const MIN_NODES: Rule<i64> = Rule {
    accepts: |n| (1..=i64::from(u32::MAX)).contains(&n),
    says: "must be at least 1",
};
const STRUCTURE: Rule<i64> = Rule {
    accepts: |n| matches!(n, 0 | 2 | 3),
    says: "must be 0 (none), 2 or 3",
};

/// Parses the words after `motion`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<MotionOptions>, UsageError> {
    match parse(args, FLAGS, 1)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<MotionOptions, UsageError> {
    let Some(input) = matches.positionals().first().cloned() else {
        return Err(UsageError::new(
            "INPUT",
            "is required (a directory, a .y4m file or -)",
        ));
    };
    let defaults = MotionParams::default();
    let structure = |flag| -> Result<Option<Structure>, UsageError> {
        Ok(match matches.integer(flag, 0, STRUCTURE)? {
            2 => Some(Structure::Square2),
            3 => Some(Structure::Square3),
            _ => None,
        })
    };
    // Each value was range-checked by its rule, so the conversions below cannot truncate.
    let motion = MotionParams {
        threshold: matches.number("--threshold", f64::from(defaults.threshold), THRESHOLD)? as f32,
        close: structure("--close")?,
        open: structure("--open")?,
        boxes: BoxRules {
            min_nodes: matches.integer(
                "--min-nodes",
                i64::from(defaults.boxes.min_nodes),
                MIN_NODES,
            )? as u32,
            ..defaults.boxes
        },
        ..defaults
    };
    Ok(MotionOptions {
        input,
        out: matches.required_path("--out")?,
        viz: matches.path("--viz"),
        settings: MotionSettings {
            dense: dense_params(matches)?,
            motion,
            ..MotionSettings::default()
        },
        stats: matches.path("--stats"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<MotionOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn defaults_are_the_library_defaults() {
        let options = parsed("frames --out b.csv").unwrap().unwrap();
        assert_eq!(options.input, OsString::from("frames"));
        assert_eq!(options.settings, MotionSettings::default());
        assert_eq!(options.viz, None);
    }

    #[test]
    fn every_option_is_read() {
        let line =
            "- --out b.csv --viz v --cell 6 --threshold 1.5 --min-nodes 2 --close 3 --open 2";
        let options = parsed(line).unwrap().unwrap();
        let s = options.settings;
        assert_eq!(options.input, OsString::from("-"));
        assert_eq!(
            (s.dense.cell, s.motion.threshold, s.motion.boxes.min_nodes),
            (6, 1.5, 2)
        );
        assert_eq!(
            (s.motion.close, s.motion.open),
            (Some(Structure::Square3), Some(Structure::Square2))
        );
        assert_eq!(options.viz.unwrap().to_str(), Some("v"));
    }

    #[test]
    fn bad_command_lines_name_the_culprit() {
        let message = |line| parsed(line).unwrap_err().to_string();
        assert_eq!(
            message("--out b.csv"),
            "INPUT: is required (a directory, a .y4m file or -)"
        );
        assert_eq!(message("d"), "--out: is required");
        assert_eq!(
            message("d --out b.csv --threshold 0"),
            "--threshold: must be a finite number > 0 (got 0)"
        );
        assert_eq!(
            message("d --out b.csv --close 5"),
            "--close: must be 0 (none), 2 or 3 (got 5)"
        );
        assert_eq!(
            message("d e --out b.csv"),
            "'e': unexpected argument (flags start with --)"
        );
    }
}
