//! Runs `host-sim egomotion`, `stabilize` and `synth-sequence` on seeded synthetic flights and
//! checks them against the exact camera motion, and the command-line contract on bad input.
//!
//! The frames are rendered here with `host_sim::synth` (or by `synth-sequence` where that
//! command is under test) and written as PNG files into a scratch directory.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use host_sim::io::images::write_png;
use host_sim::synth::{FlightPath, FlightSequence, Homography, SceneSpec};
use host_sim::Frame;

/// A directory for one test's files, removed when the test ends.
struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("host-sim-ego-{test}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        Self { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Writes `frames` as `frames/frame_NNNNN.png` and returns the directory.
    fn frames(&self, frames: impl IntoIterator<Item = Frame>) -> PathBuf {
        let dir = self.path("frames");
        fs::create_dir_all(&dir).unwrap();
        for (k, frame) in frames.into_iter().enumerate() {
            write_png(&dir.join(format!("frame_{k:05}.png")), &frame).unwrap();
        }
        dir
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.dir);
    }
}

fn host_sim(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args.iter().map(|a| a.as_ref()))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap()
}

fn assert_success(output: &Output) {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.stdout.is_empty() && output.stderr.is_empty());
}

/// Checks the error contract: exit `code`, exactly one stderr line starting `host-sim: ` and
/// naming every culprit, nothing on stdout, no panic or backtrace.
fn assert_one_line_error(output: &Output, code: i32, culprits: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(code), "stderr: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "not one line: {stderr:?}");
    assert!(stderr.starts_with("host-sim: "), "{stderr:?}");
    for culprit in culprits {
        assert!(
            stderr.contains(culprit),
            "{stderr:?} does not name {culprit:?}"
        );
    }
    let lower = stderr.to_lowercase();
    assert!(!lower.contains("panicked") && !lower.contains("backtrace"));
    assert!(output.stdout.is_empty());
    stderr
}

/// One row of ego.csv.
#[derive(Debug, Clone)]
struct EgoRow {
    frame: usize,
    h: Homography,
    inliers: usize,
    quality: u8,
    tracked: usize,
    integrated_x: f64,
    status: String,
}

fn read_ego(path: &Path) -> Vec<EgoRow> {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "frame,h11,h12,h13,h21,h22,h23,h31,h32,h33,inliers,quality,\
             tracked,rms,integrated_x,integrated_y,status"
        )
    );
    lines
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 17, "{line}");
            let number = |i: usize| -> f64 {
                let v: f64 = f[i].parse().unwrap_or_else(|_| panic!("{line}"));
                assert!(v.is_finite(), "{line}");
                v
            };
            let h: [f64; 9] = std::array::from_fn(|i| number(i + 1));
            assert_eq!(h[8], 1.0, "{line}");
            EgoRow {
                frame: f[0].parse().unwrap(),
                h: Homography {
                    m: [[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], h[8]]],
                },
                inliers: f[10].parse().unwrap(),
                quality: f[11].parse().unwrap(),
                tracked: f[12].parse().unwrap(),
                integrated_x: number(14),
                status: f[16].to_owned(),
            }
        })
        .collect()
}

/// The mean distance between the images of the four frame corners under `a` and `b`.
fn corner_error(a: &Homography, b: &Homography, width: usize, height: usize) -> f64 {
    let (w, h) = (width as f64 - 1.0, height as f64 - 1.0);
    let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)];
    corners
        .iter()
        .map(|&(x, y)| {
            let (p, q) = (a.apply(x, y), b.apply(x, y));
            (p.0 - q.0).hypot(p.1 - q.1)
        })
        .sum::<f64>()
        / 4.0
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Renders `frames` frames of a flight and runs `egomotion` on them with `extra` flags.
fn egomotion_on_flight(
    scratch: &Scratch,
    sequence: &FlightSequence,
    frames: usize,
    extra: &[&dyn AsRef<std::ffi::OsStr>],
) -> Vec<EgoRow> {
    let input = scratch.frames((0..frames).map(|k| sequence.frame(k)));
    let out = scratch.path("ego.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"egomotion", &input, &"--out", &out];
    args.extend_from_slice(extra);
    assert_success(&host_sim(&args));
    let rows = read_ego(&out);
    assert_eq!(rows.len(), frames - 1);
    rows
}

/// The corner error of every row against the flight's exact motion.
fn corner_errors(rows: &[EgoRow], sequence: &FlightSequence, size: (usize, usize)) -> Vec<f64> {
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            assert_eq!(row.frame, i + 1);
            let truth = sequence.flight().pair_homography(row.frame);
            corner_error(&row.h, &truth, size.0, size.1)
        })
        .collect()
}

