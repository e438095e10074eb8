//! Runs `host-sim track` and `host-sim demo` on sequences written in a scratch directory and
//! checks the contract: tracks.csv's format and id rules, the three kinds of INPUT, --viz,
//! and bad input (empty folder, changing size, corrupt or truncated frames) ending with one
//! line naming the frame while the frames before it stay written.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::ffi::OsStr;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{assert_one_line_error, entries, host_sim, Scratch};
use host_sim::io::images::write_png;
use host_sim::synth::{CameraPath, Scene, SceneSpec, Sequence};
use host_sim::Frame;

const WIDTH: usize = 160;
const HEIGHT: usize = 120;
const FRAMES: usize = 8;

/// `count` frames of a seeded scene under a slow pan and rotation.
fn frames(width: usize, height: usize, count: usize) -> Vec<Frame> {
    let path = CameraPath {
        pan: (0.8, 0.3),
        rotation: 0.002,
        ..CameraPath::still(((width - 1) as f64 / 2.0, (height - 1) as f64 / 2.0))
    };
    let scene = Scene::new(SceneSpec::new(width, height, 11).with_noise(1.0));
    Sequence::new(scene, path, count).frames().collect()
}

/// Writes `frames` as `dir/0000.png`, `dir/0001.png`, ... and returns the paths.
fn write_folder(dir: &Path, frames: &[Frame]) -> Vec<PathBuf> {
    fs::create_dir_all(dir).unwrap();
    frames
        .iter()
        .enumerate()
        .map(|(k, frame)| {
            let path = dir.join(format!("{k:04}.png"));
            write_png(&path, frame).unwrap();
            path
        })
        .collect()
}

/// The frames as a monochrome y4m stream.
fn y4m(frames: &[Frame]) -> Vec<u8> {
    let (w, h) = (frames[0].width, frames[0].height);
    let mut bytes = format!("YUV4MPEG2 W{w} H{h} F30:1 Ip A1:1 Cmono\n").into_bytes();
    for frame in frames {
        bytes.extend_from_slice(b"FRAME\n");
        bytes.extend_from_slice(&frame.data);
    }
    bytes
}

/// The rows of tracks.csv after its header, checking the header.
fn rows(csv: &Path) -> Vec<Row> {
    let text = fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("frame,id,x,y,age,residual"));
    lines
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 6, "{line}");
            Row {
                frame: f[0].parse().unwrap(),
                id: f[1].parse().unwrap(),
                x: f[2].parse().unwrap(),
                y: f[3].parse().unwrap(),
                age: f[4].parse().unwrap(),
            }
        })
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Row {
    frame: usize,
    id: u32,
    x: f64,
    y: f64,
    age: usize,
}

/// Checks the contract's rules on the rows of a run over `frames` frames and returns the
/// number of rows per frame: frames counted from 0 in order, ids unique in a frame, a track's
/// first row in its birth frame (age 0), its rows in consecutive frames, ids never reused.
fn check_rules(rows: &[Row], frames: usize) -> Vec<usize> {
    let mut per_frame = vec![0; frames];
    let mut last_frame_of: BTreeMap<u32, usize> = BTreeMap::new();
    let mut in_frame: BTreeSet<(usize, u32)> = BTreeSet::new();
    let mut previous_frame = 0;
    for row in rows {
        assert!(
            row.frame >= previous_frame,
            "rows out of frame order: {row:?}"
        );
        previous_frame = row.frame;
        assert!(
            in_frame.insert((row.frame, row.id)),
            "id twice in a frame: {row:?}"
        );
        per_frame[row.frame] += 1;
        match last_frame_of.insert(row.id, row.frame) {
            None => assert_eq!(row.age, 0, "first row is not the birth frame: {row:?}"),
            Some(last) => {
                assert_eq!(last + 1, row.frame, "id reused or gap: {row:?}");
                assert!(row.age > 0);
            }
        }
        assert!((0.0..WIDTH as f64).contains(&row.x) && (0.0..HEIGHT as f64).contains(&row.y));
    }
    per_frame
}

