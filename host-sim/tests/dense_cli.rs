//! Runs `host-sim dense` and `host-sim motion` on files made in a scratch directory and checks
//! the command-line contract: outputs and their formats, exit status, one-line errors naming
//! the culprit, nothing written on error for `dense`, complete results up to a bad frame for
//! `motion`.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

mod common;

use common::{assert_one_line_error, entries, host_sim, Scratch};
use host_sim::dense::field::FlowField;
use host_sim::synth::objects::{BoxPx, MovingObject, ObjectSequence};
use host_sim::synth::{CameraPath, Scene, SceneSpec};
use image::{GrayImage, Luma};
use kestrel::dense::grid_len;

const WIDTH: u32 = 96;
const HEIGHT: u32 = 72;

/// A textured frame and the same frame shifted 2 px to the right, as a.png and b.png.
fn pair(scratch: &Scratch) -> (PathBuf, PathBuf) {
    let (a, b) = (scratch.path("a.png"), scratch.path("b.png"));
    textured(WIDTH, HEIGHT, 0.0).save(&a).unwrap();
    textured(WIDTH, HEIGHT, 2.0).save(&b).unwrap();
    (a, b)
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

fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect()
}

/// `dense` on the scratch pair with `extra` arguments, writing grid.csv.
fn dense(scratch: &Scratch, extra: &[&dyn AsRef<std::ffi::OsStr>]) -> (Output, PathBuf) {
    let (a, b) = pair(scratch);
    let out = scratch.path("grid.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
        vec![&"dense", &"--prev", &a, &"--next", &b, &"--out", &out];
    args.extend_from_slice(extra);
    (host_sim(&args), out)
}

#[test]
fn dense_writes_the_grid_the_flo_field_and_the_picture() {
    let scratch = Scratch::new("outputs");
    let (flo, png, stats) = (
        scratch.path("f.flo"),
        scratch.path("f.png"),
        scratch.path("s.json"),
    );
    let (output, out) = dense(
        &scratch,
        &[
            &"--flo",
            &flo,
            &"--png",
            &png,
            &"--repeat",
            &"3",
            &"--stats",
            &stats,
        ],
    );
    assert!(output.status.success(), "{output:?}");
    assert!(output.stderr.is_empty() && output.stdout.is_empty());

    let text = fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().next(), Some("x,y,dx,dy,ok,status"));
    let grid = rows(&text);
    assert_eq!(grid.len(), grid_len(WIDTH as usize, HEIGHT as usize, 8));
    assert_eq!(&grid[0][..2], ["4", "4"]);
    assert_eq!(&grid[13][..2], ["12", "12"]); // 12 columns per row
    let measured: Vec<f64> = grid
        .iter()
        .filter(|r| r[4] == "1")
        .map(|r| r[2].parse().unwrap())
        .collect();
    eprintln!("{} of {} nodes measured", measured.len(), grid.len());
    assert!(measured.len() >= grid.len() / 2);
    let mut dx = measured.clone();
    dx.sort_by(f64::total_cmp);
    assert!(
        (dx[dx.len() / 2] - 2.0).abs() < 0.1,
        "median dx {}",
        dx[dx.len() / 2]
    );

    let field = FlowField::from_flo(&fs::read(&flo).unwrap()).unwrap();
    assert_eq!(
        (field.width, field.height),
        (WIDTH as usize, HEIGHT as usize)
    );
    let known: Vec<f32> = field.flow.iter().flatten().map(|f| f.0).collect();
    assert!(known.len() > field.flow.len() / 2);
    assert!(known.iter().filter(|&&u| (u - 2.0).abs() < 0.2).count() > known.len() / 2);

    let picture = image::open(&png).unwrap();
    assert_eq!((picture.width(), picture.height()), (WIDTH, HEIGHT));
    assert!(matches!(picture, image::DynamicImage::ImageRgb8(_)));

    let summary = fs::read_to_string(&stats).unwrap();
    assert!(summary.starts_with("{\"nodes\": 108, \"repeat\": 3, \"median_core_seconds\": "));
}