/// Per path, the median corner error over its frame pairs must be within half a pixel; over
/// all pairs of the four paths, within the budget for the library's fit on synthetic
/// tracks (0.2 px at 160x120, 0.1 px at 320x240), here with real frames, detection and LK.
#[test]
fn homographies_move_the_corners_within_half_a_pixel() {
    let mut report = String::from("egomotion, corner error against the exact motion:");
    for (width, height, budget) in [(160, 120, 0.2), (320, 240, 0.1)] {
        let mut all_pairs = Vec::new();
        for path in [
            FlightPath::Pan,
            FlightPath::Yaw,
            FlightPath::Climb,
            FlightPath::Perspective,
        ] {
            let scratch = Scratch::new(&format!("corners-{}-{width}", path.name()));
            let spec = SceneSpec::new(width, height, 11).with_noise(1.0);
            // Two independently moving objects: 20-30% of the tracks are outliers.
            let sequence = FlightSequence::new(spec, path, 2);
            let rows = egomotion_on_flight(&scratch, &sequence, 8, &[]);
            let errors = corner_errors(&rows, &sequence, (width, height));
            let error = median(errors.clone());
            all_pairs.extend(errors);
            let inliers: usize = rows.iter().map(|r| r.inliers).sum();
            report += &format!(
                "\n  {width}x{height} {:<12} median {error:.3} px, quality {}..{}, {} inliers per pair",
                path.name(),
                rows.iter().map(|r| r.quality).min().unwrap(),
                rows.iter().map(|r| r.quality).max().unwrap(),
                inliers / rows.len(),
            );
            assert!(error < 0.5, "{path:?} at {width}x{height}: {error:.3} px");
            assert!(rows.iter().all(|r| r.quality > 0 && r.status == "ok"));
        }
        let pooled = median(all_pairs);
        report += &format!("\n  {width}x{height} all paths: median {pooled:.3} px");
        assert!(pooled < budget, "{width}x{height}: {pooled:.3} px");
    }
    println!("{report}");
}

#[test]
fn the_translation_model_recovers_a_pure_pan() {
    let scratch = Scratch::new("pan");
    let spec = SceneSpec::new(160, 120, 5).with_noise(1.0);
    let sequence = FlightSequence::new(spec, FlightPath::Pan, 0);
    let rows = egomotion_on_flight(&scratch, &sequence, 5, &[&"--model", &"translation"]);
    let truth = sequence.flight().pair_homography(1).m;
    for row in &rows {
        let m = row.h.m;
        assert_eq!((m[0][0], m[0][1], m[1][0], m[1][1]), (1.0, 0.0, 0.0, 1.0));
        assert_eq!((m[2][0], m[2][1]), (0.0, 0.0));
        let (dx, dy) = (m[0][2] - truth[0][2], m[1][2] - truth[1][2]);
        println!(
            "pan ({:.3}, {:.3}) px: measured ({:.3}, {:.3})",
            truth[0][2], truth[1][2], m[0][2], m[1][2]
        );
        assert!(dx.abs() < 0.1 && dy.abs() < 0.1, "{row:?}");
    }
}

/// A synthetic flight written by `synth-sequence`, with its truth and gyro log.
fn synth_sequence(scratch: &Scratch, path: &str, frames: usize, size: (usize, usize)) -> PathBuf {
    let out = scratch.path("flight");
    let output = host_sim(&[
        &"synth-sequence",
        &"--out",
        &out,
        &"--path",
        &path,
        &"--frames",
        &frames.to_string(),
        &"--width",
        &size.0.to_string(),
        &"--height",
        &size.1.to_string(),
        &"--seed",
        &"3",
    ]);
    assert_success(&output);
    out
}

fn read_truth(path: &Path) -> Vec<Homography> {
    let text = fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|f| f.parse().unwrap())
                .collect();
            Homography {
                m: [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]],
            }
        })
        .collect()
}

