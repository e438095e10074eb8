//! The `dense` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use kestrel::dense::grid::DenseParams;
use kestrel::lk::LkParams;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use super::flow::{LEVELS, REPEAT, WINDOW};
use crate::commands::dense::DenseOptions;

/// The usage text of `host-sim dense --help`.
pub const USAGE: &str = "\
host-sim dense: the library's grid flow from frame A to frame B: LK at every node of a
regular grid, each node checked for texture, convergence and residual, the rest filled from
their neighbours.

Usage: host-sim dense --prev A --next B --out grid.csv [options]

Files:
  --prev A          first frame: PNG, JPEG, PGM or BMP, converted to BT.601 grey
  --next B          second frame, the same size as A
  --out grid.csv    one row per grid node, row by row (see below)
  --flo F.flo       the flow at every pixel of A, interpolated from the grid, as a Middlebury
                    .flo file (unknown flow is 1e10)
  --png F.png       the Middlebury colour picture of that flow: hue is the direction, colour
                    strength the speed up to the largest in the picture, black is unknown; a
                    legend wheel sits in the top-right corner

Options:
  --cell N          grid spacing in px, 1 to the frame's smaller side [default: 8]
  --window N        LK window side in px, odd, 3 to 63 [default: 9]
  --levels L        coarsest pyramid level, 0 to 7 [default: 3]
  --repeat N        run the core (build both pyramids, compute the grid) N times,
                    N >= 1 [default: 1]
  --stats S.json    write {\"nodes\": n, \"repeat\": N, \"median_core_seconds\": t};
                    decoding is not timed
  -h, --help        print this help

grid.csv columns:
  x,y      the node centre in A: (cell/2 + i*cell, cell/2 + j*cell)
  dx,dy    its flow from A to B, px (0 when unknown; filled from the neighbours when filled)
  ok       1 when measured; 0 otherwise
  status   tracked, low_texture, residual (the window does not match), lost (not converged
           or left the frame) or filled

Coordinates are pixels from the centre of the top-left pixel, x right, y down.
Nothing is written unless every step succeeds.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--prev"),
    Flag::value("--next"),
    Flag::value("--out"),
    Flag::value("--flo"),
    Flag::value("--png"),
    Flag::value("--cell"),
    Flag::value("--window"),
    Flag::value("--levels"),
    Flag::value("--repeat"),
    Flag::value("--stats"),
];

/// Cells up to the largest frame; the frame's own size is checked once it is read.
const CELL: Rule<i64> = Rule {
    accepts: |n| (1..=kestrel::frame::MAX_DIMENSION as i64).contains(&n),
    says: "must be between 1 and 4096",
};

/// Parses the words after `dense`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<DenseOptions>, UsageError> {
    match parse(args, FLAGS, 0)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

/// The grid and LK flags shared with `motion`, over the dense defaults.
pub(crate) fn dense_params(matches: &Matches) -> Result<DenseParams, UsageError> {
    let defaults = DenseParams::default();
    // Each value was range-checked by its rule, so the conversions below cannot truncate.
    Ok(DenseParams {
        cell: matches.integer("--cell", defaults.cell as i64, CELL)? as usize,
        lk: LkParams {
            window: matches.integer("--window", defaults.lk.window as i64, WINDOW)? as usize,
            max_level: matches.integer("--levels", defaults.lk.max_level as i64, LEVELS)? as usize,
            ..defaults.lk
        },
        ..defaults
    })
}

fn options(matches: &Matches) -> Result<DenseOptions, UsageError> {
    Ok(DenseOptions {
        prev: matches.required_path("--prev")?,
        next: matches.required_path("--next")?,
        out: matches.required_path("--out")?,
        flo: matches.path("--flo"),
        png: matches.path("--png"),
        params: dense_params(matches)?,
        repeat: matches.integer("--repeat", 1, REPEAT)? as usize,
        stats: matches.path("--stats"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILES: &str = "--prev a.png --next b.png --out g.csv";

    fn parsed(line: &str) -> Result<Option<DenseOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    #[test]
    fn defaults_are_the_library_defaults() {
        let options = parsed(FILES).unwrap().unwrap();
        assert_eq!(options.params, DenseParams::default());
        assert_eq!((options.flo, options.png, options.repeat), (None, None, 1));
    }

    #[test]
    fn every_option_is_read() {
        let line = format!(
            "{FILES} --cell 16 --window 11 --levels 2 --flo f.flo --png f.png --repeat 4 --stats s.json"
        );
        let options = parsed(&line).unwrap().unwrap();
        let p = options.params;
        assert_eq!((p.cell, p.lk.window, p.lk.max_level), (16, 11, 2));
        assert_eq!(options.flo.unwrap().to_str(), Some("f.flo"));
        assert_eq!(options.png.unwrap().to_str(), Some("f.png"));
        assert_eq!(options.repeat, 4);
    }

    #[test]
    fn bad_values_name_the_flag() {
        let message = |extra: &str| parsed(&format!("{FILES} {extra}")).unwrap_err().to_string();
        assert_eq!(
            message("--cell 0"),
            "--cell: must be between 1 and 4096 (got 0)"
        );
        assert_eq!(
            message("--window 8"),
            "--window: must be odd and between 3 and 63 (got 8)"
        );
        assert_eq!(
            message("--repeat 0"),
            "--repeat: must be at least 1 (got 0)"
        );
        assert_eq!(
            parsed("--prev a.png --next b.png").unwrap_err().to_string(),
            "--out: is required"
        );
    }
}
