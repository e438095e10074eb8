//! The `egomotion` command line: its flags, their rules, and its usage text.

use std::ffi::OsString;

use kestrel::ego::camera::FOCAL_RANGE;
use kestrel::ego::ModelKind;

use super::args::{parse, Flag, Matches, Parsed, Rule, UsageError};
use crate::commands::egomotion::EgomotionOptions;
use crate::egomotion::{
    EstimatorSettings, MavlinkDestination, DEFAULT_MAX_POINTS, DEFAULT_THRESHOLD,
};

/// The usage text of `host-sim egomotion --help`.
pub const USAGE: &str = "\
host-sim egomotion: the camera's motion between consecutive frames, and the autopilot's
MAVLink stream.

Usage: host-sim egomotion INPUT --out ego.csv [options]

Per frame pair: Shi-Tomasi corners in the earlier frame, spread by a grid; the library's Q16
pyramidal Lucas-Kanade to the later frame (seeded by the gyro's prediction with --gyro); the
motion model fitted by RANSAC; the OPTICAL_FLOW_RAD reading of the pair's interval.

Input:
  INPUT             a directory of frames (PNG, JPEG, PGM or BMP, in file-name order), a .y4m
                    file, or - for y4m on standard input

Options:
  --out ego.csv     results, one row per frame pair (see below)
  --model M         translation, similarity, affine or homography [default: homography]
  --focal PX        focal length in px, 1 to 100000 [default: that of a 60 degree horizontal
                    field of view; the principal point is the frame centre]
  --gyro G.csv      gyro log: columns t_us,gx,gy,gz; time in microseconds on the frames' clock
                    (frame k at k / fps s), body rates in rad/s about the sensor axes (X to the
                    top of the image, Y to its right, Z along the optical axis), linear between
                    samples. Intervals the log does not cover have no gyro reading.
  --mavlink DEST    MAVLink 2 stream: per frame pair OPTICAL_FLOW_RAD (id 106, read by PX4)
                    and OPTICAL_FLOW (id 100, read by ArduPilot), after a HEARTBEAT at each
                    new second of the frame clock; system 1, component 100, one sequence
                    from 0. DEST is a file (raw bytes, back to back) or udp:HOST:PORT
                    (datagrams to a listener, like MAVProxy's or QGroundControl's udpout; a
                    listener that is missing or stops costs nothing, failed sends are counted
                    on stderr at the end)
  --rate HZ         pace the replay in real time at HZ frame pairs per second, 0.1 to 10000
                    [default: as fast as it can]
  --fps F           frame rate, 1 to 10000 [default: the y4m header's, else 30]
  --max-points N    points tracked per pair, 8 to 2000 [default: 200; 25 with --preset]
  --window N        LK window side, odd, 3 to 63 [default: 21; 7 with --preset flow-sensor]
  --levels L        coarsest pyramid level LK searches, 0 to 7 [default: 3; 1 with the preset]
  --illumination M  plain or gain-bias [default: gain-bias]
  --preset NAME     flow-sensor: the LK settings and pyramid of the library's
                    TrackerConfig::flow_sensor() (7x7 windows on two levels of a box-mean
                    pyramid, nearest-pixel templates, 10 iterations) and its 25 points;
                    flags given beside it override it [default: none, OpenCV's LK settings]
  --threshold PX    RANSAC inlier threshold, 0.05 to 100 px; raise it for blurred or noisy
                    video [default: 0.5]
  --stats S.json    write {\"frames\", \"pairs\", \"mean_tracked_points\",
                    \"median_pair_seconds\", \"mean_pair_seconds\"}; per pair the new frame's
                    pyramid, detection, tracking and the fit are timed, decoding is not
  -h, --help        print this help

ego.csv columns:
  frame            the later frame of the pair (1, 2, ...)
  h11..h33         the homography from pixels of frame-1 to pixels of frame, row-major,
                   h33 = 1; the identity when the fit failed
  inliers          tracked points within --threshold of the model (0 when the fit failed)
  quality          0..255 as in OPTICAL_FLOW_RAD: 0 when the fit failed or the gyro reading
                   was unusable (then the fitted homography is still given)
  tracked          points tracked from frame-1 to frame, fitted by RANSAC
  rms              RMS inlier residual, px
  integrated_x,y   OPTICAL_FLOW_RAD angular flow over the interval, rad (0 when quality is 0)
  status           ok, too_few_tracks, degenerate, no_consensus, bad_input or bad_gyro

Coordinates are pixels from the centre of the top-left pixel, x right, y down. A bad frame
stops the run; the rows (and MAVLink frames) of the pairs before it are kept.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line.
";

const FLAGS: &[Flag] = &[
    Flag::value("--out"),
    Flag::value("--model"),
    Flag::value("--focal"),
    Flag::value("--gyro"),
    Flag::value("--mavlink"),
    Flag::value("--rate"),
    Flag::value("--fps"),
    Flag::value("--max-points"),
    Flag::value("--preset"),
    Flag::value("--window"),
    Flag::value("--levels"),
    Flag::value("--illumination"),
    Flag::value("--threshold"),
    Flag::value("--stats"),
];

const FOCAL: Rule<f64> = Rule {
    accepts: |f| FOCAL_RANGE.contains(&(f as f32)) && f.is_finite(),
    says: "must be a focal length between 1 and 100000 px",
};
pub(crate) const FPS: Rule<f64> = Rule {
    accepts: |f| (1.0..=10_000.0).contains(&f),
    says: "must be between 1 and 10000 frames per second",
};
const RATE: Rule<f64> = Rule {
    accepts: |r| (0.1..=10_000.0).contains(&r),
    says: "must be between 0.1 and 10000 frame pairs per second",
};
pub(crate) const THRESHOLD: Rule<f64> = Rule {
    accepts: |t| (0.05..=100.0).contains(&t),
    says: "must be between 0.05 and 100 px",
};
pub(crate) const MAX_POINTS: Rule<i64> = Rule {
    accepts: |n| (8..=2000).contains(&n),
    says: "must be between 8 and 2000",
};

/// Parses the words after `egomotion`; `None` means help was asked for.
pub fn parse_options(args: &[OsString]) -> Result<Option<EgomotionOptions>, UsageError> {
    match parse(args, FLAGS, 1)? {
        Parsed::Help => Ok(None),
        Parsed::Flags(matches) => options(&matches).map(Some),
    }
}

fn options(matches: &Matches) -> Result<EgomotionOptions, UsageError> {
    let input = required_input(matches)?;
    let out = matches.required_path("--out")?;
    let focal = match matches.value("--focal") {
        Some(_) => Some(matches.number("--focal", 0.0, FOCAL)? as f32),
        None => None,
    };
    let mut settings = EstimatorSettings {
        model: model(matches, ModelKind::Homography)?,
        focal,
        ..measurement(matches)?
    };
    if let Some(preset) = super::track::preset(matches)? {
        let config = preset.config(None);
        settings.lk = config.lk;
        settings.pyramid = config.pyramid;
        if matches.value("--max-points").is_none() {
            settings.max_points = config.max_tracks;
        }
    }
    settings.lk = super::track::settings(matches)?.apply_lk(settings.lk);
    Ok(EgomotionOptions {
        input,
        out,
        settings,
        gyro: matches.path("--gyro"),
        mavlink: mavlink(matches)?,
        rate: match matches.value("--rate") {
            Some(_) => Some(matches.number("--rate", 0.0, RATE)?),
            None => None,
        },
        fps: optional_fps(matches)?,
        stats: matches.path("--stats"),
    })
}

/// `--mavlink`: a file path, or `udp:HOST:PORT`.
fn mavlink(matches: &Matches) -> Result<Option<MavlinkDestination>, UsageError> {
    match matches.value("--mavlink") {
        None => Ok(None),
        Some(text) if text.is_empty() => Err(UsageError::new("--mavlink", "must not be empty")),
        Some(text) => MavlinkDestination::parse(text)
            .map(Some)
            .map_err(|problem| UsageError::new("--mavlink", problem)),
    }
}

/// The settings `egomotion` and `stabilize` share: `--max-points` and `--threshold`.
pub(crate) fn measurement(matches: &Matches) -> Result<EstimatorSettings, UsageError> {
    // Range-checked by their rules.
    let max_points = matches.integer("--max-points", DEFAULT_MAX_POINTS as i64, MAX_POINTS)?;
    let threshold = matches.number("--threshold", f64::from(DEFAULT_THRESHOLD), THRESHOLD)?;
    Ok(EstimatorSettings {
        max_points: max_points as usize,
        threshold: threshold as f32,
        ..EstimatorSettings::default()
    })
}

/// The INPUT positional argument, which must be present.
pub(crate) fn required_input(matches: &Matches) -> Result<OsString, UsageError> {
    match matches.positionals().first() {
        Some(input) if !input.is_empty() => Ok(input.clone()),
        _ => Err(UsageError::new(
            "INPUT",
            "is required: a directory of frames, a .y4m file, or - for standard input",
        )),
    }
}

/// `--fps`, when given.
pub(crate) fn optional_fps(matches: &Matches) -> Result<Option<f64>, UsageError> {
    match matches.value("--fps") {
        Some(_) => matches.number("--fps", 0.0, FPS).map(Some),
        None => Ok(None),
    }
}

/// The motion model named by `--model`, or `default`.
pub(crate) fn model(matches: &Matches, default: ModelKind) -> Result<ModelKind, UsageError> {
    match matches.value("--model").map(|v| v.to_string_lossy()) {
        None => Ok(default),
        Some(name) => match name.as_ref() {
            "translation" => Ok(ModelKind::Translation),
            "similarity" => Ok(ModelKind::Similarity),
            "affine" => Ok(ModelKind::Affine),
            "homography" => Ok(ModelKind::Homography),
            _ => Err(UsageError::new(
                "--model",
                format!("must be translation, similarity, affine or homography (got \"{name}\")"),
            )),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(line: &str) -> Result<Option<EgomotionOptions>, UsageError> {
        let words: Vec<OsString> = line.split_whitespace().map(OsString::from).collect();
        parse_options(&words)
    }

    fn error(line: &str) -> String {
        parsed(line).unwrap_err().to_string()
    }

    #[test]
    fn defaults() {
        let options = parsed("clip.y4m --out ego.csv").unwrap().unwrap();
        assert_eq!(options.input, OsString::from("clip.y4m"));
        assert_eq!(options.settings, EstimatorSettings::default());
        assert_eq!(
            (options.gyro, options.mavlink, options.fps, options.rate),
            (None, None, None, None)
        );
    }

    #[test]
    fn every_option_is_read() {
        let line = "- --out e.csv --model affine --focal 200.5 --gyro g.csv --mavlink m.bin \
                    --fps 60 --max-points 50 --threshold 0.8 --stats s.json";
        let options = parsed(line).unwrap().unwrap();
        assert_eq!(options.input, OsString::from("-"));
        assert_eq!(
            options.settings,
            EstimatorSettings {
                model: ModelKind::Affine,
                focal: Some(200.5),
                max_points: 50,
                threshold: 0.8,
                ..EstimatorSettings::default()
            }
        );
        assert_eq!(options.fps, Some(60.0));
        let preset = parsed("- --out e.csv --preset flow-sensor")
            .unwrap()
            .unwrap();
        let sensor = kestrel::track::TrackerConfig::flow_sensor();
        assert_eq!(preset.settings.lk, sensor.lk);
        assert_eq!(preset.settings.max_points, 25);
        let wider = parsed("- --out e.csv --preset flow-sensor --max-points 60")
            .unwrap()
            .unwrap();
        assert_eq!(wider.settings.max_points, 60);
        let narrower = parsed("- --out e.csv --preset flow-sensor --window 9 --levels 2")
            .unwrap()
            .unwrap();
        assert_eq!(
            (narrower.settings.lk.window, narrower.settings.lk.max_level),
            (9, 2)
        );
        assert_eq!(narrower.settings.lk.template, sensor.lk.template);
        assert!(options.gyro.is_some() && options.mavlink.is_some() && options.stats.is_some());
    }

    #[test]
    fn mavlink_takes_a_file_or_a_udp_listener() {
        let file = parsed("d --out e.csv --mavlink m.bin").unwrap().unwrap();
        assert_eq!(file.mavlink, Some(MavlinkDestination::File("m.bin".into())));
        let udp = parsed("d --out e.csv --mavlink udp:localhost:14550 --rate 30")
            .unwrap()
            .unwrap();
        let expected = MavlinkDestination::Udp {
            host: "localhost".into(),
            port: 14550,
        };
        assert_eq!((udp.mavlink, udp.rate), (Some(expected), Some(30.0)));
        assert!(error("d --out e.csv --mavlink udp:").starts_with("--mavlink: a UDP destination"));
        assert!(error("d --out e.csv --mavlink udp:host:0").starts_with("--mavlink: the port"));
        assert!(error("d --out e.csv --rate 0").starts_with("--rate: must be between"));
    }

    #[test]
    fn bad_values_name_the_flag() {
        assert_eq!(
            error("d --out e.csv --model rigid"),
            "--model: must be translation, similarity, affine or homography (got \"rigid\")"
        );
        assert_eq!(
            error("d --out e.csv --focal 0"),
            "--focal: must be a focal length between 1 and 100000 px (got 0)"
        );
        assert_eq!(
            error("d --out e.csv --focal nan"),
            "--focal: must be a focal length between 1 and 100000 px (got NaN)"
        );
        assert_eq!(
            error("d --out e.csv --focal abc"),
            "--focal: expected a number (got \"abc\")"
        );
        assert!(error("d --out e.csv --fps 0").starts_with("--fps: must be between 1"));
        assert!(error("d --out e.csv --max-points 3").starts_with("--max-points: must be"));
        assert!(error("d --out e.csv --threshold 0").starts_with("--threshold: must be"));
        assert!(error("--out e.csv").starts_with("INPUT: is required"));
        assert!(error("d").starts_with("--out: is required"));
        assert!(error("a b --out e.csv").starts_with("'b': unexpected argument"));
    }
}