#[test]
fn an_exact_gyro_keeps_pure_rotation_rows_correct() {
    let scratch = Scratch::new("gyro");
    let flight = synth_sequence(&scratch, "rotation", 8, (160, 120));
    let (frames, gyro) = (flight.join("frames"), flight.join("gyro.csv"));
    let (out, mavlink) = (scratch.path("ego.csv"), scratch.path("flow.bin"));
    let output = host_sim(&[
        &"egomotion",
        &frames,
        &"--out",
        &out,
        &"--gyro",
        &gyro,
        &"--mavlink",
        &mavlink,
    ]);
    assert_success(&output);
    let rows = read_ego(&out);
    let truth = read_truth(&flight.join("truth.csv"));
    assert_eq!(rows.len(), truth.len());
    let errors: Vec<f64> = rows
        .iter()
        .zip(&truth)
        .map(|(row, truth)| corner_error(&row.h, truth, 160, 120))
        .collect();
    let error = median(errors);
    // The gyro log's first sample: the constant rates.
    let gyro_text = fs::read_to_string(&gyro).unwrap();
    let rates: Vec<f64> = gyro_text
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .skip(1)
        .map(|f| f.parse().unwrap())
        .collect();
    let roll_per_frame = rates[0] / 30.0;
    let flow_x = median(rows.iter().map(|r| r.integrated_x).collect());
    println!(
        "rotation with gyro: corner error median {error:.3} px; integrated_x {flow_x:.5} rad per \
         frame, gyro {roll_per_frame:.5} rad"
    );
    assert!(error < 0.5, "{error:.3} px");
    assert!(rows.iter().all(|r| r.quality > 0 && r.status == "ok"));
    // Under pure rotation the flow about X is the roll the gyro measured.
    assert!(
        (flow_x - roll_per_frame).abs() < 0.1 * roll_per_frame.abs(),
        "{flow_x} {roll_per_frame}"
    );

    // A HEARTBEAT, then OPTICAL_FLOW_RAD and OPTICAL_FLOW per pair; one sequence from 0.
    let bytes = fs::read(&mavlink).unwrap();
    let frames = mavlink_frames(&bytes);
    assert_eq!(frames.len(), 1 + 2 * rows.len());
    for (sequence, frame) in frames.iter().enumerate() {
        assert_eq!(frame[0], 0xFD);
        assert_eq!(
            (usize::from(frame[4]), frame[5], frame[6]),
            (sequence, 1, 100)
        );
    }
    assert_eq!(message_id(frames[0]), 0);
    for (pair, row) in frames[1..].chunks(2).zip(&rows) {
        let (rad, flow) = (pair[0], pair[1]);
        assert_eq!((message_id(rad), message_id(flow)), (106, 100));
        // integrated_xgyro is the fifth payload field, after an u64, an u32 and two f32.
        let xgyro = f32::from_le_bytes(rad[10 + 20..10 + 24].try_into().unwrap());
        assert!((f64::from(xgyro) - roll_per_frame).abs() < 1e-4, "{xgyro}");
        // Quality is the last payload byte of OPTICAL_FLOW_RAD (when not trimmed as zero),
        // byte 25 of OPTICAL_FLOW's.
        assert_eq!((rad[10 + 43], flow[10 + 25]), (row.quality, row.quality));
        // flow_rate_x (bytes 26..30) is integrated_x per second, at 30 frames per second.
        let rate_x = f32::from_le_bytes(flow[10 + 26..10 + 30].try_into().unwrap());
        let integrated_x = f32::from_le_bytes(rad[10 + 12..10 + 16].try_into().unwrap());
        let seconds = u32::from_le_bytes(rad[18..22].try_into().unwrap()) as f32 * 1e-6;
        assert!((rate_x - integrated_x / seconds).abs() < 1e-5, "{rate_x}");
    }
}

/// Splits a MAVLink 2 byte stream into its (unsigned) frames.
fn mavlink_frames(bytes: &[u8]) -> Vec<&[u8]> {
    let mut frames = Vec::new();
    let mut offset = 0;
    while offset < bytes.len() {
        let len = 12 + usize::from(bytes[offset + 1]);
        frames.push(&bytes[offset..offset + len]);
        offset += len;
    }
    assert_eq!(offset, bytes.len(), "the last frame is cut");
    frames
}

/// A MAVLink 2 frame's message id.
fn message_id(frame: &[u8]) -> u32 {
    u32::from_le_bytes([frame[7], frame[8], frame[9], 0])
}