#[test]
fn dense_with_a_coarser_grid() {
    let scratch = Scratch::new("coarse");
    let (output, out) = dense(&scratch, &[&"--cell", &"16", &"--window", &"11"]);
    assert!(output.status.success(), "{output:?}");
    let grid = rows(&fs::read_to_string(out).unwrap());
    assert_eq!(grid.len(), 6 * 4);
    assert_eq!(&grid[7][..2], ["24", "24"]);
}

#[test]
fn smoothing_moves_measured_nodes_only_and_can_be_turned_off() {
    let scratch = Scratch::new("smooth");
    let read = |out: PathBuf| rows(&fs::read_to_string(out).unwrap());
    let (output, out) = dense(&scratch, &[]);
    assert!(output.status.success(), "{output:?}");
    let smoothed = read(out);
    let (output, out) = dense(&scratch, &[&"--smooth-passes", &"0"]);
    assert!(output.status.success(), "{output:?}");
    let measured = read(out.clone());
    let (output, _) = dense(&scratch, &[&"--smooth-gate", &"0"]);
    assert!(output.status.success(), "{output:?}");
    assert_eq!(read(out), measured, "a zero gate is no smoothing too");
    // Same nodes, same statuses; most measured nodes averaged with their neighbours.
    assert_eq!(smoothed.len(), measured.len());
    let error = |row: &[String]| {
        let (dx, dy): (f64, f64) = (row[2].parse().unwrap(), row[3].parse().unwrap());
        (dx - 2.0).hypot(dy)
    };
    let (mut changed, mut before, mut after) = (0, Vec::new(), Vec::new());
    for (s, m) in smoothed.iter().zip(&measured) {
        assert_eq!((&s[..2], &s[4..]), (&m[..2], &m[4..]));
        if s[5] == "tracked" {
            changed += usize::from(s[2..4] != m[2..4]);
            before.push(error(m));
            after.push(error(s));
        } else {
            assert_eq!(s[2..4], m[2..4]);
        }
    }
    assert!(changed > before.len() / 2, "{changed} of {}", before.len());
    // This pair has no sensor noise, so there is little for the smoothing to average away
    // (tests/dense_grid.rs measures what it does under noise); it must not add error.
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    eprintln!(
        "mean error {:.4} px measured, {:.4} smoothed",
        mean(&before),
        mean(&after)
    );
    assert!(mean(&after) < mean(&before) + 0.01);
    for (flag, value, expected) in [
        (
            "--smooth-gate",
            "-1",
            "--smooth-gate: must be between 0 and 8 px (got -1)",
        ),
        (
            "--smooth-gate",
            "nan",
            "--smooth-gate: must be between 0 and 8 px (got NaN)",
        ),
        (
            "--smooth-passes",
            "9",
            "--smooth-passes: must be between 0 and 8 (got 9)",
        ),
    ] {
        let (output, _) = dense(&scratch, &[&flag, &value]);
        let message = assert_one_line_error(&output, 2, flag);
        assert_eq!(message, format!("host-sim: {expected}\n"));
    }
}

