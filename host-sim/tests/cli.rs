//! Runs the `host-sim` binary on files made in a scratch directory and checks the command-line
//! contract: outputs, exit status, one-line errors naming the culprit, and no output on error.

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use common::{assert_one_line_error, host_sim, Scratch};
use image::{GrayImage, Luma, Rgb, RgbImage};

const WIDTH: u32 = 96;
const HEIGHT: u32 = 72;

/// A textured frame and the same frame shifted 2 px to the right, as a.png and b.png, and the
/// points file p.csv.
fn pair_and_points(scratch: &Scratch, points: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (a, b, p) = (
        scratch.path("a.png"),
        scratch.path("b.png"),
        scratch.path("p.csv"),
    );
    textured(WIDTH, HEIGHT, 0.0).save(&a).unwrap();
    textured(WIDTH, HEIGHT, 2.0).save(&b).unwrap();
    fs::write(&p, points).unwrap();
    (a, b, p)
}

/// A smooth, non-repeating texture, its content moved `shift` px to the right.
fn textured(width: u32, height: u32, shift: f32) -> GrayImage {
    GrayImage::from_fn(width, height, |x, y| {
        let (x, y) = (x as f32 - shift, y as f32);
        let value = 128.0
            + 45.0 * (0.31 * x + 0.6 * (0.17 * y).sin()).sin()
            + 40.0 * (0.23 * y + 0.4 * (0.13 * x).cos()).cos()
            + 20.0 * (0.07 * (x + y)).sin();
        Luma([value.round().clamp(0.0, 255.0) as u8])
    })
}

/// `flow` on the scratch pair with `extra` arguments, writing o.csv.
fn flow(scratch: &Scratch, points: &str, extra: &[&str]) -> (Output, PathBuf) {
    let (a, b, p) = pair_and_points(scratch, points);
    let out = scratch.path("o.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ];
    args.extend(extra.iter().map(|e| e as &dyn AsRef<std::ffi::OsStr>));
    (host_sim(&args), out)
}

/// Only the inputs remain: no output and no temporary beside it.
fn assert_no_output(scratch: &Scratch) {
    assert_eq!(scratch.entries(), ["a.png", "b.png", "p.csv"]);
}

const POINTS: &str = "x,y\n30,30\n50.5,40.25\n-10,5\n70,20\n";

fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines()
        .skip(1)
        .map(|line| line.split(',').map(str::to_owned).collect())
        .collect()
}

fn number(field: &str) -> f64 {
    field.parse().unwrap()
}

#[test]
fn flow_tracks_a_two_pixel_shift_in_input_order() {
    let scratch = Scratch::new("happy");
    let (output, out) = flow(&scratch, POINTS, &[]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.stderr.is_empty() && output.stdout.is_empty());
    let csv = fs::read_to_string(out).unwrap();
    assert_eq!(csv.lines().next(), Some("x,y,nx,ny,ok,err,status"));
    let rows = rows(&csv);
    let inputs: Vec<(&str, &str)> = rows
        .iter()
        .map(|r| (r[0].as_str(), r[1].as_str()))
        .collect();
    assert_eq!(
        inputs,
        [
            ("30.0000", "30.0000"),
            ("50.5000", "40.2500"),
            ("-10.0000", "5.0000"),
            ("70.0000", "20.0000")
        ]
    );
    for row in rows.iter().filter(|r| r[0] != "-10.0000") {
        assert_eq!(
            (row[4].as_str(), row[6].as_str()),
            ("1", "tracked"),
            "{row:?}"
        );
        assert!(
            (number(&row[2]) - number(&row[0]) - 2.0).abs() < 0.1,
            "{row:?}"
        );
        assert!((number(&row[3]) - number(&row[1])).abs() < 0.1, "{row:?}");
        assert!(number(&row[5]) >= 0.0 && number(&row[5]) < 10.0, "{row:?}");
    }
    let outside = &rows[2];
    assert_eq!(
        (outside[4].as_str(), outside[6].as_str()),
        ("0", "out_of_bounds")
    );
    assert_eq!(scratch.entries(), ["a.png", "b.png", "o.csv", "p.csv"]);
}

#[test]
fn flow_options_are_accepted() {
    let scratch = Scratch::new("options");
    let extra = [
        "--window",
        "15",
        "--levels",
        "2",
        "--max-iters",
        "20",
        "--epsilon",
        "0.001",
    ];
    let (output, out) = flow(&scratch, POINTS, &extra);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let rows = rows(&fs::read_to_string(out).unwrap());
    assert_eq!(rows.len(), 4);
    assert!((number(&rows[0][2]) - 32.0).abs() < 0.1, "{:?}", rows[0]);
}