#[test]
fn the_frame_rate_comes_from_the_y4m_header_unless_given() {
    let scratch = Scratch::new("fps");
    let spec = SceneSpec::new(64, 48, 2).with_noise(1.0);
    let sequence = FlightSequence::new(spec, FlightPath::Pan, 0);
    let mut y4m = b"YUV4MPEG2 W64 H48 F60:1 Cmono\n".to_vec();
    for k in 0..3 {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend_from_slice(&sequence.frame(k).data);
    }
    let clip = scratch.path("clip.y4m");
    fs::write(&clip, y4m).unwrap();
    let (out, mavlink) = (scratch.path("ego.csv"), scratch.path("flow.bin"));
    let integration_times = |extra: &[&dyn AsRef<std::ffi::OsStr>]| {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&"egomotion", &clip, &"--out", &out, &"--mavlink", &mavlink];
        args.extend_from_slice(extra);
        assert_success(&host_sim(&args));
        let bytes = fs::read(&mavlink).unwrap();
        mavlink_frames(&bytes)
            .into_iter()
            .filter(|frame| message_id(frame) == 106)
            .map(|frame| u32::from_le_bytes(frame[18..22].try_into().unwrap()))
            .collect::<Vec<_>>()
    };
    assert_eq!(integration_times(&[]), [16_667, 16_666]);
    assert_eq!(integration_times(&[&"--fps", &"25"]), [40_000, 40_000]);
}

/// A still camera over a textureless floor: nothing to track.
#[test]
fn frames_without_texture_give_quality_zero_and_the_identity() {
    let scratch = Scratch::new("flat");
    let input = scratch.frames((0..3).map(|_| Frame::filled(64, 48, 90)));
    let out = scratch.path("ego.csv");
    assert_success(&host_sim(&[&"egomotion", &input, &"--out", &out]));
    let rows = read_ego(&out);
    assert_eq!(rows.len(), 2);
    for row in rows {
        assert_eq!(
            (row.quality, row.inliers, row.status.as_str()),
            (0, 0, "too_few_tracks")
        );
        assert_eq!(row.h, Homography::IDENTITY);
    }
}

/// Writes `rows` as a gyro log, each `t_us,gx,gy,gz`.
fn gyro_log(scratch: &Scratch, rows: &[&str]) -> PathBuf {
    let path = scratch.path("gyro.csv");
    fs::write(&path, format!("t_us,gx,gy,gz\n{}\n", rows.join("\n"))).unwrap();
    path
}

fn pan_frames(scratch: &Scratch, frames: usize) -> PathBuf {
    let spec = SceneSpec::new(96, 72, 8).with_noise(1.0);
    let sequence = FlightSequence::new(spec, FlightPath::Pan, 0);
    scratch.frames((0..frames).map(|k| sequence.frame(k)))
}

#[test]
fn a_malformed_gyro_log_names_line_and_column_and_writes_nothing() {
    let scratch = Scratch::new("badgyro");
    let input = pan_frames(&scratch, 2);
    let out = scratch.path("ego.csv");
    let cases: [(&[&str], &[&str]); 3] = [
        (
            &["0,0,0,0", "20000,0,zero,0"],
            &[
                "gyro.csv",
                "line 3, column 3 (gy)",
                "\"zero\" is not a number",
            ],
        ),
        (
            &["0,0,0,0", "0,0,0,0"],
            &["gyro.csv", "line 3, column 1 (t_us)", "times must increase"],
        ),
        (&["0,0,0"], &["gyro.csv", "line 2", "expected 4 fields"]),
    ];
    for (rows, culprits) in cases {
        let gyro = gyro_log(&scratch, rows);
        let output = host_sim(&[&"egomotion", &input, &"--out", &out, &"--gyro", &gyro]);
        assert_one_line_error(&output, 1, culprits);
        assert!(!out.exists());
    }
    fs::write(scratch.path("gyro.csv"), "time,gx,gy,gz\n0,0,0,0\n").unwrap();
    let output = host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--gyro",
        &scratch.path("gyro.csv"),
    ]);
    assert_one_line_error(&output, 1, &["gyro.csv", "line 1", "t_us,gx,gy,gz"]);
    let missing = scratch.path("none.csv");
    let output = host_sim(&[&"egomotion", &input, &"--out", &out, &"--gyro", &missing]);
    assert_one_line_error(&output, 1, &["none.csv", "no such file"]);
    assert!(!out.exists());
}

