//! The `synth-sequence` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use super::synth::{NOISE, SEED, SIZE};
use crate::commands::synth_sequence::SynthSequenceOptions;
use crate::synth::FlightPath;

/// The usage text of `host-sim synth-sequence --help`.
pub const USAGE: &str = "\
host-sim synth-sequence: write a seeded synthetic flight over textured ground, with the exact
homography of every frame pair and, when the camera turns at a constant rate, its gyro log.

Usage: host-sim synth-sequence --out DIR [options]

The camera looks down at a plane with a 60 degree horizontal field of view. Paths:
  pan          translation parallel to the ground (the image shifts)
  yaw          turning about the optical axis while drifting (the image turns)
  climb        moving towards or away from the ground while drifting (the image zooms)
  perspective  a tilted ground, turning and moving along every axis (a full homography)
  rotation     turning about every axis without moving (a gyro predicts it all)
  shake        hovering with a slow drift and a random tremor in every frame

Options:
  --out DIR         output directory, created if missing
  --path P          one of the paths above [default: pan]
  --frames N        number of frames, 2 to 10000 [default: 30]
  --width W         frame width, 16 to 4096 px [default: 320]
  --height H        frame height, 16 to 4096 px [default: 240]
  --seed S          seed of the scene, the path and the objects, >= 0 [default: 1]
  --objects K       independently moving textured rectangles, each covering 12% of the
                    frame, 0 to 4 (2 make 20-30% of the tracks outliers) [default: 0]
  --noise SIGMA     sensor noise, 0 to 50 grey levels [default: 1]
  --fps F           frame rate of the gyro log's clock, 1 to 10000 [default: 30]
  -h, --help        print this help

Files in DIR:
  frames/frame_NNNNN.png   the frames (8-bit grey), for 'host-sim egomotion DIR/frames'
  truth.csv                frame,h11,...,h33: the exact homography from frame-1 to frame
  gyro.csv                 t_us,gx,gy,gz: the exact body rates every millisecond, for
                           'egomotion --gyro' (all paths but shake)

Exit status: 0 success; 1 an output that cannot be written; 2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--path"),
    Flag::value("--frames"),
    Flag::value("--width"),
    Flag::value("--height"),
    Flag::value("--seed"),
    Flag::value("--objects"),
    Flag::value("--noise"),
    Flag::value("--fps"),
];

const FRAMES: Rule<i64> = Rule {
    accepts: |n| (2..=10_000).contains(&n),
    says: "must be between 2 and 10000",
};
const OBJECTS: Rule<i64> = Rule {
    accepts: |n| (0..=4).contains(&n),
    says: "must be between 0 and 4",
};

/// Parses the words after `synth-sequence`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<SynthSequenceOptions>, UsageError> {
    match parse(args, FLAGS, 0)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<SynthSequenceOptions, UsageError> {
    // Each value was range-checked by its rule, so the conversions below cannot truncate.
    Ok(SynthSequenceOptions {
        out: matches.required_path("--out")?,
        path: path(matches)?,
        frames: matches.integer("--frames", 30, FRAMES)? as usize,
        width: matches.integer("--width", 320, SIZE)? as usize,
        height: matches.integer("--height", 240, SIZE)? as usize,
        seed: matches.integer("--seed", 1, SEED)? as u64,
        objects: matches.integer("--objects", 0, OBJECTS)? as usize,
        noise: matches.number("--noise", 1.0, NOISE)?,
        fps: matches.number("--fps", 30.0, super::egomotion::FPS)?,
    })
}

fn path(matches: &Matches) -> Result<FlightPath, UsageError> {
    let Some(name) = matches.value("--path").map(|v| v.to_string_lossy()) else {
        return Ok(FlightPath::Pan);
    };
    FlightPath::from_name(&name).ok_or_else(|| {
        let names: Vec<&str> = FlightPath::ALL.iter().map(|p| p.name()).collect();
        UsageError::new(
            "--path",
            format!("must be one of {} (got \"{name}\")", names.join(", ")),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<SynthSequenceOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn defaults_and_overrides() {
        let options = parsed("--out d").unwrap().unwrap();
        assert_eq!(
            (options.path, options.frames, options.objects),
            (FlightPath::Pan, 30, 0)
        );
        let options = parsed("--out d --path shake --frames 5 --objects 2 --fps 60")
            .unwrap()
            .unwrap();
        assert_eq!(
            (options.path, options.frames, options.objects),
            (FlightPath::Shake, 5, 2)
        );
        assert_eq!(options.fps, 60.0);
    }

    #[test]
    fn bad_values_name_the_flag() {
        let message = |line| parsed(line).unwrap_err().to_string();
        assert_eq!(
            message("--out d --path loop"),
            "--path: must be one of pan, yaw, climb, perspective, rotation, shake (got \"loop\")"
        );
        assert!(message("--out d --frames 1").starts_with("--frames: must be between 2"));
        assert!(message("--out d --objects 9").starts_with("--objects: must be between 0"));
    }
}
