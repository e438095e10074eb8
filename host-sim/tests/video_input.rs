//! Video files as INPUT: every sequence command decodes them through ffmpeg to the frames
//! ffmpeg's y4m gives, a damaged video keeps the frames before the damage and ends with one
//! line, and without ffmpeg the line says to install it.
//!
//! The clips are made by ffmpeg at test time; the tests that need it are skipped, with a note,
//! when it is not on the PATH.

mod common;

use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{assert_one_line_error, entries, host_sim, Scratch};

/// Frames in the test clip: at 96x64 and a key frame every 8, half of the file holds several
/// whole frames before the cut.
const FRAMES: usize = 40;

/// True when ffmpeg runs; prints why the test is skipped otherwise.
fn ffmpeg_available() -> bool {
    let found = Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|output| output.status.success());
    if !found {
        eprintln!("skipped: ffmpeg is not on the PATH");
    }
    found
}

/// Runs ffmpeg with `args`, quietly, and checks that it succeeded.
fn ffmpeg(args: &[&dyn AsRef<OsStr>]) {
    let output = Command::new("ffmpeg")
        .args(["-nostdin", "-v", "error", "-y"])
        .args(args.iter().map(|a| a.as_ref()))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "ffmpeg: {stderr}");
}

/// A 96x64 H.264 clip of ffmpeg's test pattern at 10 fps, its index at the front of the file
/// (as cameras and web videos have it), so that a truncated copy still starts decoding.
fn make_clip(path: &Path) {
    ffmpeg(&[
        &"-f",
        &"lavfi",
        &"-i",
        &"testsrc=size=96x64:rate=10",
        &"-frames:v",
        &FRAMES.to_string(),
        &"-c:v",
        &"libx264",
        &"-g",
        &"8",
        &"-pix_fmt",
        &"yuv420p",
        &"-movflags",
        &"+faststart",
        &path,
    ]);
}

/// The frames of `clip` as ffmpeg's own y4m: full-range grey, which is what host-sim asks of
/// ffmpeg for a video.
fn decode_to_y4m(clip: &Path, y4m: &Path) {
    ffmpeg(&[
        &"-i",
        &clip,
        &"-f",
        &"yuv4mpegpipe",
        &"-pix_fmt",
        &"gray",
        &y4m,
    ]);
}

/// The sequence commands, each with the file or directory its --out names.
const COMMANDS: [(&str, &str); 4] = [
    ("track", "tracks.csv"),
    ("motion", "boxes.csv"),
    ("egomotion", "ego.csv"),
    ("stabilize", "stable"),
];

/// Runs `command` on `input` with all its outputs in the fresh directory `out` (egomotion's
/// MAVLink stream too).
fn run(command: &str, input: &Path, out: &Path) -> Output {
    let _ = fs::remove_dir_all(out);
    fs::create_dir_all(out).unwrap();
    let (_, output_name) = COMMANDS.iter().find(|(name, _)| *name == command).unwrap();
    let (target, mavlink) = (out.join(output_name), out.join("flow.bin"));
    let mut words: Vec<&dyn AsRef<OsStr>> = vec![&command, &input, &"--out", &target];
    if command == "egomotion" {
        words.extend([&"--mavlink" as &dyn AsRef<OsStr>, &mavlink]);
    }
    host_sim(&words)
}

/// Every file under `dir` with its bytes, by path relative to `dir`.
fn contents(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    for name in entries(dir) {
        let path = dir.join(&name);
        if path.is_dir() {
            let inner = contents(&path);
            files.extend(
                inner
                    .into_iter()
                    .map(|(p, b)| (Path::new(&name).join(p), b)),
            );
        } else {
            files.push((PathBuf::from(name), fs::read(&path).unwrap()));
        }
    }
    files
}

fn assert_success(output: &Output, what: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{what}: {stderr}");
}

/// The data rows of tracks.csv, its header dropped.
fn track_rows(csv: &Path) -> Vec<String> {
    let text = fs::read_to_string(csv).unwrap();
    text.lines().skip(1).map(str::to_owned).collect()
}

/// The frame column of a tracks.csv row.
fn frame_of(row: &str) -> usize {
    row.split(',').next().unwrap().parse().unwrap()
}

#[test]
fn every_sequence_command_reads_a_video_as_the_y4m_ffmpeg_makes_of_it() {
    if !ffmpeg_available() {
        return;
    }
    let scratch = Scratch::new("video-same");
    let (clip, y4m) = (scratch.path("clip.mp4"), scratch.path("clip.y4m"));
    make_clip(&clip);
    decode_to_y4m(&clip, &y4m);
    for (command, _) in COMMANDS {
        let from_video = scratch.path(&format!("{command}-video"));
        let from_y4m = scratch.path(&format!("{command}-y4m"));
        assert_success(&run(command, &clip, &from_video), command);
        assert_success(&run(command, &y4m, &from_y4m), command);
        let (video, y4m) = (contents(&from_video), contents(&from_y4m));
        assert!(!video.is_empty(), "{command} wrote nothing");
        assert!(
            video == y4m,
            "{command}: the video's results differ from the y4m's"
        );
    }
    let rows = track_rows(&scratch.path("track-video").join("tracks.csv"));
    let last = rows.iter().map(|row| frame_of(row)).max();
    assert!(rows.len() > FRAMES, "{} rows", rows.len());
    assert_eq!(
        last,
        Some(FRAMES - 1),
        "every frame of the video is tracked"
    );
}