#[test]
fn nan_and_absurd_gyro_values_give_quality_zero_for_their_frames_only() {
    let scratch = Scratch::new("nangyro");
    let input = pan_frames(&scratch, 4);
    let out = scratch.path("ego.csv");
    // Frames at 0, 33333, 66667 and 100000 us; a NaN in the second interval, an absurd rate
    // (1000 rad/s) in the third.
    let gyro = gyro_log(
        &scratch,
        &[
            "0,0,0,0",
            "33333,0,0,0",
            "50000,NaN,0,0",
            "66667,0,0,0",
            "80000,0,1000,0",
            "100000,0,0,0",
        ],
    );
    assert_success(&host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--gyro",
        &gyro,
    ]));
    let rows = read_ego(&out);
    let summary: Vec<(u8, &str)> = rows
        .iter()
        .map(|r| (r.quality, r.status.as_str()))
        .collect();
    assert!(summary[0].0 > 0 && summary[0].1 == "ok", "{summary:?}");
    assert_eq!(&summary[1..], &[(0, "bad_gyro"), (0, "bad_gyro")]);
    // The fit itself did not need the gyro: its homography is still given.
    assert!(rows[1].inliers > 0 && rows[1].h != Homography::IDENTITY);
    assert!(!fs::read_to_string(&out)
        .unwrap()
        .to_lowercase()
        .contains("nan"));
}

#[test]
fn bad_model_and_focal_values_are_usage_errors() {
    let scratch = Scratch::new("flags");
    let input = pan_frames(&scratch, 2);
    let out = scratch.path("ego.csv");
    let cases: [(&[&str], &str); 6] = [
        (
            &["--model", "rigid"],
            "--model: must be translation, similarity, affine or homography (got \"rigid\")",
        ),
        (
            &["--focal", "0"],
            "--focal: must be a focal length between 1 and 100000 px (got 0)",
        ),
        (
            &["--focal", "-50"],
            "--focal: must be a focal length between 1 and 100000 px (got -50)",
        ),
        (
            &["--focal", "inf"],
            "--focal: must be a focal length between 1 and 100000 px (got inf)",
        ),
        (
            &["--focal", "wide"],
            "--focal: expected a number (got \"wide\")",
        ),
        (
            &["--fps", "0"],
            "--fps: must be between 1 and 10000 frames per second (got 0)",
        ),
    ];
    for (extra, message) in cases {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"egomotion", &input, &"--out", &out];
        args.extend(extra.iter().map(|e| e as &dyn AsRef<std::ffi::OsStr>));
        let stderr = assert_one_line_error(&host_sim(&args), 2, &[message]);
        assert_eq!(stderr, format!("host-sim: {message}\n"));
        assert!(!out.exists());
    }
}

/// Frames 0-3 of 96 x 72, then frame 4 of 48 x 36.
fn frames_changing_size(scratch: &Scratch) -> PathBuf {
    let input = pan_frames(scratch, 4);
    write_png(&input.join("frame_00004.png"), &Frame::filled(48, 36, 10)).unwrap();
    input
}

#[test]
fn a_frame_of_another_size_stops_egomotion_and_keeps_the_pairs_before_it() {
    let scratch = Scratch::new("resize");
    let input = frames_changing_size(&scratch);
    let (out, mavlink) = (scratch.path("ego.csv"), scratch.path("flow.bin"));
    let output = host_sim(&[&"egomotion", &input, &"--out", &out, &"--mavlink", &mavlink]);
    assert_one_line_error(
        &output,
        1,
        &["frame_00004.png", "frame 4", "48x36", "96x72"],
    );
    let rows = read_ego(&out);
    let frames: Vec<usize> = rows.iter().map(|r| r.frame).collect();
    assert_eq!(frames, [1, 2, 3]);
    assert!(rows.iter().all(|r| r.quality > 0));
    // A heartbeat and two frames per pair, the last one complete.
    let bytes = fs::read(&mavlink).unwrap();
    assert_eq!(mavlink_frames(&bytes).len(), 1 + 2 * 3);
}

