//! The `flow` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use kestrel::lk::{Illumination, LkParams};

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use crate::commands::flow::{Engine, FlowOptions};

/// The usage text of `host-sim flow --help`.
pub const USAGE: &str = "\
host-sim flow: track points from frame A to frame B with the library's Q16 pyramidal
Lucas-Kanade (or the f32 reference).

Usage: host-sim flow --prev A --next B --points P.csv --out O.csv [options]

Files:
  --prev A          first frame: PNG, JPEG, PGM or BMP, converted to BT.601 grey
  --next B          second frame, the same size as A
  --points P.csv    points to track: a header line starting with x,y, then one point per line
  --out O.csv       results, one row per point in input order (see below)

Options:
  --window N        window side in px, odd, 3 to 63 [default: 21]
  --levels L        coarsest pyramid level, 0 to 7, like OpenCV's maxLevel [default: 3]
  --max-iters K     iterations per level, at least 1 [default: 30]
  --epsilon E       stop when a step is shorter than E px, finite and >= 0 [default: 0.01]
  --illumination M  brightness model between the frames: gain-bias (fit a gain and a bias
                    per window; robust to exposure changes) or plain [default: gain-bias]
  --reference       run the f32 reference implementation instead of the library
  --repeat N        run the core (build both pyramids, track every point) N times,
                    N >= 1 [default: 1]
  --stats S.json    write {\"points\": n, \"repeat\": N, \"median_core_seconds\": t};
                    decoding is not timed
  -h, --help        print this help

O.csv columns:
  x,y      the input point
  nx,ny    its position in B (the last estimate when ok is 0)
  ok       1 when tracked; 0 when outside the image, too little texture or not converged
  err      mean absolute intensity residual over the window, grey levels (0 when ok is 0)
  status   tracked, out_of_bounds, low_texture or not_converged

Coordinates are pixels from the centre of the top-left pixel, x right, y down.
Nothing is written unless every step succeeds.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--prev"),
    Flag::value("--next"),
    Flag::value("--points"),
    Flag::value("--out"),
    Flag::value("--window"),
    Flag::value("--levels"),
    Flag::value("--max-iters"),
    Flag::value("--epsilon"),
    Flag::value("--illumination"),
    Flag::switch("--reference"),
    Flag::value("--repeat"),
    Flag::value("--stats"),
];

pub(crate) const WINDOW: Rule<i64> = Rule {
    accepts: |n| (3..=63).contains(&n) && n % 2 == 1,
    says: "must be odd and between 3 and 63",
};
pub(crate) const LEVELS: Rule<i64> = Rule {
    accepts: |n| (0..=7).contains(&n),
    says: "must be between 0 and 7",
};
/// Iterations are a `u32` in the library.
const MAX_ITERS: Rule<i64> = Rule {
    accepts: |n| (1..=i64::from(u32::MAX)).contains(&n),
    says: "must be at least 1",
};
const EPSILON: Rule<f64> = Rule {
    accepts: |e| e.is_finite() && e >= 0.0,
    says: "must be a finite number >= 0",
};
pub(crate) const REPEAT: Rule<i64> = Rule {
    accepts: |n| n >= 1,
    says: "must be at least 1",
};

/// Parses the words after `flow`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<FlowOptions>, UsageError> {
    match parse(args, FLAGS, 0)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<FlowOptions, UsageError> {
    let prev = matches.required_path("--prev")?;
    let next = matches.required_path("--next")?;
    let points = matches.required_path("--points")?;
    let out = matches.required_path("--out")?;
    let defaults = LkParams::default();
    // Each value was range-checked by its rule, so the conversions below cannot truncate.
    let params = LkParams {
        window: matches.integer("--window", defaults.window as i64, WINDOW)? as usize,
        max_level: matches.integer("--levels", defaults.max_level as i64, LEVELS)? as usize,
        max_iterations: matches.integer(
            "--max-iters",
            i64::from(defaults.max_iterations),
            MAX_ITERS,
        )? as u32,
        epsilon: matches.number("--epsilon", f64::from(defaults.epsilon), EPSILON)? as f32,
        illumination: illumination(matches)?,
        ..defaults
    };
    let engine = if matches.switch("--reference") {
        Engine::Reference
    } else {
        Engine::Library
    };
    Ok(FlowOptions {
        prev,
        next,
        points,
        out,
        params,
        engine,
        repeat: matches.integer("--repeat", 1, REPEAT)? as usize,
        stats: matches.path("--stats"),
    })
}