#[test]
fn colour_frames_are_tracked_like_grey_ones() {
    let scratch = Scratch::new("colour");
    let (a, b, p) = pair_and_points(&scratch, POINTS);
    // The same texture in colour: BT.601 luma of (v, v, v) is v.
    for path in [&a, &b] {
        let grey = image::open(path).unwrap().to_luma8();
        RgbImage::from_fn(WIDTH, HEIGHT, |x, y| {
            let v = grey.get_pixel(x, y).0[0];
            Rgb([v, v, v])
        })
        .save(path)
        .unwrap();
    }
    let out = scratch.path("o.csv");
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    assert!(output.status.success());
    let rows = rows(&fs::read_to_string(out).unwrap());
    assert!((number(&rows[0][2]) - 32.0).abs() < 0.1, "{:?}", rows[0]);
}

#[test]
fn repeat_and_stats_write_the_timing_summary() {
    let scratch = Scratch::new("stats");
    let stats = scratch.path("s.json");
    let stats_arg = stats.to_str().unwrap();
    let (output, out) = flow(&scratch, POINTS, &["--repeat", "3", "--stats", stats_arg]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(out.exists());
    let json = fs::read_to_string(&stats).unwrap();
    assert!(
        json.starts_with("{\"points\": 4, \"repeat\": 3, \"median_core_seconds\": "),
        "{json}"
    );
    let seconds = json
        .trim_end()
        .trim_end_matches('}')
        .rsplit(": ")
        .next()
        .unwrap();
    assert!(number(seconds) > 0.0 && number(seconds) < 10.0, "{json}");
}

#[test]
fn stats_without_repeat_counts_one_run() {
    let scratch = Scratch::new("stats1");
    let stats = scratch.path("s.json");
    let (output, _) = flow(&scratch, POINTS, &["--stats", stats.to_str().unwrap()]);
    assert!(output.status.success());
    assert!(fs::read_to_string(&stats)
        .unwrap()
        .contains("\"repeat\": 1,"));
}

#[test]
fn reference_engine_writes_the_same_columns() {
    let scratch = Scratch::new("reference");
    let (output, out) = flow(&scratch, POINTS, &["--reference"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let csv = fs::read_to_string(out).unwrap();
    assert!(csv.starts_with("x,y,nx,ny,ok,err,"));
    assert_eq!(rows(&csv).len(), 4);
}

#[test]
fn help_goes_to_stdout_with_success() {
    for args in [
        &["--help"][..],
        &["-h"],
        &["flow", "--help"],
        &["flow", "--window", "20", "-h"],
    ] {
        let args: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|a| a as _).collect();
        let output = host_sim(&args);
        assert_eq!(output.status.code(), Some(0));
        assert!(output.stderr.is_empty());
        let usage = String::from_utf8(output.stdout).unwrap();
        assert!(
            usage.contains("Usage: host-sim") && usage.contains("Exit status"),
            "{usage}"
        );
    }
}

#[test]
fn a_missing_frame_is_named() {
    let scratch = Scratch::new("missing");
    let (a, _, p) = pair_and_points(&scratch, POINTS);
    let missing = scratch.path("missing.png");
    let out = scratch.path("o.csv");
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &missing,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    let message = assert_one_line_error(&output, 1, "missing.png");
    assert!(message.contains("no such file"), "{message}");
    assert_no_output(&scratch);
}

#[test]
fn a_corrupt_png_is_named() {
    let scratch = Scratch::new("corrupt");
    let (a, b, p) = pair_and_points(&scratch, POINTS);
    let png = fs::read(&b).unwrap();
    fs::write(&b, &png[..png.len() / 2]).unwrap();
    let out = scratch.path("o.csv");
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    assert_one_line_error(&output, 1, "b.png");
    assert_no_output(&scratch);
    fs::write(&b, b"\x89PNG\r\n\x1a\nthis is not a png at all").unwrap();
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    assert_one_line_error(&output, 1, "b.png");
    assert_no_output(&scratch);
}

#[test]
fn frames_of_different_sizes_name_both_files() {
    let scratch = Scratch::new("sizes");
    let (a, b, p) = pair_and_points(&scratch, POINTS);
    textured(WIDTH / 2, HEIGHT, 0.0).save(&b).unwrap();
    let out = scratch.path("o.csv");
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    let message = assert_one_line_error(&output, 1, "a.png");
    assert!(
        message.contains("b.png") && message.contains("96x72") && message.contains("48x72"),
        "{message}"
    );
    assert_no_output(&scratch);
}

#[test]
fn a_bad_csv_number_names_file_line_and_column() {
    let scratch = Scratch::new("csv");
    let (output, _) = flow(&scratch, "x,y\n10,10\n20,abc\n", &[]);
    let message = assert_one_line_error(&output, 1, "p.csv");
    assert!(
        message.contains("line 3") && message.contains("column 2") && message.contains("abc"),
        "{message}"
    );
    assert_no_output(&scratch);
}

#[test]
fn a_csv_without_header_is_refused() {
    let scratch = Scratch::new("header");
    let (output, _) = flow(&scratch, "10,10\n", &[]);
    let message = assert_one_line_error(&output, 1, "p.csv");
    assert!(
        message.contains("line 1") && message.contains("header"),
        "{message}"
    );
    assert_no_output(&scratch);
}

#[test]
fn out_of_range_flags_are_usage_errors() {
    let cases = [
        (
            ["--window", "20"],
            "--window: must be odd and between 3 and 63 (got 20)",
        ),
        (
            ["--window", "65"],
            "--window: must be odd and between 3 and 63 (got 65)",
        ),
        (
            ["--levels", "9"],
            "--levels: must be between 0 and 7 (got 9)",
        ),
        (
            ["--max-iters", "0"],
            "--max-iters: must be at least 1 (got 0)",
        ),
        (
            ["--epsilon", "-0.5"],
            "--epsilon: must be a finite number >= 0 (got -0.5)",
        ),
        (["--repeat", "0"], "--repeat: must be at least 1 (got 0)"),
        (
            ["--window", "big"],
            "--window: expected a whole number (got \"big\")",
        ),
    ];
    for (extra, expected) in cases {
        let scratch = Scratch::new("range");
        let (output, _) = flow(&scratch, POINTS, &extra);
        let message = assert_one_line_error(&output, 2, extra[0]);
        assert_eq!(message, format!("host-sim: {expected}\n"));
        assert_no_output(&scratch);
    }
}

#[test]
fn unknown_repeated_and_missing_flags_are_usage_errors() {
    let cases: [(&[&str], &str); 4] = [
        (&["--bogus", "1"], "host-sim: --bogus: unknown flag\n"),
        (
            &["--window", "5", "--window", "7"],
            "host-sim: --window: given more than once\n",
        ),
        (&["--levels"], "host-sim: --levels: needs a value\n"),
        (
            &["extra.png"],
            "host-sim: 'extra.png': unexpected argument (flags start with --)\n",
        ),
    ];
    for (extra, expected) in cases {
        let scratch = Scratch::new("flags");
        let (output, _) = flow(&scratch, POINTS, extra);
        let message = assert_one_line_error(&output, 2, extra[0]);
        assert_eq!(message, expected);
        assert_no_output(&scratch);
    }
    let output = host_sim(&[&"flow", &"--prev", &"a.png"]);
    assert_one_line_error(&output, 2, "--next");
    assert_one_line_error(&host_sim(&[&"fly"]), 2, "'fly'");
    assert_one_line_error(&host_sim(&[]), 2, "missing command");
}

#[test]
fn an_unwritable_output_path_is_named_and_nothing_is_written() {
    let scratch = Scratch::new("unwritable");
    // Unwritable even for root: a directory that does not exist, and a parent that is a file.
    for out in ["no-such-dir/o.csv", "p.csv/o.csv"] {
        let out = scratch.path(out);
        let (a, b, p) = pair_and_points(&scratch, POINTS);
        let output = host_sim(&[
            &"flow",
            &"--prev",
            &a,
            &"--next",
            &b,
            &"--points",
            &p,
            &"--out",
            &out,
        ]);
        assert_one_line_error(&output, 1, &out.display().to_string());
        assert_no_output(&scratch);
    }
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &scratch.path("a.png"),
        &"--next",
        &scratch.path("b.png"),
        &"--points",
        &scratch.path("p.csv"),
        &"--out",
        &scratch.dir(),
    ]);
    let message = assert_one_line_error(&output, 1, "is a directory");
    assert!(message.contains(&scratch.dir().display().to_string()));
}