/// `--preset flow-sensor` is the library's flow sensor, the firmware's pipeline: its rows are
/// what `kestrel::sensor::FlowSensor` reads out on the same frames, bit for bit, from at most
/// the preset's 25 tracks kept from frame to frame.
#[test]
fn the_flow_sensor_preset_is_the_librarys_flow_sensor() {
    use kestrel::detect::Corner;
    use kestrel::ego::CameraParams;
    use kestrel::lk::scratch_len;
    use kestrel::sensor::{FlowSensor, FlowSensorConfig};
    use kestrel::track::{tracker_storage_len, TrackerBuffers, TrackerConfig};

    let scratch = Scratch::new("preset");
    let (width, height) = (160, 120);
    let sequence = FlightSequence::new(SceneSpec::new(width, height, 2), FlightPath::Pan, 0);
    let frames = 12;
    let rows = egomotion_on_flight(&scratch, &sequence, frames, &[&"--preset", &"flow-sensor"]);

    const PRESET: TrackerConfig = TrackerConfig::flow_sensor();
    let mut storage = vec![0u8; tracker_storage_len(width, height, PRESET.pyramid_levels())];
    let mut lk_scratch = vec![0i16; scratch_len(PRESET.lk.window)];
    let mut candidates = vec![Corner::default(); 3 * PRESET.max_tracks];
    let buffers = TrackerBuffers {
        storage: &mut storage,
        lk_scratch: &mut lk_scratch,
        detect_scratch: &mut [],
        candidates: &mut candidates,
    };
    let fov = std::f32::consts::FRAC_PI_3;
    let camera = CameraParams::from_horizontal_fov(width as u16, height as u16, fov);
    let config = FlowSensorConfig::new(camera);
    let mut sensor = FlowSensor::<25>::new(config, width, height, buffers).unwrap();
    let frame = |k: usize| sequence.frame(k);
    let first = frame(0);
    sensor.start(first.view().unwrap()).unwrap();
    for (k, row) in (1..frames).zip(&rows) {
        let (prev, next) = (frame(k - 1), frame(k));
        let step = sensor
            .process(prev.view().unwrap(), next.view().unwrap(), 33_333, None)
            .unwrap();
        let reading = sensor.readout(0);
        // ego.csv writes the shortest text that reads back as the same f32.
        assert_eq!(row.integrated_x as f32, reading.integrated_x, "frame {k}");
        assert_eq!(row.quality, reading.quality, "frame {k}");
        assert_eq!(row.inliers, usize::from(step.motion.inliers), "frame {k}");
        assert!(row.tracked <= 25 && row.tracked == sensor.pairs().0.len());
    }
    // The tracks live on: after the first pair most of them were followed, not detected anew.
    assert!(rows.iter().skip(1).all(|r| r.tracked >= 15), "{rows:?}");
    assert!(rows.iter().all(|r| r.status == "ok" && r.quality > 0));
}

#[test]
fn a_frame_of_another_size_stops_the_flow_sensor_preset_too() {
    let scratch = Scratch::new("resize-preset");
    let input = frames_changing_size(&scratch);
    let out = scratch.path("ego.csv");
    let output = host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--preset",
        &"flow-sensor",
    ]);
    assert_one_line_error(
        &output,
        1,
        &["frame_00004.png", "frame 4", "48x36", "96x72"],
    );
    let frames: Vec<usize> = read_ego(&out).iter().map(|r| r.frame).collect();
    assert_eq!(frames, [1, 2, 3]);
}

#[test]
fn empty_and_missing_inputs_write_nothing() {
    let scratch = Scratch::new("empty");
    let empty = scratch.path("frames");
    fs::create_dir_all(&empty).unwrap();
    let out = scratch.path("ego.csv");
    let output = host_sim(&[&"egomotion", &empty, &"--out", &out]);
    assert_one_line_error(&output, 1, &["frames", "no frames"]);
    let missing = scratch.path("nothing.y4m");
    let output = host_sim(&[&"egomotion", &missing, &"--out", &out]);
    assert_one_line_error(&output, 1, &["nothing.y4m", "no such file"]);
    let output = host_sim(&[&"egomotion", &"--out", &out]);
    assert_one_line_error(&output, 2, &["INPUT: is required"]);
    assert!(!out.exists());
}

/// The mean corner displacement of each frame pair's motion, as `egomotion` measures it.
fn inter_frame_motion(scratch: &Scratch, frames: &Path, size: (usize, usize)) -> Vec<f64> {
    let out = scratch.path("motion.csv");
    assert_success(&host_sim(&[
        &"egomotion",
        &frames,
        &"--out",
        &out,
        &"--model",
        &"similarity",
    ]));
    read_ego(&out)
        .iter()
        .map(|row| corner_error(&row.h, &Homography::IDENTITY, size.0, size.1))
        .collect()
}