#[test]
fn track_writes_one_row_per_live_track_per_frame_by_the_rules() {
    let scratch = Scratch::new("track-folder");
    let dir = scratch.path("frames");
    write_folder(&dir, &frames(WIDTH, HEIGHT, FRAMES));
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &out]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // Not a terminal: no progress line.
    assert!(output.stderr.is_empty() && output.stdout.is_empty());
    let rows = rows(&out);
    let per_frame = check_rules(&rows, FRAMES);
    let ids: BTreeSet<u32> = rows.iter().map(|r| r.id).collect();
    eprintln!(
        "{FRAMES} frames: rows per frame {per_frame:?}, {} ids",
        ids.len()
    );
    assert!(
        per_frame.iter().all(|&n| (50..=100).contains(&n)),
        "{per_frame:?}"
    );
    assert_eq!(scratch.entries(), ["frames", "tracks.csv"]);
}

#[test]
fn a_y4m_file_and_y4m_on_stdin_give_the_same_tracks_as_a_folder() {
    let scratch = Scratch::new("track-y4m");
    let frames = frames(WIDTH, HEIGHT, FRAMES);
    let dir = scratch.path("frames");
    write_folder(&dir, &frames);
    let clip = scratch.path("clip.y4m");
    fs::write(&clip, y4m(&frames)).unwrap();
    let (from_dir, from_file, from_stdin) = (
        scratch.path("dir.csv"),
        scratch.path("file.csv"),
        scratch.path("stdin.csv"),
    );
    assert!(host_sim(&[&"track", &dir, &"--out", &from_dir])
        .status
        .success());
    assert!(host_sim(&[&"track", &clip, &"--out", &from_file])
        .status
        .success());

    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["track", "-", "--out"])
        .arg(&from_stdin)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(&y4m(&frames))
        .unwrap();
    let output = child.wait_with_output().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );

    let expected = fs::read_to_string(&from_dir).unwrap();
    assert_eq!(fs::read_to_string(&from_file).unwrap(), expected);
    assert_eq!(fs::read_to_string(&from_stdin).unwrap(), expected);
    eprintln!(
        "folder, y4m file and stdin: {} identical lines",
        expected.lines().count()
    );
}

#[test]
fn max_tracks_caps_the_rows_of_every_frame() {
    let scratch = Scratch::new("track-max");
    let dir = scratch.path("frames");
    write_folder(&dir, &frames(WIDTH, HEIGHT, 4));
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &out, &"--max-tracks", &"12"]);
    assert!(output.status.success());
    let per_frame = check_rules(&rows(&out), 4);
    assert!(
        per_frame.iter().all(|&n| (1..=12).contains(&n)),
        "{per_frame:?}"
    );
}

/// `count` frames of a camera panning 10 px a frame: tracks leave the view.
fn fast_pan(count: usize) -> Vec<Frame> {
    let path = CameraPath {
        pan: (10.0, 0.0),
        ..CameraPath::still(((WIDTH - 1) as f64 / 2.0, (HEIGHT - 1) as f64 / 2.0))
    };
    let scene = Scene::new(SceneSpec::new(WIDTH, HEIGHT, 11).with_noise(1.0));
    Sequence::new(scene, path, count).frames().collect()
}

#[test]
fn stats_report_the_library_time_per_frame() {
    let scratch = Scratch::new("track-stats");
    let dir = scratch.path("frames");
    // Tracks leave the view, so that the drops have something to count.
    write_folder(&dir, &fast_pan(3));
    let (out, stats) = (scratch.path("tracks.csv"), scratch.path("s.json"));
    let output = host_sim(&[&"track", &dir, &"--out", &out, &"--stats", &stats]);
    assert!(output.status.success());
    let json = fs::read_to_string(&stats).unwrap();
    assert!(
        json.starts_with("{\"frames\": 3, \"median_frame_seconds\": "),
        "{json}"
    );
    let field = |name: &str| -> f64 {
        let rest = json.split(&format!("\"{name}\": ")).nth(1).unwrap();
        rest.split([',', '}'])
            .next()
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    };
    let seconds = field("mean_frame_seconds");
    assert!(seconds > 0.0 && seconds < 10.0, "{json}");
    // The mean life is the rows per track, and every track that ends before the last frame
    // was dropped by one gate or another: the counts by gate add up to the tracks that ended.
    let rows = rows(&out);
    let ids: BTreeSet<u32> = rows.iter().map(|r| r.id).collect();
    let life = field("mean_track_life");
    let rows_per_track = rows.len() as f64 / ids.len() as f64;
    assert!((life - rows_per_track).abs() < 1e-9, "{json}");
    let in_frame: BTreeSet<(usize, u32)> = rows.iter().map(|r| (r.frame, r.id)).collect();
    let ended = in_frame
        .iter()
        .filter(|&&(frame, id)| frame < 2 && !in_frame.contains(&(frame + 1, id)))
        .count();
    let drops: f64 = [
        "lost",
        "out_of_frame",
        "residual",
        "appearance",
        "relocation",
        "forward_backward",
    ]
    .iter()
    .map(|reason| field(reason))
    .sum();
    // Measured: 12 tracks ended, 2 of them out of the frame.
    assert!(ended > 0 && field("out_of_frame") >= 1.0, "{json}");
    assert_eq!(drops, ended as f64, "{json}");
}

