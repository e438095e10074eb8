//! `host-sim synth-sequence`'s camera model: every effect off by default, each one changing the
//! frames the way a real sensor does when it is turned on.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use common::{
    assert_one_line_error, run_synth, synth, synth_frame as frame, synth_run_hash as run_hash,
    Scratch,
};
use host_sim::io::images::read_grey;
use host_sim::synth::{Homography, Light};
use host_sim::Frame;

/// The pixels of a frame as numbers.
fn values(frame: &Frame) -> Vec<f64> {
    frame.data.iter().map(|&v| f64::from(v)).collect()
}

fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

fn std_dev(values: &[f64]) -> f64 {
    let m = mean(values);
    mean(&values.iter().map(|v| (v - m).powi(2)).collect::<Vec<_>>()).sqrt()
}

/// The mean absolute difference of two frames' pixels.
fn mean_abs_diff(a: &Frame, b: &Frame) -> f64 {
    let diffs: Vec<f64> = values(a)
        .iter()
        .zip(values(b))
        .map(|(p, q)| (p - q).abs())
        .collect();
    mean(&diffs)
}

/// Small runs: 160x120, the ideal camera's noise off so that only the effect differs.
const SMALL: [&str; 6] = ["--width", "160", "--height", "120", "--noise", "0"];

/// `SMALL` and `more`.
fn small<'a>(more: &[&'a str]) -> Vec<&'a str> {
    SMALL.iter().chain(more).copied().collect()
}

/// Runs without any camera flag, and the hashes of their outputs as recorded at commit 3870d6f,
/// before the camera model.
const UNCHANGED_RUNS: [(&[&str], u64); 3] = [
    (&[], 0xf17e504e8c1e02e9),
    (
        &[
            "--path",
            "perspective",
            "--objects",
            "2",
            "--frames",
            "6",
            "--width",
            "96",
            "--height",
            "72",
        ],
        0x32467c6b4d61494d,
    ),
    (
        &[
            "--path", "shake", "--noise", "0", "--frames", "5", "--seed", "7",
        ],
        0xd797b03f0d2dc4b7,
    ),
];

#[test]
fn without_camera_flags_the_frames_are_byte_for_byte_unchanged() {
    let scratch = Scratch::new("synth-unchanged");
    common::assert_synth_hashes(&scratch, &UNCHANGED_RUNS);
}

/// Every camera flag at once.
const EVERY_EFFECT: [&str; 15] = [
    "--light",
    "30",
    "--exposure",
    "20",
    "--rolling-shutter",
    "15",
    "--vignetting",
    "0.3",
    "--jpeg",
    "60",
    "--downscale",
    "2",
    "--auto-exposure",
    "--scene",
    "PHOTO",
];

/// A photograph for --scene: a procedural frame of another seed, larger than the runs' frames.
fn photograph(scratch: &Scratch) -> PathBuf {
    let dir = synth(
        scratch,
        "photo-source",
        &[
            "--width", "480", "--height", "360", "--frames", "2", "--seed", "11", "--noise", "0",
        ],
    );
    let path = scratch.path("photo.png");
    fs::copy(dir.join("frames").join("frame_00000.png"), &path).unwrap();
    path
}

#[test]
fn every_effect_repeats_with_its_seed_and_leaves_the_truth_alone() {
    let scratch = Scratch::new("synth-seeded");
    let photo = photograph(&scratch);
    let photo = photo.to_str().unwrap();
    let base = [
        "--width",
        "96",
        "--height",
        "72",
        "--frames",
        "10",
        "--objects",
        "1",
    ];
    let with_all = |seed: &'static str| -> Vec<&str> {
        let effects = EVERY_EFFECT
            .iter()
            .map(|a| if *a == "PHOTO" { photo } else { a });
        base.iter()
            .copied()
            .chain(effects)
            .chain(["--seed", seed])
            .collect()
    };
    let (a, b) = (
        synth(&scratch, "a", &with_all("4")),
        synth(&scratch, "b", &with_all("4")),
    );
    assert_eq!(run_hash(&a), run_hash(&b));
    let other = synth(&scratch, "other", &with_all("5"));
    assert_ne!(frame(&a, 3), frame(&other, 3));
    let ideal: Vec<&str> = base.iter().copied().chain(["--seed", "4"]).collect();
    let ideal = synth(&scratch, "ideal", &ideal);
    assert_ne!(frame(&a, 3), frame(&ideal, 3));
    for file in ["truth.csv", "gyro.csv", "objects.csv"] {
        assert_eq!(
            fs::read(a.join(file)).unwrap(),
            fs::read(ideal.join(file)).unwrap(),
            "{file}"
        );
    }
    assert_eq!(
        common::entries(&a),
        [
            "exposure.csv",
            "frames",
            "gyro.csv",
            "objects.csv",
            "truth.csv"
        ]
    );
}