#[test]
fn stabilize_removes_the_shake() {
    let scratch = Scratch::new("stabilize");
    let size = (160, 120);
    let spec = SceneSpec::new(size.0, size.1, 21).with_noise(1.0);
    let sequence = FlightSequence::new(spec, FlightPath::Shake, 0);
    let frames = 24;
    let input = scratch.frames((0..frames).map(|k| sequence.frame(k)));
    let stable = scratch.path("stable");
    assert_success(&host_sim(&[
        &"stabilize",
        &input,
        &"--out",
        &stable,
        &"--smoothing",
        &"6",
    ]));

    let mut names: Vec<String> = fs::read_dir(&stable)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let expected: Vec<String> = (0..frames).map(|k| format!("frame_{k:05}.png")).collect();
    assert_eq!(names, expected);
    for name in &names {
        let frame = image::open(stable.join(name)).unwrap();
        assert_eq!(
            (frame.width(), frame.height()),
            (size.0 as u32, size.1 as u32)
        );
    }

    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let before = inter_frame_motion(&scratch, &input, size);
    let after = inter_frame_motion(&scratch, &stable, size);
    println!(
        "stabilize: inter-frame motion (mean corner displacement) {:.2} px before, {:.2} px after; \
         median {:.2} px before, {:.2} px after",
        mean(&before),
        mean(&after),
        median(before.clone()),
        median(after.clone()),
    );
    assert!(mean(&after) < mean(&before) / 2.0, "{before:?} {after:?}");
}

#[test]
fn stabilize_keeps_the_frames_before_a_bad_one() {
    let scratch = Scratch::new("stabilize-resize");
    let input = frames_changing_size(&scratch);
    let stable = scratch.path("stable");
    let output = host_sim(&[
        &"stabilize",
        &input,
        &"--out",
        &stable,
        &"--smoothing",
        &"2",
    ]);
    assert_one_line_error(&output, 1, &["frame_00004.png", "frame 4"]);
    let count = fs::read_dir(&stable).unwrap().count();
    assert_eq!(count, 4);
    let output = host_sim(&[
        &"stabilize",
        &input,
        &"--out",
        &stable,
        &"--smoothing",
        &"0",
    ]);
    assert_one_line_error(
        &output,
        2,
        &["--smoothing: must be between 1 and 1000 frames (got 0)"],
    );
}

#[test]
fn help_texts_describe_the_new_commands() {
    for command in ["egomotion", "stabilize", "synth-sequence"] {
        let output = host_sim(&[&command, &"--help"]);
        assert_eq!(output.status.code(), Some(0));
        let usage = String::from_utf8(output.stdout).unwrap();
        assert!(
            usage.contains(&format!("Usage: host-sim {command}")),
            "{usage}"
        );
    }
}

#[test]
fn an_unwritable_output_fails_before_any_work_and_writes_nothing() {
    let scratch = Scratch::new("unwritable");
    let input = pan_frames(&scratch, 2);
    let out = scratch.path("ego.csv");
    let nowhere = scratch.path("no-such-dir").join("flow.bin");
    let output = host_sim(&[&"egomotion", &input, &"--out", &out, &"--mavlink", &nowhere]);
    assert_one_line_error(&output, 1, &["flow.bin", "no-such-dir does not exist"]);
    assert!(!out.exists());
    // A file where the output directory should be.
    let file = scratch.path("taken");
    fs::write(&file, "not a directory").unwrap();
    let output = host_sim(&[&"stabilize", &input, &"--out", &file]);
    assert_one_line_error(&output, 1, &["taken", "cannot create"]);
}