/// `--refill-below` sets when new corners are detected: at 0 only the first frame starts
/// tracks, though a fast pan takes some out of the view; by default the lost ones are replaced,
/// and with `--leaving-within` none starts where the pan soon takes it out of the view.
#[test]
fn refill_below_and_leaving_within_set_where_and_when_new_tracks_start() {
    let scratch = Scratch::new("track-refill-below");
    let dir = scratch.path("frames");
    write_folder(&dir, &fast_pan(4));
    let out = scratch.path("tracks.csv");
    let born_later = |extra: &[&dyn AsRef<OsStr>]| {
        let mut args: Vec<&dyn AsRef<OsStr>> = vec![&"track", &dir, &"--out", &out];
        args.extend_from_slice(extra);
        let output = host_sim(&args);
        assert!(output.status.success(), "{output:?}");
        let rows = rows(&out);
        let first: BTreeSet<u32> = rows.iter().filter(|r| r.frame == 0).map(|r| r.id).collect();
        // Where each later track started.
        let later: BTreeMap<u32, f64> = rows
            .iter()
            .rev()
            .filter(|r| !first.contains(&r.id))
            .map(|r| (r.id, r.x))
            .collect();
        (first.len(), later, check_rules(&rows, 4))
    };
    let (started, later, live) = born_later(&[&"--refill-below", &"0"]);
    assert!(started > 0 && later.is_empty(), "{started} {later:?}");
    assert!(live.last() < live.first(), "{live:?}");
    // The scene moves 10 px a frame to the right: 20 frames take a corner a quarter of the
    // width, 40 px, and none starts within 48 px of the right edge; with every corner started,
    // some do.
    let right = (WIDTH - 1 - 48) as f64;
    let (_, later, _) = born_later(&[]);
    assert!(
        !later.is_empty() && later.values().all(|&x| x <= right),
        "{later:?}"
    );
    let (_, every, _) = born_later(&[&"--leaving-within", &"0"]);
    assert!(every.values().any(|&x| x > right), "{every:?}");
}

/// The preset and the LK and gate flags reach the tracker: the preset's 25 tracks cap the
/// rows, a flag beside it overrides it, and a bad value is a usage error naming the flag.
#[test]
fn the_preset_and_the_tracker_flags_configure_the_run() {
    let scratch = Scratch::new("track-preset");
    let dir = scratch.path("frames");
    write_folder(&dir, &frames(WIDTH, HEIGHT, 4));
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &out, &"--preset", &"flow-sensor"]);
    assert!(output.status.success(), "{output:?}");
    let per_frame = check_rules(&rows(&out), 4);
    assert!(
        per_frame.iter().all(|&n| (1..=25).contains(&n)),
        "{per_frame:?}"
    );
    let preset_and = |flag: &str, value: &str| {
        host_sim(&[
            &"track",
            &dir,
            &"--out",
            &out,
            &"--preset",
            &"flow-sensor",
            &flag,
            &value,
        ])
    };
    let wider = preset_and("--max-tracks", "40");
    assert!(wider.status.success(), "{wider:?}");
    assert!(check_rules(&rows(&out), 4).iter().any(|&n| n > 25));
    let firmware = host_sim(&[
        &"track",
        &dir,
        &"--out",
        &out,
        &"--window",
        &"9",
        &"--levels",
        &"2",
        &"--template",
        &"nearest-pixel",
        &"--illumination",
        &"plain",
        &"--fb-threshold",
        &"0.5",
        &"--leaving-within",
        &"0",
        &"--refill-below",
        &"50",
    ]);
    assert!(firmware.status.success(), "{firmware:?}");
    for (flag, value, says) in [
        (
            "--window",
            "8",
            "--window: must be an odd number from 3 to 63 (got 8)",
        ),
        ("--levels", "9", "--levels: must be between 0 and 7 (got 9)"),
        (
            "--illumination",
            "auto",
            "--illumination: must be plain or gain-bias (got auto)",
        ),
        (
            "--min-correlation",
            "2",
            "--min-correlation: must be between -1 and 1 (got 2)",
        ),
        (
            "--preset",
            "fast",
            "--preset: must be flow-sensor (got fast)",
        ),
        (
            "--refill-below",
            "101",
            "--refill-below: must be at most the 100 tracks aimed for (got 101)",
        ),
    ] {
        let output = host_sim(&[&"track", &dir, &"--out", &out, &flag, &value]);
        assert_eq!(output.status.code(), Some(2), "{flag}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(says), "{flag}: {stderr}");
    }
    // The preset aims for 25 tracks.
    let preset = preset_and("--refill-below", "30");
    assert_eq!(preset.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&preset.stderr);
    assert!(
        stderr.contains("must be at most the 25 tracks aimed for (got 30)"),
        "{stderr}"
    );
}

