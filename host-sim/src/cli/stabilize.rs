//! The `stabilize` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use kestrel::ego::ModelKind;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use super::egomotion::{measurement, model, required_input};
use crate::commands::stabilize::{StabilizeOptions, DEFAULT_SMOOTHING};
use crate::egomotion::EstimatorSettings;

/// The usage text of `host-sim stabilize --help`.
pub const USAGE: &str = "\
host-sim stabilize: write camera-motion-compensated frames (video stabilization).

Usage: host-sim stabilize INPUT --out DIR [options]

The camera's motion between frames is measured like 'host-sim egomotion' does and chained
into its path; the path's shift, rotation and scale about the frame centre are averaged over
a window of frames centred on each frame; and each frame is warped (bilinear, black outside)
to the view of the averaged path. A steady pan, turn or zoom is kept, shake is removed. A
frame pair whose fit fails is taken to move like the last pair measured.

Input:
  INPUT             a directory of frames (PNG, JPEG, PGM or BMP, in file-name order), a .y4m
                    file, or - for y4m on standard input

Options:
  --out DIR         output directory, created if missing: frame_00000.png, frame_00001.png,
                    ... (8-bit grey, the input's size, in input order)
  --model M         translation, similarity, affine or homography [default: similarity]
  --smoothing N     frames on each side of a frame that its path is averaged over, 1 to 1000;
                    near the ends of the sequence the window shrinks to stay centred
                    [default: 15]
  --max-points N    points tracked per pair, 8 to 2000 [default: 200]
  --threshold PX    RANSAC inlier threshold, 0.05 to 100 px [default: 0.5]
  -h, --help        print this help

At most N + 1 frames are held in memory. A bad frame stops the run; the frames before it are
written.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--model"),
    Flag::value("--smoothing"),
    Flag::value("--max-points"),
    Flag::value("--threshold"),
];

const SMOOTHING: Rule<i64> = Rule {
    accepts: |n| (1..=1000).contains(&n),
    says: "must be between 1 and 1000 frames",
};

/// Parses the words after `stabilize`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<StabilizeOptions>, UsageError> {
    match parse(args, FLAGS, 1)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<StabilizeOptions, UsageError> {
    let input = required_input(matches)?;
    let out = matches.required_path("--out")?;
    let settings = EstimatorSettings {
        model: model(matches, ModelKind::Similarity)?,
        ..measurement(matches)?
    };
    // Range-checked by its rule.
    let smoothing = matches.integer("--smoothing", DEFAULT_SMOOTHING as i64, SMOOTHING)? as usize;
    Ok(StabilizeOptions {
        input,
        out,
        settings,
        smoothing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<StabilizeOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn defaults_and_overrides() {
        let options = parsed("frames --out stable").unwrap().unwrap();
        assert_eq!(options.settings.model, ModelKind::Similarity);
        assert_eq!(options.smoothing, DEFAULT_SMOOTHING);
        let options = parsed("- --out s --model homography --smoothing 4")
            .unwrap()
            .unwrap();
        assert_eq!(
            (options.settings.model, options.smoothing),
            (ModelKind::Homography, 4)
        );
    }

    #[test]
    fn bad_values_name_the_flag() {
        let message = |line| parsed(line).unwrap_err().to_string();
        assert_eq!(
            message("f --out s --smoothing 0"),
            "--smoothing: must be between 1 and 1000 frames (got 0)"
        );
        assert!(message("f --out s --model warp").starts_with("--model: must be"));
        assert!(message("--out s").starts_with("INPUT: is required"));
    }
}