fn illumination(matches: &Matches) -> Result<Illumination, UsageError> {
    match matches.value("--illumination").map(|v| v.to_string_lossy()) {
        None => Ok(Illumination::default()),
        Some(v) if v == "gain-bias" => Ok(Illumination::GainBias),
        Some(v) if v == "plain" => Ok(Illumination::Plain),
        Some(v) => Err(UsageError::new(
            "--illumination",
            format!("must be gain-bias or plain (got \"{v}\")"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILES: &str = "--prev a.png --next b.png --points p.csv --out o.csv";

    fn parse_line(line: &str) -> Result<Option<FlowOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    fn error(extra: &str) -> String {
        parse_line(&format!("{FILES} {extra}"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn illumination_model_is_chosen_by_name() {
        let plain = parse_line(&format!("{FILES} --illumination plain"));
        assert_eq!(
            plain.unwrap().unwrap().params.illumination,
            Illumination::Plain
        );
        let default = parse_line(FILES).unwrap().unwrap();
        assert_eq!(default.params.illumination, Illumination::GainBias);
        assert_eq!(
            error("--illumination sunny"),
            "--illumination: must be gain-bias or plain (got \"sunny\")"
        );
    }

    #[test]
    fn defaults_are_the_library_defaults() {
        let options = parse_line(FILES).unwrap().unwrap();
        assert_eq!(options.params, LkParams::default());
        assert_eq!(
            (options.engine, options.repeat, options.stats),
            (Engine::Library, 1, None)
        );
    }

    #[test]
    fn every_option_is_read() {
        let line = format!(
            "{FILES} --window 7 --levels 0 --max-iters 5 --epsilon 0.5 --reference --repeat 3 --stats s.json"
        );
        let options = parse_line(&line).unwrap().unwrap();
        let p = options.params;
        assert_eq!(
            (p.window, p.max_level, p.max_iterations, p.epsilon),
            (7, 0, 5, 0.5)
        );
        assert_eq!((options.engine, options.repeat), (Engine::Reference, 3));
        assert_eq!(options.stats.unwrap().to_str(), Some("s.json"));
    }

    #[test]
    fn out_of_range_values_name_the_flag_and_the_value() {
        assert_eq!(
            error("--window 20"),
            "--window: must be odd and between 3 and 63 (got 20)"
        );
        assert_eq!(
            error("--window 65"),
            "--window: must be odd and between 3 and 63 (got 65)"
        );
        assert_eq!(
            error("--window 1"),
            "--window: must be odd and between 3 and 63 (got 1)"
        );
        assert_eq!(
            error("--levels 9"),
            "--levels: must be between 0 and 7 (got 9)"
        );
        assert_eq!(
            error("--max-iters 0"),
            "--max-iters: must be at least 1 (got 0)"
        );
        assert_eq!(
            error("--epsilon -1"),
            "--epsilon: must be a finite number >= 0 (got -1)"
        );
        assert_eq!(
            error("--epsilon inf"),
            "--epsilon: must be a finite number >= 0 (got inf)"
        );
        assert_eq!(
            error("--epsilon NaN"),
            "--epsilon: must be a finite number >= 0 (got NaN)"
        );
        assert_eq!(error("--repeat 0"), "--repeat: must be at least 1 (got 0)");
    }

    #[test]
    fn missing_files_are_named() {
        let error = parse_line("--prev a.png --next b.png --out o.csv").unwrap_err();
        assert_eq!(error.to_string(), "--points: is required");
    }

    #[test]
    fn help_is_not_an_error() {
        assert_eq!(parse_line("--window 20 --help"), Ok(None));
    }
}
