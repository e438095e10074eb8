//! The `track` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use crate::commands::track::TrackOptions;
use crate::tracking::MAX_TRACKS;
use crate::tracking::{Preset, TrackerSettings};
use kestrel::lk::{Illumination, TemplatePlacement};

/// The usage text of `host-sim track --help`.
pub const USAGE: &str = "\
host-sim track: the library's KLT tracker over a sequence: corners detected, followed with
Lucas-Kanade, checked (forward-backward, residual, appearance), dropped and refilled.

Usage: host-sim track INPUT --out tracks.csv [options]

INPUT:
  a directory of frames (PNG, JPEG, PGM or BMP, in file-name order), a .y4m file (the Y plane),
  or - for y4m on standard input (ffmpeg -i clip.mp4 -f yuv4mpegpipe - | host-sim track - ...)

Options:
  --out FILE        tracks, one row per live track per frame (see below)
  --max-tracks N    number of tracks aimed for, 1 to 1000 [default: 100; the preset's with
                    --preset]
  --preset NAME     flow-sensor: the library's TrackerConfig::flow_sensor() (25 tracks, 7x7
                    windows on two levels of a box-mean pyramid, FAST corners), the settings
                    a flight controller runs at 400 Hz; flags given beside it override it
                    [default: none, the tracker's defaults]
  --window N        LK window side, odd, 3 to 63 [default: 21; 7 with --preset flow-sensor]
  --levels L        coarsest pyramid level LK searches, 0 to 7 [default: 3; 1 with the preset]
  --illumination M  plain, or gain-bias: a brightness gain and bias fitted between frames
                    [default: gain-bias]
  --template P      at-point (interpolated at each track, OpenCV's) or nearest-pixel (on the
                    pixel nearest it, cheaper: the firmware's) [default: at-point;
                    nearest-pixel with the preset]
  --fb-threshold PX forward-backward gate, px, >= 0 [default: 1]
  --max-residual G  residual gate, grey levels, >= 0 [default: 12]
  --min-correlation C
                    appearance gate: least correlation with the track's birth patch, -1 to 1
                    (-1 turns it off) [default: 0.8]
  --viz DIR         one PNG per frame (000000.png, ...) with each track's trail over its last
                    10 frames, coloured by id; DIR is created if missing
  --stats S.json    write {\"frames\", \"median_frame_seconds\", \"mean_frame_seconds\",
                    \"mean_track_life\", \"drops\": {reason: count}}: the library's time per
                    frame (decoding and writing excluded), the frames a track is live in on
                    average, and the tracks dropped by each gate (lost, residual, appearance,
                    forward_backward)
  -h, --help        print this help

tracks.csv columns:
  frame     frame index, from 0
  id        track id; ids are never reused, and a track's first row is the frame it was
            detected in
  x,y       position in px, from the centre of the top-left pixel, x right, y down
  age       frames the track has been followed since it was detected
  residual  mean absolute intensity residual of its last step, grey levels

The firmware's configuration (firmware/src/pipeline.rs) is --window 9 --levels 2 --template
nearest-pixel; the flow sensor's is --preset flow-sensor.

A bad frame ends the run with an error naming it; tracks.csv then holds every frame before it.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--max-tracks"),
    Flag::value("--preset"),
    Flag::value("--window"),
    Flag::value("--levels"),
    Flag::value("--illumination"),
    Flag::value("--template"),
    Flag::value("--fb-threshold"),
    Flag::value("--max-residual"),
    Flag::value("--min-correlation"),
    Flag::value("--viz"),
    Flag::value("--stats"),
];

const TRACKS: Rule<i64> = Rule {
    accepts: |n| (1..=MAX_TRACKS as i64).contains(&n),
    says: "must be between 1 and 1000",
};

/// Parses the words after `track`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<TrackOptions>, UsageError> {
    match parse(args, FLAGS, 1)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<TrackOptions, UsageError> {
    let Some(input) = matches.positionals().first() else {
        return Err(UsageError::new(
            "INPUT",
            "is required: a directory of frames, a .y4m file or - for standard input",
        ));
    };
    Ok(TrackOptions {
        input: input.clone(),
        out: matches.required_path("--out")?,
        // Range-checked by the rule, so the conversion cannot truncate.
        max_tracks: match matches.value("--max-tracks") {
            Some(_) => Some(matches.integer("--max-tracks", 100, TRACKS)? as usize),
            None => None,
        },
        preset: preset(matches)?,
        settings: settings(matches)?,
        viz: matches.path("--viz"),
        stats: matches.path("--stats"),
    })
}

const WINDOW: Rule<i64> = Rule {
    accepts: |n| (3..=63).contains(&n) && n % 2 == 1,
    says: "must be an odd number from 3 to 63",
};
const LEVELS: Rule<i64> = Rule {
    accepts: |n| (0..=7).contains(&n),
    says: "must be between 0 and 7",
};
const NON_NEGATIVE: Rule<f64> = Rule {
    accepts: |v| v >= 0.0,
    says: "must be a number >= 0",
};
const CORRELATION: Rule<f64> = Rule {
    accepts: |v| (-1.0..=1.0).contains(&v),
    says: "must be between -1 and 1",
};

/// The LK and gate flags shared by `track` and `egomotion`: each set one overrides the
/// configuration it is applied to.
pub fn settings(matches: &Matches) -> Result<TrackerSettings, UsageError> {
    let given = |flag| matches.value(flag).is_some();
    let integer = |flag, rule| -> Result<Option<usize>, UsageError> {
        // Range-checked by the rule, so the conversion cannot truncate.
        Ok(if given(flag) {
            Some(matches.integer(flag, 0, rule)? as usize)
        } else {
            None
        })
    };
    let number = |flag, rule| -> Result<Option<f32>, UsageError> {
        Ok(if given(flag) {
            Some(matches.number(flag, 0.0, rule)? as f32)
        } else {
            None
        })
    };
    let illumination = matches.choice(
        "--illumination",
        &[
            ("plain", Illumination::Plain),
            ("gain-bias", Illumination::GainBias),
        ],
    )?;
    let template = matches.choice(
        "--template",
        &[
            ("at-point", TemplatePlacement::AtPoint),
            ("nearest-pixel", TemplatePlacement::NearestPixel),
        ],
    )?;
    Ok(TrackerSettings {
        template,
        window: integer("--window", WINDOW)?,
        levels: integer("--levels", LEVELS)?,
        illumination,
        fb_threshold: number("--fb-threshold", NON_NEGATIVE)?,
        max_residual: number("--max-residual", NON_NEGATIVE)?,
        min_correlation: number("--min-correlation", CORRELATION)?,
    })
}

/// The `--preset` flag's value.
pub fn preset(matches: &Matches) -> Result<Option<Preset>, UsageError> {
    matches.choice("--preset", &[("flow-sensor", Preset::FlowSensor)])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<TrackOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    fn error(line: &str) -> String {
        parsed(line).unwrap_err().to_string()
    }

    #[test]
    fn defaults_and_every_option() {
        let options = parsed("clip.y4m --out t.csv").unwrap().unwrap();
        assert_eq!(options.input, OsString::from("clip.y4m"));
        assert_eq!((options.max_tracks, options.viz), (None, None));
        let options = parsed("- --out t.csv --max-tracks 250 --viz pics")
            .unwrap()
            .unwrap();
        assert_eq!(options.input, OsString::from("-"));
        assert_eq!(options.max_tracks, Some(250));
        assert_eq!(options.viz.unwrap().to_str(), Some("pics"));
        let sensor = parsed("- --out t.csv --preset flow-sensor")
            .unwrap()
            .unwrap();
        assert_eq!(sensor.preset, Some(Preset::FlowSensor));
        assert_eq!(
            error("- --out t.csv --preset fast"),
            "--preset: must be flow-sensor (got fast)"
        );
    }

    #[test]
    fn mistakes_name_the_flag() {
        assert_eq!(
            error("frames --out t.csv --max-tracks 0"),
            "--max-tracks: must be between 1 and 1000 (got 0)"
        );
        assert_eq!(
            error("frames --out t.csv --max-tracks 1001"),
            "--max-tracks: must be between 1 and 1000 (got 1001)"
        );
        assert_eq!(error("frames"), "--out: is required");
        assert!(error("--out t.csv").starts_with("INPUT: is required"));
        assert!(error("a b --out t.csv").starts_with("'b': unexpected argument"));
    }

    #[test]
    fn help_is_not_an_error() {
        assert_eq!(parsed("--max-tracks 0 --help"), Ok(None));
    }
}