/// The standard deviation of `noisy - clean` over the pixels whose clean grey level is within
/// `range`, and that level's mean.
fn noise_in(clean: &Frame, noisy: &Frame, range: std::ops::Range<f64>) -> (f64, f64) {
    let (mut levels, mut residuals) = (Vec::new(), Vec::new());
    for (c, n) in values(clean).into_iter().zip(values(noisy)) {
        if range.contains(&c) {
            levels.push(c);
            residuals.push(n - c);
        }
    }
    assert!(
        residuals.len() > 500,
        "{range:?}: {} pixels",
        residuals.len()
    );
    (std_dev(&residuals), mean(&levels))
}

#[test]
fn under_light_the_noise_grows_with_brightness_and_as_the_light_falls() {
    let scratch = Scratch::new("synth-light");
    let clean = frame(&synth(&scratch, "clean", &small(&["--frames", "2"])), 1);
    let noisy = |lux: &'static str| {
        frame(
            &synth(&scratch, lux, &small(&["--frames", "2", "--light", lux])),
            1,
        )
    };
    // At 50 lux, within 8% of the model (its variance plus 1/12 for rounding) at every level.
    let lit = noisy("50");
    let mut previous = 0.0;
    for range in [20.0..70.0, 90.0..140.0, 170.0..230.0] {
        let (sigma, level) = noise_in(&clean, &lit, range.clone());
        let modelled = (Light::new(50.0).noise_at(level).powi(2) + 1.0 / 12.0).sqrt();
        assert!(
            (sigma / modelled - 1.0).abs() < 0.08,
            "{range:?}: {sigma} vs {modelled}"
        );
        assert!(
            sigma > previous * 1.2,
            "{range:?}: {sigma} after {previous}"
        );
        previous = sigma;
    }
    // At mid grey: a hundred times less light, about ten times the noise; the model says 11.6
    // with the read noise, measured 11.8 (2.41 grey levels at 500 lux, 28.4 at 5).
    let mid = |lux| noise_in(&clean, &noisy(lux), 100.0..140.0).0;
    let (bright, dim, dark) = (mid("500"), mid("50"), mid("5"));
    assert!(bright < dim && dim < dark, "{bright} {dim} {dark}");
    assert!((10.0..13.5).contains(&(dark / bright)), "{dark} / {bright}");
}

/// The mean squared change of `frame` one pixel along the unit direction `u` (bilinear): the
/// energy of its gradient that way, which a blur along `u` takes away (a plain mean of absolute
/// changes would not see it spread an edge).
fn contrast_along(frame: &Frame, u: (f64, f64)) -> f64 {
    let at = |x: f64, y: f64| {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let p = |i: f64, j: f64| f64::from(frame.at(i as usize, j as usize));
        let top = p(x0, y0) + fx * (p(x0 + 1.0, y0) - p(x0, y0));
        let bottom = p(x0, y0 + 1.0) + fx * (p(x0 + 1.0, y0 + 1.0) - p(x0, y0 + 1.0));
        top + fy * (bottom - top)
    };
    let mut diffs = Vec::new();
    for y in 4..frame.height - 4 {
        for x in 4..frame.width - 4 {
            let (x, y) = (x as f64, y as f64);
            diffs.push((at(x + u.0, y + u.1) - at(x, y)).powi(2));
        }
    }
    mean(&diffs)
}

/// Row `k` of truth.csv: the homography from frame k - 1 to frame k.
fn truth(dir: &Path, k: usize) -> Homography {
    let text = fs::read_to_string(dir.join("truth.csv")).unwrap();
    let row: Vec<f64> = text
        .lines()
        .nth(k)
        .unwrap()
        .split(',')
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect();
    Homography {
        m: [
            [row[0], row[1], row[2]],
            [row[3], row[4], row[5]],
            [row[6], row[7], row[8]],
        ],
    }
}