#[test]
fn dense_bad_input_names_the_culprit_and_writes_nothing() {
    let scratch = Scratch::new("bad");
    let flo = scratch.path("f.flo");
    let only_inputs = ["a.png", "b.png"];

    let (output, _) = dense(&scratch, &[&"--cell", &"0"]);
    assert_one_line_error(&output, 2, "--cell");
    let (output, _) = dense(&scratch, &[&"--cell", &"73", &"--flo", &flo]);
    let message = assert_one_line_error(&output, 1, "--cell");
    assert!(
        message.contains("larger than the 96x72 frames"),
        "{message}"
    );
    assert_eq!(scratch.entries(), only_inputs);

    // Level 3 of 96 x 72 is 12 x 9: narrower than half a 21 px window.
    let (output, _) = dense(&scratch, &[&"--window", &"21", &"--flo", &flo]);
    let message = assert_one_line_error(&output, 1, "a.png");
    assert!(message.contains("too small"), "{message}");
    assert_eq!(scratch.entries(), only_inputs);

    let small = scratch.path("small.png");
    textured(40, 30, 0.0).save(&small).unwrap();
    let out = scratch.path("grid.csv");
    let a = scratch.path("a.png");
    let output = host_sim(&[&"dense", &"--prev", &a, &"--next", &small, &"--out", &out]);
    assert_one_line_error(&output, 1, "small.png");
    let missing = scratch.path("missing.png");
    let output = host_sim(&[&"dense", &"--prev", &a, &"--next", &missing, &"--out", &out]);
    assert_one_line_error(&output, 1, "missing.png");

    // An output that cannot be created stops the run before any work.
    let nowhere = scratch.path("no-such-dir").join("f.png");
    let (output, _) = dense(&scratch, &[&"--png", &nowhere]);
    assert_one_line_error(&output, 1, "no-such-dir");
    assert_eq!(scratch.entries(), ["a.png", "b.png", "small.png"]);
}

/// Frames 0.. of a still scene with two objects moving across it, as PNGs in `dir`.
fn write_sequence(dir: &Path, frames: usize) -> ObjectSequence {
    fs::create_dir_all(dir).unwrap();
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let view = BoxPx {
        x: 0.0,
        y: 0.0,
        w: w as f64,
        h: h as f64,
    };
    let objects = vec![
        MovingObject::new(11, (16.0, 14.0), (8.0, 8.0), (2.5, 0.5), view),
        MovingObject::new(12, (20.0, 16.0), (60.0, 46.0), (-1.5, -1.0), view),
    ];
    let scene = Scene::new(SceneSpec::new(w, h, 5).with_noise(1.0));
    let still = CameraPath::still((w as f64 / 2.0, h as f64 / 2.0));
    let sequence = ObjectSequence::new(scene, objects, still, frames);
    for k in 0..frames {
        let f = sequence.frame(k);
        let image = GrayImage::from_raw(f.width as u32, f.height as u32, f.data).unwrap();
        image.save(dir.join(format!("{k:04}.png"))).unwrap();
    }
    sequence
}

/// The rows of boxes.csv as numbers.
fn boxes(path: &Path) -> Vec<[f64; 5]> {
    let text = fs::read_to_string(path).unwrap();
    assert_eq!(text.lines().next(), Some("frame,x,y,w,h,nodes"));
    rows(&text)
        .iter()
        .map(|r| std::array::from_fn(|i| r[i].parse().unwrap()))
        .collect()
}

#[test]
fn motion_finds_the_objects_of_a_small_sequence() {
    let scratch = Scratch::new("motion");
    let frames = scratch.path("frames");
    let sequence = write_sequence(&frames, 6);
    let (out, viz) = (scratch.path("boxes.csv"), scratch.path("viz"));
    let output = host_sim(&[&"motion", &frames, &"--out", &out, &"--viz", &viz]);
    assert!(output.status.success(), "{output:?}");
    // Not a terminal: no progress on stderr.
    assert!(output.stderr.is_empty() && output.stdout.is_empty());

    let found = boxes(&out);
    // A region is reported once it has moved in two consecutive pairs: none in frame 1.
    assert!(found.iter().all(|r| r[0] >= 2.0), "{found:?}");
    for k in 2..6 {
        let in_frame: Vec<BoxPx> = found
            .iter()
            .filter(|r| r[0] == k as f64)
            .map(|r| BoxPx {
                x: r[1],
                y: r[2],
                w: r[3],
                h: r[4],
            })
            .collect();
        eprintln!("frame {k}: {in_frame:?}");
        for truth in sequence.boxes(k) {
            let best = in_frame.iter().map(|b| b.iou(&truth)).fold(0.0, f64::max);
            assert!(
                best >= 0.3,
                "frame {k}: object {truth:?} found with IoU {best}"
            );
        }
        assert_eq!(in_frame.len(), 2, "frame {k}");
    }
    let pictures = entries(&viz);
    assert_eq!(pictures.len(), 5);
    assert_eq!(pictures[0], "frame_000001.png");
    let picture = image::open(viz.join(&pictures[0])).unwrap();
    assert_eq!((picture.width(), picture.height()), (WIDTH, HEIGHT));
}