#[test]
fn viz_writes_one_trail_picture_per_frame() {
    let scratch = Scratch::new("track-viz");
    let dir = scratch.path("frames");
    write_folder(&dir, &frames(WIDTH, HEIGHT, 5));
    let (out, viz) = (scratch.path("tracks.csv"), scratch.path("pictures/trails"));
    let output = host_sim(&[&"track", &dir, &"--out", &out, &"--viz", &viz]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let names = entries(&viz);
    assert_eq!(
        names,
        [
            "000000.png",
            "000001.png",
            "000002.png",
            "000003.png",
            "000004.png"
        ]
    );
    let picture = image::open(viz.join("000004.png")).unwrap();
    assert_eq!(
        (picture.width(), picture.height()),
        (WIDTH as u32, HEIGHT as u32)
    );
    // Coloured trails on a grey frame.
    let rgb = picture.to_rgb8();
    let coloured = rgb
        .pixels()
        .filter(|p| p.0[0] != p.0[1] || p.0[1] != p.0[2])
        .count();
    eprintln!(
        "--viz: {} pictures, {coloured} coloured pixels in the last",
        names.len()
    );
    assert!(coloured > 200);
}

#[test]
fn an_empty_folder_is_an_error_and_writes_nothing() {
    let scratch = Scratch::new("track-empty");
    let dir = scratch.path("frames");
    fs::create_dir_all(&dir).unwrap();
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &out]);
    let message = assert_one_line_error(&output, 1, "frames");
    assert!(message.contains("no frames"), "{message}");
    assert_eq!(scratch.entries(), ["frames"]);
}

#[test]
fn a_frame_of_another_size_ends_the_run_and_the_frames_before_it_are_kept() {
    let scratch = Scratch::new("track-size");
    let dir = scratch.path("frames");
    let mut sequence = frames(WIDTH, HEIGHT, 4);
    sequence.push(Frame::filled(96, 72, 128));
    let paths = write_folder(&dir, &sequence);
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &out]);
    let message = assert_one_line_error(&output, 1, "frame 4");
    assert!(message.contains(&*paths[4].to_string_lossy()), "{message}");
    assert!(message.contains("96x72"), "{message}");
    let per_frame = check_rules(&rows(&out), 4);
    assert!(per_frame.iter().all(|&n| n > 0), "{per_frame:?}");
}

#[test]
fn a_corrupt_png_in_the_middle_ends_the_run_and_the_frames_before_it_are_kept() {
    let scratch = Scratch::new("track-corrupt");
    let dir = scratch.path("frames");
    let paths = write_folder(&dir, &frames(WIDTH, HEIGHT, 6));
    let bytes = fs::read(&paths[3]).unwrap();
    fs::write(&paths[3], &bytes[..bytes.len() / 2]).unwrap();
    let (out, viz) = (scratch.path("tracks.csv"), scratch.path("viz"));
    let output = host_sim(&[&"track", &dir, &"--out", &out, &"--viz", &viz]);
    let message = assert_one_line_error(&output, 1, "frame 3");
    assert!(
        message.contains("0003.png") && message.contains("corrupt"),
        "{message}"
    );
    let per_frame = check_rules(&rows(&out), 3);
    assert!(per_frame.iter().all(|&n| n > 0), "{per_frame:?}");
    assert_eq!(entries(&viz), ["000000.png", "000001.png", "000002.png"]);
    // No temporary is left beside the output.
    assert_eq!(scratch.entries(), ["frames", "tracks.csv", "viz"]);
}