#[test]
fn an_exposure_blurs_along_the_motion_centred_on_the_frame_instant() {
    let scratch = Scratch::new("synth-blur");
    let args = [
        "--frames", "3", "--path", "pan", "--seed", "3", "--noise", "0",
    ];
    let sharp = synth(&scratch, "sharp", &args);
    let blurred = synth(
        &scratch,
        "blurred",
        &[args.as_slice(), &["--exposure", "33"]].concat(),
    );
    // The pan moves the image 6.3 px per frame, so an exposure of nearly a frame blurs it over
    // about 6 px: the gradient's energy along the motion halves, across it falls by a quarter.
    let shift = truth(&sharp, 1).apply(0.0, 0.0);
    let length = shift.0.hypot(shift.1);
    assert!(length > 5.0, "the pan moves {length} px per frame");
    let along = (shift.0 / length, shift.1 / length);
    let across = (-along.1, along.0);
    let kept = |u| contrast_along(&frame(&blurred, 1), u) / contrast_along(&frame(&sharp, 1), u);
    let (kept_along, kept_across) = (kept(along), kept(across));
    assert!(
        kept_along < 0.75 * kept_across,
        "along {kept_along}, across {kept_across}"
    );
    // Centred on frame 1's instant: as far from frame 0 as from frame 2, nearest frame 1.
    let blur = frame(&blurred, 1);
    let [before, now, after] = [0, 1, 2].map(|k| mean_abs_diff(&blur, &frame(&sharp, k)));
    assert!(now < 0.5 * before.min(after), "{before} {now} {after}");
    assert!((before / after - 1.0).abs() < 0.15, "{before} {after}");
}

/// Row `row` of a frame.
fn row(frame: &Frame, row: usize) -> &[u8] {
    &frame.data[row * frame.width..(row + 1) * frame.width]
}

#[test]
fn a_rolling_shutter_reads_the_first_row_at_the_frame_instant_and_later_rows_later() {
    let scratch = Scratch::new("synth-rolling");
    let args = small(&["--frames", "3", "--path", "pan", "--seed", "3"]);
    let global = synth(&scratch, "global", &args);
    let rolling = synth(
        &scratch,
        "rolling",
        &[args.as_slice(), &["--rolling-shutter", "30"]].concat(),
    );
    let (g, r) = (frame(&global, 1), frame(&rolling, 1));
    assert_eq!(row(&g, 0), row(&r, 0));
    // The last row is read 0.9 x 119/120 of a frame later: nearer frame 2's last row.
    let last = g.height - 1;
    let next = frame(&global, 2);
    let gap = |a: &[u8], b: &[u8]| {
        a.iter()
            .zip(b)
            .map(|(&p, &q)| (f64::from(p) - f64::from(q)).abs())
            .sum::<f64>()
    };
    assert!(gap(row(&r, last), row(&next, last)) < 0.5 * gap(row(&r, last), row(&g, last)));
}

/// The mean of a frame's `side` x `side` patch whose top-left pixel is (`x`, `y`).
fn patch_mean(frame: &Frame, x: usize, y: usize, side: usize) -> f64 {
    let pixels: Vec<f64> = (y..y + side)
        .flat_map(|j| (x..x + side).map(move |i| (i, j)))
        .map(|(i, j)| f64::from(frame.at(i, j)))
        .collect();
    mean(&pixels)
}

#[test]
fn vignetting_darkens_the_corners_by_its_share() {
    let scratch = Scratch::new("synth-vignetting");
    let args = small(&["--frames", "2"]);
    let plain = frame(&synth(&scratch, "plain", &args), 0);
    let dark = frame(
        &synth(
            &scratch,
            "dark",
            &[args.as_slice(), &["--vignetting", "0.4"]].concat(),
        ),
        0,
    );
    let ratio = |x, y| patch_mean(&dark, x, y, 4) / patch_mean(&plain, x, y, 4);
    for (x, y) in [(0, 0), (156, 0), (0, 116), (156, 116)] {
        // The corner patch's pixels lose 40% at the corner, a little less towards the centre.
        let r = ratio(x, y);
        assert!((0.6..0.65).contains(&r), "corner ({x}, {y}): {r}");
    }
    let centre = ratio(78, 58);
    assert!((centre - 1.0).abs() < 0.01, "centre: {centre}");
}