#[test]
fn an_unwritable_stats_path_writes_no_output_either() {
    let scratch = Scratch::new("badstats");
    let stats = scratch.path("no-such-dir/s.json");
    let (output, _) = flow(&scratch, POINTS, &["--stats", stats.to_str().unwrap()]);
    assert_one_line_error(&output, 1, "s.json");
    assert_no_output(&scratch);
}

#[test]
fn an_error_leaves_an_existing_output_untouched() {
    let scratch = Scratch::new("untouched");
    let out = scratch.path("o.csv");
    fs::write(&out, "previous results\n").unwrap();
    let (output, _) = flow(&scratch, "x,y\n1,oops\n", &[]);
    assert_one_line_error(&output, 1, "p.csv");
    assert_eq!(fs::read_to_string(&out).unwrap(), "previous results\n");
    assert_eq!(scratch.entries(), ["a.png", "b.png", "o.csv", "p.csv"]);
}

#[test]
fn an_empty_points_file_gives_a_header_only_output() {
    let scratch = Scratch::new("nopoints");
    let (output, out) = flow(&scratch, "x,y\n", &[]);
    assert!(output.status.success());
    assert_eq!(
        fs::read_to_string(out).unwrap(),
        "x,y,nx,ny,ok,err,status\n"
    );
}

/// Keeps the helper honest: `Path` arguments work alongside strings.
#[test]
fn paths_with_spaces_work() {
    let scratch = Scratch::new("spaces");
    let (a, b, p) = pair_and_points(&scratch, POINTS);
    let out: &Path = &scratch.path("out file.csv");
    let output = host_sim(&[
        &"flow",
        &"--prev",
        &a,
        &"--next",
        &b,
        &"--points",
        &p,
        &"--out",
        &out,
    ]);
    assert!(output.status.success());
    assert!(out.exists());
}