#[test]
fn a_truncated_y4m_ends_the_run_and_the_frames_before_it_are_kept() {
    let scratch = Scratch::new("track-truncated");
    let mut bytes = y4m(&frames(WIDTH, HEIGHT, 5));
    bytes.truncate(bytes.len() - 100);
    let clip = scratch.path("clip.y4m");
    fs::write(&clip, bytes).unwrap();
    let out = scratch.path("tracks.csv");
    let output = host_sim(&[&"track", &clip, &"--out", &out]);
    let message = assert_one_line_error(&output, 1, "frame 4");
    assert!(
        message.contains("clip.y4m") && message.contains("truncated"),
        "{message}"
    );
    check_rules(&rows(&out), 4);
}

#[test]
fn bad_command_lines_and_paths_are_named() {
    let scratch = Scratch::new("track-usage");
    let dir = scratch.path("frames");
    write_folder(&dir, &frames(WIDTH, HEIGHT, 2));
    let out = scratch.path("tracks.csv");
    let flag = host_sim(&[&"track", &dir, &"--out", &out, &"--max-tracks", &"0"]);
    assert_one_line_error(&flag, 2, "--max-tracks");
    let missing = host_sim(&[&"track", &scratch.path("nowhere"), &"--out", &out]);
    assert_one_line_error(&missing, 1, "nowhere");
    let unwritable = scratch.path("no-such-dir").join("tracks.csv");
    let output = host_sim(&[&"track", &dir, &"--out", &unwritable]);
    assert_one_line_error(&output, 1, "no-such-dir");
    let no_input = host_sim(&[&"track", &"--out", &out]);
    assert_one_line_error(&no_input, 2, "INPUT");
    assert_eq!(scratch.entries(), ["frames"]);
}

#[test]
fn demo_writes_its_pictures_and_prints_a_summary() {
    let scratch = Scratch::new("demo");
    let out = scratch.path("demo out");
    let output = host_sim(&[&"demo", &"--out", &out]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary = String::from_utf8(output.stdout).unwrap();
    eprintln!("{summary}");
    for needed in [
        "live tracks per frame",
        "survival",
        "error against the ground truth",
        "grid flow",
        "moving box found",
    ] {
        assert!(summary.contains(needed), "{needed}");
    }
    assert_eq!(
        fs::read_to_string(out.join("summary.txt")).unwrap(),
        summary
    );
    assert_eq!(entries(&out), ["motion", "summary.txt", "tracks"]);
    assert_eq!(entries(&out.join("motion")), ["boxes", "flow.png"]);
    assert_eq!(entries(&out.join("motion/boxes")).len(), 11);
    let flow = image::open(out.join("motion/flow.png")).unwrap();
    assert_eq!((flow.width(), flow.height()), (320, 240));
    assert_eq!(
        entries(&out.join("tracks")),
        ["contact_sheet.png", "tracks.csv", "trails"]
    );
    let trails = entries(&out.join("tracks/trails"));
    assert_eq!(trails.len(), 60);
    assert_eq!(
        (trails[0].as_str(), trails[59].as_str()),
        ("000000.png", "000059.png")
    );
    let sheet = image::open(out.join("tracks/contact_sheet.png")).unwrap();
    assert!(sheet.width() > 320 && sheet.height() > 240);
    check_demo_csv(&out.join("tracks/tracks.csv"));
}

/// The demo's tracks.csv follows the contract like the command's.
fn check_demo_csv(path: &Path) {
    let text = fs::read_to_string(path).unwrap();
    assert!(text.starts_with("frame,id,x,y,age,residual\n"));
    let frames: BTreeSet<&str> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(frames.len(), 60);
}

#[test]
fn help_lists_track_and_demo() {
    let output = host_sim(&[&"--help"]);
    let usage = String::from_utf8(output.stdout).unwrap();
    assert!(
        usage.contains("  track ") && usage.contains("  demo "),
        "{usage}"
    );
    for command in ["track", "demo"] {
        let output = host_sim(&[&command, &"--help"]);
        assert!(output.status.success());
        let text = String::from_utf8(output.stdout).unwrap();
        assert!(text.starts_with(&format!("host-sim {command}:")), "{text}");
    }
}