#[test]
fn udp_streams_every_pair_to_a_listener_and_a_missing_one_costs_nothing() {
    let scratch = Scratch::new("udp");
    let input = pan_frames(&scratch, 6);
    let out = scratch.path("ego.csv");
    let listener = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    listener
        .set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let destination = format!("udp:{}", listener.local_addr().unwrap());
    let output = host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--mavlink",
        &destination,
    ]);
    assert_success(&output);
    let rows = read_ego(&out);
    assert_eq!(rows.len(), 5);
    // One frame per datagram: a heartbeat, then OPTICAL_FLOW_RAD and OPTICAL_FLOW per pair.
    let mut buf = [0u8; 300];
    let mut ids = Vec::new();
    for sequence in 0..1 + 2 * rows.len() {
        let len = listener.recv(&mut buf).unwrap();
        let frame = &buf[..len];
        assert_eq!(mavlink_frames(frame).len(), 1);
        assert_eq!(usize::from(frame[4]), sequence);
        ids.push(message_id(frame));
        if message_id(frame) == 100 {
            assert_eq!(frame[10 + 25], rows[(sequence - 2) / 2].quality);
        }
    }
    assert_eq!(ids, [0, 106, 100, 106, 100, 106, 100, 106, 100, 106, 100]);

    // The listener is gone: the run succeeds and says on one line what it could not send.
    drop(listener);
    let output = host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--mavlink",
        &destination,
    ]);
    assert!(output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.lines().count() <= 1, "{stderr}");
    if let Some(line) = stderr.lines().next() {
        assert!(
            line.starts_with(&format!("host-sim: {destination}: ")),
            "{line}"
        );
        assert!(
            line.contains("of 11 MAVLink datagrams could not be sent"),
            "{line}"
        );
    }
    assert_eq!(read_ego(&out).len(), 5);
}

#[test]
fn a_malformed_or_unresolvable_udp_destination_fails_before_any_frame_is_read() {
    let scratch = Scratch::new("badudp");
    let out = scratch.path("ego.csv");
    // The input does not exist: the destination is checked first.
    let input = scratch.path("no-frames");
    for (destination, code, culprits) in [
        ("udp:", 2, &["--mavlink", "udp:HOST:PORT"][..]),
        ("udp:localhost:0", 2, &["--mavlink", "port"]),
        ("udp::14550", 2, &["--mavlink", "host"]),
        (
            "udp:no-such-host.invalid:14550",
            1,
            &["udp:no-such-host.invalid:14550", "resolve"],
        ),
    ] {
        let output = host_sim(&[
            &"egomotion",
            &input,
            &"--out",
            &out,
            &"--mavlink",
            &destination,
        ]);
        assert_one_line_error(&output, code, culprits);
        assert!(!out.exists());
    }
}

#[test]
fn rate_paces_the_replay_in_real_time() {
    let scratch = Scratch::new("rate");
    let input = pan_frames(&scratch, 4);
    let out = scratch.path("ego.csv");
    let start = std::time::Instant::now();
    assert_success(&host_sim(&[
        &"egomotion",
        &input,
        &"--out",
        &out,
        &"--rate",
        &"20",
    ]));
    // Frame 3 is let through 3 / 20 s after frame 0.
    assert!(start.elapsed().as_secs_f64() >= 0.15);
    assert_eq!(read_ego(&out).len(), 3);
}

#[test]
fn synth_sequence_writes_the_boxes_of_objects_of_a_given_size() {
    let scratch = Scratch::new("object-size");
    let out = scratch.path("flight");
    let output = host_sim(&[
        &"synth-sequence",
        &"--out",
        &out,
        &"--frames",
        &"5",
        &"--width",
        &"160",
        &"--height",
        &"120",
        &"--objects",
        &"3",
        &"--object-size",
        &"10-12",
    ]);
    assert_success(&output);
    let text = fs::read_to_string(out.join("objects.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|line| line.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    // Three objects in each of frames 1 to 4, inside the frame, 10 to 12 px a side.
    assert_eq!(rows.len(), 3 * 4);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!((row[0], row[1]), ((i / 3 + 1) as f64, (i % 3) as f64));
        assert!(row[2] >= 0.0 && row[2] + row[4] <= 160.0, "{row:?}");
        assert!(row[3] >= 0.0 && row[3] + row[5] <= 120.0, "{row:?}");
        assert!((10.0..=12.0).contains(&row[4]) && (10.0..=12.0).contains(&row[5]));
    }
    // Without objects there is no objects.csv; a bad size is refused.
    let plain = scratch.path("plain");
    assert_success(&host_sim(&[
        &"synth-sequence",
        &"--out",
        &plain,
        &"--frames",
        &"2",
    ]));
    assert!(!plain.join("objects.csv").exists());
    let output = host_sim(&[
        &"synth-sequence",
        &"--out",
        &plain,
        &"--object-size",
        &"12-10",
    ]);
    assert_one_line_error(&output, 2, &["--object-size", "MIN must not exceed MAX"]);
}