/// The mean absolute step of `error` between neighbouring columns, at the columns that start
/// an 8-pixel block and at the others.
fn column_steps(error: &[f64], width: usize) -> (f64, f64) {
    let (mut at_edges, mut inside) = (Vec::new(), Vec::new());
    for (i, pair) in error.windows(2).enumerate() {
        let x = (i + 1) % width;
        let step = (pair[1] - pair[0]).abs();
        match x {
            0 => {}
            x if x % 8 == 0 => at_edges.push(step),
            _ => inside.push(step),
        }
    }
    (mean(&at_edges), mean(&inside))
}

#[test]
fn jpeg_leaves_eight_by_eight_blocks_and_more_at_a_lower_quality() {
    let scratch = Scratch::new("synth-jpeg");
    let args = small(&["--frames", "2"]);
    let plain = frame(&synth(&scratch, "plain", &args), 0);
    let at = |q: &'static str| {
        frame(
            &synth(&scratch, q, &[args.as_slice(), &["--jpeg", q]].concat()),
            0,
        )
    };
    let (coarse, fine) = (at("10"), at("95"));
    let error: Vec<f64> = values(&coarse)
        .iter()
        .zip(values(&plain))
        .map(|(c, p)| c - p)
        .collect();
    let (edges, inside) = column_steps(&error, plain.width);
    assert!(edges > 1.5 * inside, "block edges {edges}, inside {inside}");
    let (coarse_error, fine_error) = (mean_abs_diff(&coarse, &plain), mean_abs_diff(&fine, &plain));
    assert!(
        fine_error > 0.0 && coarse_error > 3.0 * fine_error,
        "{coarse_error} {fine_error}"
    );
}