#[test]
fn a_truncated_video_keeps_the_frames_before_the_damage() {
    if !ffmpeg_available() {
        return;
    }
    let scratch = Scratch::new("video-cut");
    let (clip, cut) = (scratch.path("clip.mp4"), scratch.path("cut.mp4"));
    make_clip(&clip);
    let bytes = fs::read(&clip).unwrap();
    fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();

    let (whole, damaged) = (scratch.path("whole"), scratch.path("damaged"));
    assert_success(&run("track", &clip, &whole), "the whole clip");
    let output = run("track", &cut, &damaged);
    let message = assert_one_line_error(&output, 1, "cut.mp4");
    assert!(message.contains("cannot decode: ffmpeg: "), "{message}");
    // The frame named is the first one missing: every frame before it is tracked.
    let frame: usize = message
        .split("frame ")
        .nth(1)
        .and_then(|rest| rest.split(':').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no frame named: {message}"));
    assert!((1..FRAMES).contains(&frame), "{message}");
    let kept = track_rows(&damaged.join("tracks.csv"));
    let expected: Vec<String> = track_rows(&whole.join("tracks.csv"))
        .into_iter()
        .filter(|row| frame_of(row) < frame)
        .collect();
    assert!(!kept.is_empty());
    assert_eq!(kept, expected, "the rows of frames 0 to {}", frame - 1);
}

#[test]
fn a_file_ffmpeg_cannot_read_is_named_with_its_reason_and_a_renamed_y4m_is_still_y4m() {
    if !ffmpeg_available() {
        return;
    }
    let scratch = Scratch::new("video-other");
    let notes = scratch.path("notes.txt");
    fs::write(&notes, "not a video\n").unwrap();
    let output = run("track", &notes, &scratch.path("out"));
    let message = assert_one_line_error(&output, 1, "notes.txt");
    assert!(
        message.ends_with("cannot decode: ffmpeg: Invalid data found when processing input\n"),
        "{message}"
    );
    assert!(entries(&scratch.path("out")).is_empty());
    // A y4m stream under another name is read as y4m, without ffmpeg, as it always was.
    let (clip, renamed) = (scratch.path("clip.mp4"), scratch.path("clip.yuv"));
    make_clip(&clip);
    decode_to_y4m(&clip, &scratch.path("clip.y4m"));
    fs::rename(scratch.path("clip.y4m"), &renamed).unwrap();
    let without_ffmpeg = without_ffmpeg_on_path(&scratch, "track", &renamed);
    assert_success(&without_ffmpeg, "a y4m named clip.yuv");
}

/// Runs `host-sim command INPUT --out DIR/tracks.csv` with a PATH that holds no ffmpeg.
fn without_ffmpeg_on_path(scratch: &Scratch, command: &str, input: &Path) -> Output {
    let empty = scratch.path("empty-bin");
    fs::create_dir_all(&empty).unwrap();
    let out = scratch.path("out-no-ffmpeg");
    let _ = fs::remove_dir_all(&out);
    fs::create_dir_all(&out).unwrap();
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg(command)
        .arg(input)
        .arg("--out")
        .arg(out.join("tracks.csv"))
        .env("PATH", &empty)
        .output()
        .unwrap()
}

#[test]
fn without_ffmpeg_a_video_asks_for_it_and_a_missing_file_is_missing() {
    let scratch = Scratch::new("video-no-ffmpeg");
    // host-sim never decodes the file itself: any bytes will do.
    let clip = scratch.path("clip.mp4");
    fs::write(&clip, b"\x00\x00\x00\x18ftypmp42").unwrap();
    let output = without_ffmpeg_on_path(&scratch, "track", &clip);
    let message = assert_one_line_error(&output, 1, "clip.mp4");
    assert!(message.contains("video file"), "{message}");
    assert!(message.contains("apt install ffmpeg"), "{message}");
    assert!(entries(&scratch.path("out-no-ffmpeg")).is_empty());
    // A missing file is reported as missing, before any thought of ffmpeg.
    let missing = scratch.path("missing.mkv");
    let output = without_ffmpeg_on_path(&scratch, "track", &missing);
    let message = assert_one_line_error(&output, 1, "missing.mkv");
    assert!(
        message.ends_with("cannot open: no such file or directory\n"),
        "{message}"
    );
}