#[test]
fn motion_reads_y4m_on_standard_input() {
    let scratch = Scratch::new("stdin");
    let sequence = write_sequence(&scratch.path("frames"), 4);
    let mut y4m = format!("YUV4MPEG2 W{WIDTH} H{HEIGHT} F25:1 Cmono\n").into_bytes();
    for k in 0..4 {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend_from_slice(&sequence.frame(k).data);
    }
    let out = scratch.path("boxes.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["motion", "-", "--out"])
        .arg(&out)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&y4m).unwrap();
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "{output:?}");
    let found = boxes(&out);
    assert_eq!(found.iter().filter(|r| r[0] == 3.0).count(), 2);
}

#[test]
fn motion_stops_at_a_bad_frame_and_keeps_the_frames_before() {
    let scratch = Scratch::new("badframe");
    let frames = scratch.path("frames");
    write_sequence(&frames, 5);
    fs::write(frames.join("0003.png"), b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let (out, viz) = (scratch.path("boxes.csv"), scratch.path("viz"));
    // Every pair's boxes (no persistence), so that frame 1 has some.
    let output = host_sim(&[
        &"motion",
        &frames,
        &"--out",
        &out,
        &"--viz",
        &viz,
        &"--persist",
        &"1",
    ]);
    let message = assert_one_line_error(&output, 1, "0003.png");
    assert!(message.contains("frame 3"), "{message}");
    let found = boxes(&out);
    let last = found.iter().map(|r| r[0]).fold(0.0, f64::max);
    assert_eq!(last, 2.0);
    assert!(found.iter().any(|r| r[0] == 1.0));
    assert_eq!(entries(&viz), ["frame_000001.png", "frame_000002.png"]);

    // A frame of another size stops the run the same way.
    fs::remove_file(frames.join("0003.png")).unwrap();
    textured(WIDTH / 2, HEIGHT, 0.0)
        .save(frames.join("0002.png"))
        .unwrap();
    let output = host_sim(&[&"motion", &frames, &"--out", &out, &"--persist", &"1"]);
    let message = assert_one_line_error(&output, 1, "0002.png");
    assert!(
        message.contains("frame 2") && message.contains("48x72"),
        "{message}"
    );
    assert_eq!(boxes(&out).iter().map(|r| r[0]).fold(0.0, f64::max), 1.0);
}

#[test]
fn motion_bad_input_writes_nothing() {
    let scratch = Scratch::new("motionbad");
    let out = scratch.path("boxes.csv");
    let missing = scratch.path("missing");
    let output = host_sim(&[&"motion", &missing, &"--out", &out]);
    assert_one_line_error(&output, 1, "missing");
    let empty = scratch.path("empty");
    fs::create_dir_all(&empty).unwrap();
    let output = host_sim(&[&"motion", &empty, &"--out", &out]);
    assert_one_line_error(&output, 1, "no frames");
    let frames = scratch.path("frames");
    write_sequence(&frames, 2);
    let output = host_sim(&[&"motion", &frames, &"--out", &out, &"--cell", &"100"]);
    assert_one_line_error(&output, 1, "--cell");
    assert!(!out.exists());
    let output = host_sim(&[&"motion", &frames, &"--out", &out, &"--threshold", &"-1"]);
    assert_one_line_error(&output, 2, "--threshold");
    let output = host_sim(&[&"motion", &"--out", &out]);
    assert_one_line_error(&output, 2, "INPUT");
    assert_eq!(scratch.entries(), ["empty", "frames"]);
}

#[test]
fn help_texts_go_to_stdout() {
    for command in ["dense", "motion"] {
        let output = host_sim(&[&command, &"--help"]);
        assert!(output.status.success());
        let text = String::from_utf8(output.stdout).unwrap();
        assert!(text.starts_with(&format!("host-sim {command}:")), "{text}");
    }
}