#[test]
fn auto_exposure_steps_gain_and_bias_every_eight_frames() {
    let scratch = Scratch::new("synth-auto-exposure");
    let args = small(&["--frames", "18", "--path", "shake"]);
    let plain = synth(&scratch, "plain", &args);
    let stepped = synth(
        &scratch,
        "stepped",
        &[args.as_slice(), &["--auto-exposure"]].concat(),
    );
    let text = fs::read_to_string(stepped.join("exposure.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "frame,gain,bias");
    assert_eq!(lines.len(), 1 + 18);
    let lighting: Vec<(f64, f64)> = lines[1..]
        .iter()
        .map(|line| {
            let fields: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|v| v.parse().unwrap())
                .collect();
            (fields[0], fields[1])
        })
        .collect();
    assert!(lighting[..8].iter().all(|&l| l == (1.0, 0.0)));
    assert!(lighting[8..16].iter().all(|&l| l == lighting[8]) && lighting[16] != lighting[8]);
    assert!(
        (0.03..=0.08).contains(&(lighting[8].0 - 1.0).abs()),
        "{:?}",
        lighting[8]
    );
    // Each frame is the ideal camera's under its gain and bias, to the rounding of both.
    for (k, &(gain, bias)) in lighting.iter().enumerate() {
        let (p, s) = (values(&frame(&plain, k)), values(&frame(&stepped, k)));
        let worst = p
            .iter()
            .zip(&s)
            .filter(|(&p, _)| (1.0..254.0).contains(&(gain * p + bias)))
            .map(|(p, s)| (gain * p + bias - s).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1.25, "frame {k}: {worst}");
    }
}

/// `frame` warped by `warp` (from its coordinates to the returned frame's), bilinear; pixels
/// whose source lies outside, or within `margin` of its edge, are `None`.
fn warped(frame: &Frame, warp: &Homography, margin: f64) -> Vec<Option<f64>> {
    let back = warp.inverse().unwrap();
    let (w, h) = (frame.width as f64, frame.height as f64);
    let mut out = Vec::new();
    for y in 0..frame.height {
        for x in 0..frame.width {
            let (u, v) = back.apply(x as f64, y as f64);
            let inside =
                u >= margin && v >= margin && u <= w - 1.0 - margin && v <= h - 1.0 - margin;
            out.push(inside.then(|| {
                let (u0, v0) = (u.floor(), v.floor());
                let p = |i: f64, j: f64| f64::from(frame.at(i as usize, j as usize));
                let top = p(u0, v0) + (u - u0) * (p(u0 + 1.0, v0) - p(u0, v0));
                let bottom = p(u0, v0 + 1.0) + (u - u0) * (p(u0 + 1.0, v0 + 1.0) - p(u0, v0 + 1.0));
                top + (v - v0) * (bottom - top)
            }));
        }
    }
    out
}

/// The mean absolute difference between `frame` and `prediction` where it predicts.
fn prediction_error(frame: &Frame, prediction: &[Option<f64>]) -> f64 {
    let diffs: Vec<f64> = values(frame)
        .iter()
        .zip(prediction)
        .filter_map(|(v, p)| p.map(|p| (v - p).abs()))
        .collect();
    assert!(diffs.len() > frame.data.len() / 2);
    mean(&diffs)
}

#[test]
fn a_photograph_is_the_ground_and_the_flight_moves_it_as_truth_csv_says() {
    let scratch = Scratch::new("synth-scene");
    let photo = photograph(&scratch);
    let args = small(&["--frames", "6", "--path", "perspective", "--seed", "2"]);
    let textured = synth(&scratch, "textured", &args);
    let scene = ["--scene", photo.to_str().unwrap()];
    let filmed = synth(&scratch, "filmed", &[args.as_slice(), &scene].concat());
    assert_eq!(
        fs::read(textured.join("truth.csv")).unwrap(),
        fs::read(filmed.join("truth.csv")).unwrap()
    );
    let first = frame(&filmed, 0);
    assert!(mean_abs_diff(&first, &frame(&textured, 0)) > 10.0);
    // Frame 5 is frame 0 carried by the five homographies of truth.csv.
    let warp = (2..=5).fold(truth(&filmed, 1), |h, k| h.then(&truth(&filmed, k)));
    let last = frame(&filmed, 5);
    let carried = prediction_error(&last, &warped(&first, &warp, 1.0));
    let still = prediction_error(&last, &warped(&first, &Homography::IDENTITY, 1.0));
    assert!(
        carried < 2.0 && still > 4.0 * carried,
        "carried {carried}, still {still}"
    );
}

#[test]
fn a_scene_that_is_not_an_image_is_named_and_nothing_is_written() {
    let scratch = Scratch::new("synth-bad-scene");
    let bogus = scratch.path("ground.png");
    fs::write(&bogus, "not a picture").unwrap();
    let (out, output) = run_synth(&scratch, "out", &["--scene", bogus.to_str().unwrap()]);
    let message = assert_one_line_error(&output, 1, "ground.png");
    assert!(
        message.contains("not a PNG, JPEG, PGM or BMP image"),
        "{message}"
    );
    assert!(!out.exists());
    // A JPEG photograph is read like a PNG one.
    let jpeg = scratch.path("ground.jpg");
    let photo = read_grey(&photograph(&scratch)).unwrap();
    let image =
        image::GrayImage::from_raw(photo.width as u32, photo.height as u32, photo.data).unwrap();
    image.save(&jpeg).unwrap();
    synth(
        &scratch,
        "from-jpeg",
        &small(&["--frames", "2", "--scene", jpeg.to_str().unwrap()]),
    );
}

#[test]
fn camera_flags_out_of_range_or_against_each_other_are_usage_errors() {
    let scratch = Scratch::new("synth-usage");
    let cases: [(&[&str], &str); 9] = [
        (
            &["--exposure", "40"],
            "--exposure: must not exceed the frame interval, 33.333 ms at --fps 30 (got 40)",
        ),
        (
            &["--fps", "50", "--rolling-shutter", "25"],
            "--rolling-shutter: must not exceed the frame interval, 20.000 ms at --fps 50 (got 25)",
        ),
        (&["--read-noise", "2"], "--read-noise: needs --light"),
        (
            &["--light", "0"],
            "--light: must be between 0.01 and 100000 lux (got 0)",
        ),
        (
            &["--vignetting", "1.5"],
            "--vignetting: must be between 0 and 1 (got 1.5)",
        ),
        (
            &["--jpeg", "0"],
            "--jpeg: must be between 1 and 100 (got 0)",
        ),
        (
            &["--downscale", "9"],
            "--downscale: must be between 1 and 8 (got 9)",
        ),
        (
            &["--exposure", "0"],
            "--exposure: must be more than 0 and at most 1000 ms (got 0)",
        ),
        (&["--auto-exposure=1"], "--auto-exposure: takes no value"),
    ];
    for (args, says) in cases {
        let (out, output) = run_synth(&scratch, "out", args);
        let message = assert_one_line_error(&output, 2, says);
        assert!(!out.exists(), "{args:?} wrote {out:?}: {message}");
    }
}
