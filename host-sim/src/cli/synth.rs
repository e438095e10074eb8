//! The `synth` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use crate::commands::synth::SynthOptions;
use crate::synth::Lighting;

/// The usage text of `host-sim synth --help`.
pub const USAGE: &str = "\
host-sim synth: write seeded synthetic frame pairs with exact ground truth.

Usage: host-sim synth --out DIR [options]

Each pair is a procedural scene and the same scene under a known warp: a translation in a
random direction up to --max-shift px, a rotation within 1 degree and a zoom within 2% about
the centre.

Options:
  --out DIR         output directory, created if missing
  --pairs N         number of pairs, 1 to 1000 [default: 10]
  --width W         frame width, 16 to 4096 px [default: 320]
  --height H        frame height, 16 to 4096 px [default: 240]
  --seed S          seed of the whole set, a whole number >= 0 [default: 1]
  --max-shift PX    largest translation, 0 to 100 px [default: 20]
  --gain G          brightness gain of the second frame, 0.1 to 10 [default: 1]
  --bias B          brightness bias of the second frame, -255 to 255 grey levels [default: 0]
  --noise SIGMA     sensor noise, 0 to 50 grey levels [default: 1.5]
  --points N        at most N textured points per pair, 1 to 100000 [default: 300]
  -h, --help        print this help

Files in DIR, for each pair NNN:
  pairNNN_a.png, pairNNN_b.png   the two frames (8-bit grey)
  pairNNN_points.csv             x,y: points to track, for 'host-sim flow --points'
  pairNNN_truth.csv              x,y,tx,ty: each point and its true position in frame b
  manifest.csv                   pair,a,b,points,truth,dx,dy,angle_deg,scale,gain,bias

Exit status: 0 success; 1 an output that cannot be written; 2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--pairs"),
    Flag::value("--width"),
    Flag::value("--height"),
    Flag::value("--seed"),
    Flag::value("--max-shift"),
    Flag::value("--gain"),
    Flag::value("--bias"),
    Flag::value("--noise"),
    Flag::value("--points"),
];

const PAIRS: Rule<i64> = Rule {
    accepts: |n| (1..=1000).contains(&n),
    says: "must be between 1 and 1000",
};
/// Shared with `synth-sequence`.
pub(crate) const SIZE: Rule<i64> = Rule {
    accepts: |n| (16..=4096).contains(&n),
    says: "must be between 16 and 4096",
};
/// Shared with `synth-sequence`.
pub(crate) const SEED: Rule<i64> = Rule {
    accepts: |n| n >= 0,
    says: "must be a whole number >= 0",
};
const SHIFT: Rule<f64> = Rule {
    accepts: |v| (0.0..=100.0).contains(&v),
    says: "must be between 0 and 100",
};
const GAIN: Rule<f64> = Rule {
    accepts: |v| (0.1..=10.0).contains(&v),
    says: "must be between 0.1 and 10",
};
const BIAS: Rule<f64> = Rule {
    accepts: |v| (-255.0..=255.0).contains(&v),
    says: "must be between -255 and 255",
};
/// Shared with `synth-sequence`.
pub(crate) const NOISE: Rule<f64> = Rule {
    accepts: |v| (0.0..=50.0).contains(&v),
    says: "must be between 0 and 50",
};
const POINTS: Rule<i64> = Rule {
    accepts: |n| (1..=100_000).contains(&n),
    says: "must be between 1 and 100000",
};

/// Parses the words after `synth`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<SynthOptions>, UsageError> {
    match parse(args, FLAGS, 0)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<SynthOptions, UsageError> {
    // Each value was range-checked by its rule, so the conversions below cannot truncate.
    Ok(SynthOptions {
        out: matches.required_path("--out")?,
        pairs: matches.integer("--pairs", 10, PAIRS)? as usize,
        width: matches.integer("--width", 320, SIZE)? as usize,
        height: matches.integer("--height", 240, SIZE)? as usize,
        seed: matches.integer("--seed", 1, SEED)? as u64,
        max_shift: matches.number("--max-shift", 20.0, SHIFT)?,
        lighting: Lighting {
            gain: matches.number("--gain", 1.0, GAIN)?,
            bias: matches.number("--bias", 0.0, BIAS)?,
        },
        noise: matches.number("--noise", 1.5, NOISE)?,
        points: matches.integer("--points", 300, POINTS)? as usize,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<SynthOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn defaults_and_overrides() {
        let options = parsed("--out d").unwrap().unwrap();
        assert_eq!(
            (options.pairs, options.width, options.height),
            (10, 320, 240)
        );
        let options = parsed("--out d --pairs 3 --gain 1.25 --bias 15")
            .unwrap()
            .unwrap();
        assert_eq!(options.pairs, 3);
        assert_eq!(
            options.lighting,
            Lighting {
                gain: 1.25,
                bias: 15.0
            }
        );
    }

    #[test]
    fn values_out_of_range_name_the_flag() {
        let message = |line| parsed(line).unwrap_err().to_string();
        assert!(message("--out d --pairs 0").starts_with("--pairs: must be between 1"));
        assert!(message("--out d --width 8").starts_with("--width: must be between 16"));
        assert!(message("--pairs 2").starts_with("--out: is required"));
    }
}
