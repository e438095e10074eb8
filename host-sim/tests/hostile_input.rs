//! Hostile input for every command that reads files: damaged images and video, folders that
//! hold more than frames, frames of mixed size, outputs that cannot be written, malformed CSV.
//!
//! Every case checks the contract's error behaviour: exit status 1, one line on stderr naming
//! the file (and the frame or cell) and the problem, no panic text, and no half-written output.
//! Single-pair commands write nothing; sequence commands keep exactly the results of the frames
//! before the bad one, which the tests check by comparing with a run on those frames alone.

mod common;

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::fs;
use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{assert_one_line_error, host_sim, Scratch};
use image::{DynamicImage, GrayImage, ImageFormat, Luma};

const WIDTH: u32 = 128;
const HEIGHT: u32 = 96;
/// Frames of the sequences; a bad frame replaces frame [`BAD`].
const FRAMES: usize = 6;
const BAD: usize = 3;

/// A smooth, non-repeating texture, its content moved `shift` px right and `shift / 2` down.
fn textured(width: u32, height: u32, shift: f32) -> GrayImage {
    GrayImage::from_fn(width, height, |x, y| {
        let (x, y) = (x as f32 - shift, y as f32 - shift / 2.0);
        let value = 128.0
            + 45.0 * (0.31 * x + 0.6 * (0.17 * y).sin()).sin()
            + 40.0 * (0.23 * y + 0.4 * (0.13 * x).cos()).cos()
            + 20.0 * (0.07 * (x + y)).sin();
        Luma([value.round().clamp(0.0, 255.0) as u8])
    })
}

/// Frame `k` of the test sequence: the texture panning 1.5 px per frame.
fn frame(k: usize) -> GrayImage {
    textured(WIDTH, HEIGHT, 1.5 * k as f32)
}

fn encode(image: &GrayImage, format: ImageFormat) -> Vec<u8> {
    let mut bytes = Cursor::new(Vec::new());
    DynamicImage::ImageLuma8(image.clone())
        .write_to(&mut bytes, format)
        .unwrap();
    bytes.into_inner()
}

/// A damaged frame file: its name in a folder (the extension matters) and its bytes.
#[derive(Debug, Clone)]
struct Damage {
    /// What the case is, for failure messages.
    what: &'static str,
    extension: &'static str,
    bytes: Vec<u8>,
    /// Words the error must contain besides the file name.
    says: &'static str,
}

/// Every way a single frame file can be bad.
fn damaged_frames() -> Vec<Damage> {
    let png = encode(&frame(BAD), ImageFormat::Png);
    let jpeg = encode(&frame(BAD), ImageFormat::Jpeg);
    vec![
        Damage {
            what: "PNG with damaged pixel data",
            extension: "png",
            bytes: flip_bytes(&png, png.len() / 3, png.len() - 20),
            says: "corrupt",
        },
        Damage {
            what: "truncated PNG",
            extension: "png",
            bytes: png[..png.len() * 2 / 3].to_vec(),
            says: "corrupt",
        },
        Damage {
            what: "PNG signature and nothing else",
            extension: "png",
            bytes: png[..8].to_vec(),
            says: "corrupt",
        },
        Damage {
            what: "JPEG with damaged headers",
            extension: "jpg",
            bytes: flip_bytes(&jpeg, 4, 200),
            says: "corrupt",
        },
        Damage {
            what: "truncated JPEG",
            extension: "jpg",
            bytes: jpeg[..jpeg.len() * 2 / 3].to_vec(),
            says: "corrupt",
        },
        Damage {
            what: "JPEG without its end marker",
            extension: "jpg",
            bytes: jpeg[..jpeg.len() - 2].to_vec(),
            says: "corrupt",
        },
        Damage {
            what: "text named like an image",
            extension: "png",
            bytes: b"this is a note, not a frame\n".to_vec(),
            says: "not a PNG, JPEG, PGM or BMP image",
        },
        Damage {
            what: "empty file",
            extension: "png",
            bytes: Vec::new(),
            says: "not a PNG, JPEG, PGM or BMP image",
        },
        Damage {
            what: "truncated PGM",
            extension: "pgm",
            bytes: {
                let pgm = encode(&frame(BAD), ImageFormat::Pnm);
                pgm[..pgm.len() / 2].to_vec()
            },
            says: "corrupt",
        },
        Damage {
            what: "PNG whose header claims 60000 x 60000 pixels",
            extension: "png",
            bytes: huge_png_header(),
            says: "60000x60000",
        },
        Damage {
            what: "frame of another size",
            extension: "png",
            bytes: encode(&textured(WIDTH / 2, HEIGHT, 0.0), ImageFormat::Png),
            says: "64x96",
        },
    ]
}

/// `bytes` with every 7th byte from `from` to `to` inverted.
fn flip_bytes(bytes: &[u8], from: usize, to: usize) -> Vec<u8> {
    let mut damaged = bytes.to_vec();
    for byte in damaged[from..to].iter_mut().step_by(7) {
        *byte = !*byte;
    }
    damaged
}

/// A PNG signature and a valid header chunk for a 60000 x 60000 grey image, then a few bytes of
/// image data: a file that asks the decoder for 3.6 GB.
fn huge_png_header() -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&60_000u32.to_be_bytes());
    ihdr.extend_from_slice(&60_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    png.extend_from_slice(&[0, 0, 0, 2, b'I', b'D', b'A', b'T', 0x78, 0x9c, 0, 0, 0, 0]);
    png
}

/// The CRC-32 of PNG chunks.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Every file under `dir` (relative path) with its contents; directories appear as entries
/// ending in `/`, so an empty one shows too.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    if dir.exists() {
        collect(dir, dir, &mut files);
    }
    files
}

fn collect(root: &Path, dir: &Path, files: &mut BTreeMap<String, Vec<u8>>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .into_owned();
        if path.is_dir() {
            files.insert(format!("{name}/"), Vec::new());
            collect(root, &path, files);
        } else {
            files.insert(name, fs::read(&path).unwrap());
        }
    }
}

/// Makes `dir` an empty directory.
fn fresh_dir(dir: &Path) {
    let _ = fs::remove_dir_all(dir);
    fs::create_dir_all(dir).unwrap();
}

/// The names of the files (not directories) in a snapshot.
fn file_names(files: &BTreeMap<String, Vec<u8>>) -> Vec<&str> {
    files
        .keys()
        .filter(|name| !name.ends_with('/'))
        .map(String::as_str)
        .collect()
}

fn args(words: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    words.iter().map(|w| w.as_ref().to_owned()).collect()
}

fn run(args: &[OsString]) -> Output {
    let words: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|a| a as _).collect();
    host_sim(&words)
}

/// Asserts success, showing stderr otherwise.
fn assert_success(output: &Output, what: &str) {
    assert!(
        output.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Checks the error contract and that the message says each of `words`.
fn assert_error(output: &Output, what: &str, culprit: &str, words: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{what}: {stderr}");
    let message = assert_one_line_error(output, 1, culprit);
    for word in words {
        assert!(message.contains(word), "{what}: {message:?} lacks {word:?}");
    }
    message
}

// ---------------------------------------------------------------------------------------------
// Single-pair commands: nothing is written on error.

/// A single-pair command: its name and its arguments for frames `a` and `b`, writing into `out`.
struct PairCommand {
    name: &'static str,
    args: fn(&Path, &Path, &Path) -> Vec<OsString>,
}

const PAIR_COMMANDS: [PairCommand; 2] = [
    PairCommand {
        name: "flow",
        args: |a, b, out| {
            let points = out.parent().unwrap().join("p.csv");
            args(&[
                &"flow",
                &"--prev",
                &a,
                &"--next",
                &b,
                &"--points",
                &points,
                &"--out",
                &out.join("o.csv"),
                &"--stats",
                &out.join("s.json"),
            ])
        },
    },
    PairCommand {
        name: "dense",
        args: |a, b, out| {
            args(&[
                &"dense",
                &"--prev",
                &a,
                &"--next",
                &b,
                &"--out",
                &out.join("grid.csv"),
                &"--flo",
                &out.join("f.flo"),
                &"--png",
                &out.join("f.png"),
            ])
        },
    },
];

/// A scratch directory with a good pair a.png and b.png, p.csv, and an empty out/.
fn pair_scratch(test: &str) -> (Scratch, PathBuf, PathBuf, PathBuf) {
    let scratch = Scratch::new(test);
    let (a, b, out) = (
        scratch.path("a.png"),
        scratch.path("b.png"),
        scratch.path("out"),
    );
    fs::write(&a, encode(&frame(0), ImageFormat::Png)).unwrap();
    fs::write(&b, encode(&frame(1), ImageFormat::Png)).unwrap();
    fs::write(scratch.path("p.csv"), "x,y\n40,30\n64,48\n90,70\n").unwrap();
    fs::create_dir(&out).unwrap();
    (scratch, a, b, out)
}

#[test]
fn the_good_pair_works_so_the_failures_below_are_the_damage() {
    let (_scratch, a, b, out) = pair_scratch("pair-good");
    for command in &PAIR_COMMANDS {
        assert_success(&run(&(command.args)(&a, &b, &out)), command.name);
    }
    assert_eq!(
        file_names(&snapshot(&out)),
        ["f.flo", "f.png", "grid.csv", "o.csv", "s.json"]
    );
}

#[test]
fn single_pair_commands_refuse_damaged_frames_and_write_nothing() {
    for damage in damaged_frames() {
        let (scratch, a, _, out) = pair_scratch("pair-damage");
        let bad = scratch.path(&format!("bad.{}", damage.extension));
        fs::write(&bad, &damage.bytes).unwrap();
        for command in &PAIR_COMMANDS {
            // The damaged frame as either frame of the pair.
            for (prev, next) in [(&a, &bad), (&bad, &a)] {
                let what = format!("{} on {}", command.name, damage.what);
                let output = run(&(command.args)(prev, next, &out));
                let culprit = bad.display().to_string();
                assert_error(&output, &what, &culprit, &[damage.says]);
                assert!(snapshot(&out).is_empty(), "{what}: {:?}", snapshot(&out));
            }
        }
    }
}

#[test]
fn single_pair_commands_refuse_a_directory_or_a_missing_file_as_a_frame() {
    let (scratch, a, _, out) = pair_scratch("pair-notfile");
    let missing = scratch.path("missing.png");
    let directory = scratch.path("frame.png");
    fs::create_dir(&directory).unwrap();
    for command in &PAIR_COMMANDS {
        for (bad, says) in [(&missing, "no such file"), (&directory, "is a directory")] {
            let output = run(&(command.args)(&a, bad, &out));
            assert_error(&output, command.name, &bad.display().to_string(), &[says]);
            assert!(snapshot(&out).is_empty(), "{}", command.name);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sequence commands: a bad frame stops the run, the results of the frames before it are kept.

/// A sequence command: its name and its arguments for `input`, writing everything into `out`.
struct SequenceCommand {
    name: &'static str,
    args: fn(&Path, &Path) -> Vec<OsString>,
}

const SEQUENCE_COMMANDS: [SequenceCommand; 4] = [
    SequenceCommand {
        name: "track",
        args: |input, out| {
            args(&[
                &"track",
                &input,
                &"--out",
                &out.join("tracks.csv"),
                &"--viz",
                &out.join("viz"),
                &"--max-tracks",
                &"30",
            ])
        },
    },
    SequenceCommand {
        name: "motion",
        args: |input, out| {
            args(&[
                &"motion",
                &input,
                &"--out",
                &out.join("boxes.csv"),
                &"--viz",
                &out.join("viz"),
            ])
        },
    },
    SequenceCommand {
        name: "egomotion",
        args: |input, out| {
            args(&[
                &"egomotion",
                &input,
                &"--out",
                &out.join("ego.csv"),
                &"--mavlink",
                &out.join("flow.bin"),
            ])
        },
    },
    SequenceCommand {
        name: "stabilize",
        args: |input, out| {
            args(&[
                &"stabilize",
                &input,
                &"--out",
                &out.join("frames"),
                &"--smoothing",
                &"2",
            ])
        },
    },
];

/// Writes frames `0..count` into `dir` as PNG, named so that file-name order is frame order.
fn write_frames(dir: &Path, count: usize) {
    fs::create_dir_all(dir).unwrap();
    for k in 0..count {
        let name = dir.join(format!("{k:04}.png"));
        fs::write(name, encode(&frame(k), ImageFormat::Png)).unwrap();
    }
}

/// What each command writes for the first [`BAD`] frames alone: the results a run that meets
/// a bad frame [`BAD`] must keep, file for file and byte for byte.
fn prefix_results(scratch: &Scratch) -> Vec<BTreeMap<String, Vec<u8>>> {
    let prefix = scratch.path("prefix");
    write_frames(&prefix, BAD);
    SEQUENCE_COMMANDS
        .iter()
        .map(|command| {
            let out = scratch.path(&format!("prefix-{}", command.name));
            fresh_dir(&out);
            assert_success(&run(&(command.args)(&prefix, &out)), command.name);
            let results = snapshot(&out);
            assert!(!file_names(&results).is_empty(), "{}", command.name);
            results
        })
        .collect()
}

#[test]
fn a_bad_frame_stops_every_sequence_command_and_the_frames_before_it_are_kept() {
    let scratch = Scratch::new("seq-damage");
    let expected = prefix_results(&scratch);
    for damage in damaged_frames() {
        let input = scratch.path("frames");
        let _ = fs::remove_dir_all(&input);
        write_frames(&input, FRAMES);
        fs::remove_file(input.join(format!("{BAD:04}.png"))).unwrap();
        let bad = input.join(format!("{BAD:04}.{}", damage.extension));
        fs::write(&bad, &damage.bytes).unwrap();
        for (command, expected) in SEQUENCE_COMMANDS.iter().zip(&expected) {
            let what = format!("{} on {}", command.name, damage.what);
            let out = scratch.path("out");
            fresh_dir(&out);
            let output = run(&(command.args)(&input, &out));
            let frame = format!("frame {BAD}");
            assert_error(
                &output,
                &what,
                &bad.display().to_string(),
                &[&frame, damage.says],
            );
            assert!(snapshot(&out) == *expected, "{what}: results differ");
        }
    }
}

#[test]
fn a_bad_first_frame_leaves_no_output_file() {
    let scratch = Scratch::new("seq-first");
    let input = scratch.path("frames");
    write_frames(&input, FRAMES);
    fs::write(input.join("0000.png"), b"not a picture").unwrap();
    for command in &SEQUENCE_COMMANDS {
        let out = scratch.path("out");
        fresh_dir(&out);
        let output = run(&(command.args)(&input, &out));
        assert_error(&output, command.name, "0000.png", &["frame 0"]);
        let written = snapshot(&out);
        assert!(
            file_names(&written).is_empty(),
            "{}: {written:?}",
            command.name
        );
    }
}

#[test]
fn a_folder_with_other_files_is_refused_before_any_frame_is_read() {
    let scratch = Scratch::new("seq-other");
    for (stray, is_dir, says) in [
        ("notes.txt", false, "not a frame image"),
        ("0002.png.bak", false, "not a frame image"),
        ("thumbs", true, "is a directory"),
    ] {
        let input = scratch.path("frames");
        let _ = fs::remove_dir_all(&input);
        write_frames(&input, FRAMES);
        if is_dir {
            fs::create_dir(input.join(stray)).unwrap();
        } else {
            fs::write(input.join(stray), b"stray").unwrap();
        }
        // Hidden files (.DS_Store and the like) are no frames and are skipped.
        fs::write(input.join(".DS_Store"), b"junk").unwrap();
        for command in &SEQUENCE_COMMANDS {
            let out = scratch.path("out");
            fresh_dir(&out);
            let output = run(&(command.args)(&input, &out));
            let what = format!("{} with {stray}", command.name);
            assert_error(&output, &what, stray, &[says]);
            let written = snapshot(&out);
            assert!(file_names(&written).is_empty(), "{what}: {written:?}");
        }
    }
}

#[test]
fn empty_and_missing_sequences_write_nothing() {
    let scratch = Scratch::new("seq-empty");
    let empty = scratch.path("empty");
    fs::create_dir(&empty).unwrap();
    let missing = scratch.path("missing");
    let no_y4m = scratch.path("none.y4m");
    let header_only = scratch.path("header.y4m");
    fs::write(&header_only, b"YUV4MPEG2 W128 H96 F30:1 Cmono\n").unwrap();
    for (input, says) in [
        (&empty, "no frames"),
        (&missing, "no such file"),
        (&no_y4m, "no such file"),
        (&header_only, "no frames"),
    ] {
        for command in &SEQUENCE_COMMANDS {
            let out = scratch.path("out");
            fresh_dir(&out);
            let output = run(&(command.args)(input, &out));
            let what = format!("{} on {}", command.name, input.display());
            assert_error(&output, &what, &input.display().to_string(), &[says]);
            let written = snapshot(&out);
            assert!(file_names(&written).is_empty(), "{what}: {written:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// y4m video.

/// The test sequence's first `count` frames as a y4m stream with `colour` chroma (`C420jpeg`
/// and the like; chroma samples are mid-grey).
fn y4m(count: usize, colour: &str) -> Vec<u8> {
    let mut bytes = format!("YUV4MPEG2 W{WIDTH} H{HEIGHT} F30:1 Ip A1:1 {colour}\n").into_bytes();
    let chroma = match colour {
        "Cmono" => 0,
        "C444" => 2 * (WIDTH * HEIGHT) as usize,
        _ => 2 * (WIDTH.div_ceil(2) * HEIGHT.div_ceil(2)) as usize,
    };
    for k in 0..count {
        bytes.extend_from_slice(b"FRAME\n");
        bytes.extend_from_slice(frame(k).as_raw());
        bytes.extend(std::iter::repeat_n(128, chroma));
    }
    bytes
}

/// Every way a y4m stream can be bad from the start: the error comes before any frame.
fn bad_y4m_headers() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let body = |header: &str| {
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(&y4m(2, "Cmono")[y4m(0, "Cmono").len()..]);
        bytes
    };
    vec![
        ("empty file", Vec::new(), "empty input"),
        (
            "no signature",
            body("YUV4MPEG W128 H96 Cmono\n"),
            "no YUV4MPEG2 signature",
        ),
        (
            "a PNG named .y4m",
            encode(&frame(0), ImageFormat::Png),
            "no YUV4MPEG2 signature",
        ),
        ("no width", body("YUV4MPEG2 H96 Cmono\n"), "no width"),
        (
            "bad height",
            body("YUV4MPEG2 W128 H9x6 Cmono\n"),
            "bad height",
        ),
        ("zero width", body("YUV4MPEG2 W0 H96 Cmono\n"), "no pixels"),
        (
            "huge frame",
            body("YUV4MPEG2 W100000 H96 Cmono\n"),
            "at most 4096",
        ),
        (
            "10-bit colour",
            body("YUV4MPEG2 W128 H96 C420p10\n"),
            "unsupported y4m colour space C420p10",
        ),
        (
            "unknown colour",
            body("YUV4MPEG2 W128 H96 Cxyz\n"),
            "unsupported y4m colour space Cxyz",
        ),
        (
            "bad frame rate",
            body("YUV4MPEG2 W128 H96 F30:0 Cmono\n"),
            "bad frame rate",
        ),
        (
            "header cut short",
            b"YUV4MPEG2 W128 H9".to_vec(),
            "truncated",
        ),
        (
            "binary garbage",
            vec![0xA5; 10_000],
            "no YUV4MPEG2 signature",
        ),
    ]
}

#[test]
fn bad_y4m_headers_are_named_and_nothing_is_written() {
    let scratch = Scratch::new("y4m-header");
    let clip = scratch.path("clip.y4m");
    for (what, bytes, says) in bad_y4m_headers() {
        fs::write(&clip, &bytes).unwrap();
        for command in &SEQUENCE_COMMANDS {
            let out = scratch.path("out");
            fresh_dir(&out);
            let output = run(&(command.args)(&clip, &out));
            let what = format!("{} on {what}", command.name);
            assert_error(&output, &what, "clip.y4m", &[says]);
            let written = snapshot(&out);
            assert!(file_names(&written).is_empty(), "{what}: {written:?}");
        }
    }
}

/// Streams whose frame [`BAD`] is damaged, the frames before it intact.
fn bad_y4m_frames() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let whole = y4m(BAD + 1, "C420jpeg");
    let frame_len = 6 + (WIDTH * HEIGHT) as usize * 3 / 2;
    let at_bad = whole.len() - frame_len;
    let mut no_marker = whole.clone();
    no_marker[at_bad..at_bad + 5].copy_from_slice(b"FRAMX");
    vec![
        (
            "last frame cut in its picture",
            whole[..whole.len() - 100].to_vec(),
            "truncated",
        ),
        (
            "last frame cut in its luma",
            whole[..at_bad + 6 + 50].to_vec(),
            "truncated",
        ),
        (
            "last frame cut in its marker",
            whole[..at_bad + 3].to_vec(),
            "truncated FRAME marker",
        ),
        (
            "a frame without its marker",
            no_marker,
            "expected a FRAME marker",
        ),
    ]
}

#[test]
fn a_damaged_y4m_frame_stops_the_run_and_the_frames_before_it_are_kept() {
    let scratch = Scratch::new("y4m-frame");
    // What the first frames alone give, from a y4m file so that nothing but the damage differs.
    let prefix = scratch.path("prefix.y4m");
    fs::write(&prefix, y4m(BAD, "C420jpeg")).unwrap();
    let expected: Vec<_> = SEQUENCE_COMMANDS
        .iter()
        .map(|command| {
            let out = scratch.path(&format!("prefix-{}", command.name));
            fresh_dir(&out);
            assert_success(&run(&(command.args)(&prefix, &out)), command.name);
            snapshot(&out)
        })
        .collect();
    let clip = scratch.path("clip.y4m");
    for (what, bytes, says) in bad_y4m_frames() {
        fs::write(&clip, &bytes).unwrap();
        for (command, expected) in SEQUENCE_COMMANDS.iter().zip(&expected) {
            let out = scratch.path("out");
            fresh_dir(&out);
            let output = run(&(command.args)(&clip, &out));
            let what = format!("{} on {what}", command.name);
            let frame = format!("frame {BAD}");
            assert_error(&output, &what, "clip.y4m", &[&frame, says]);
            assert!(snapshot(&out) == *expected, "{what}: results differ");
        }
    }
}

#[test]
fn a_truncated_y4m_on_standard_input_keeps_the_frames_before_it() {
    let scratch = Scratch::new("y4m-stdin");
    let whole = y4m(BAD + 1, "C420jpeg");
    let cut = &whole[..whole.len() - 100];
    let clip = scratch.path("clip.y4m");
    fs::write(&clip, cut).unwrap();
    for command in &SEQUENCE_COMMANDS {
        let (from_file, from_stdin) = (scratch.path("file"), scratch.path("stdin"));
        fresh_dir(&from_file);
        fresh_dir(&from_stdin);
        assert_eq!(
            run(&(command.args)(&clip, &from_file)).status.code(),
            Some(1)
        );
        let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args((command.args)(Path::new("-"), &from_stdin))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The command may stop reading at the damage; a closed pipe is expected then.
        let _ = child.stdin.take().unwrap().write_all(cut);
        let output = child.wait_with_output().unwrap();
        let frame = format!("frame {BAD}");
        assert_error(
            &output,
            command.name,
            "standard input",
            &[&frame, "truncated"],
        );
        let (file, stdin) = (snapshot(&from_file), snapshot(&from_stdin));
        assert!(!file_names(&stdin).is_empty(), "{}", command.name);
        assert!(file == stdin, "{}: results differ", command.name);
        let _ = fs::remove_dir_all(from_file);
        let _ = fs::remove_dir_all(from_stdin);
    }
}

// ---------------------------------------------------------------------------------------------
// Outputs that cannot be written. The tests may run as root, which ignores permissions, so
// the paths are impossible for anyone: under a regular file, or a directory where a file goes.

/// Where each output flag of each command is pointed, in turn, by the unwritable-path tests.
fn output_flags(command: &str) -> &'static [&'static str] {
    match command {
        "flow" => &["--out", "--stats"],
        "dense" => &["--out", "--flo", "--png"],
        "track" => &["--out", "--viz"],
        "motion" => &["--out", "--viz"],
        "egomotion" => &["--out", "--mavlink"],
        "stabilize" => &["--out"],
        _ => unreachable!("{command}"),
    }
}

/// `args` with the value of `flag` replaced by `path`.
fn with_value(args: &[OsString], flag: &str, path: &Path) -> Vec<OsString> {
    let mut args = args.to_vec();
    let at = args.iter().position(|a| a == flag).unwrap();
    args[at + 1] = path.as_os_str().to_owned();
    args
}

/// Paths no one can write a file at: under a regular file, and (for files) a directory.
fn impossible_paths(scratch: &Scratch, wants_directory: bool) -> Vec<(PathBuf, &'static str)> {
    let file = scratch.path("regular");
    fs::write(&file, b"a file").unwrap();
    let taken = scratch.path("taken");
    let mut paths = vec![
        (file.join("out"), "not a directory"),
        (file.join("deeper").join("out"), "not a directory"),
    ];
    if wants_directory {
        paths.push((file.clone(), "not a directory"));
    } else {
        fs::create_dir_all(&taken).unwrap();
        paths.push((taken, "is a directory"));
    }
    paths
}

fn is_directory_flag(command: &str, flag: &str) -> bool {
    flag == "--viz" || (command == "stabilize" && flag == "--out")
}

#[test]
fn unwritable_outputs_are_named_before_any_work_and_nothing_is_written() {
    let (scratch, a, b, out) = pair_scratch("unwritable");
    let frames = scratch.path("frames");
    write_frames(&frames, FRAMES);
    let commands: Vec<(&str, Vec<OsString>)> = PAIR_COMMANDS
        .iter()
        .map(|c| (c.name, (c.args)(&a, &b, &out)))
        .chain(
            SEQUENCE_COMMANDS
                .iter()
                .map(|c| (c.name, (c.args)(&frames, &out))),
        )
        .collect();
    for (name, good) in &commands {
        for &flag in output_flags(name) {
            for (path, says) in impossible_paths(&scratch, is_directory_flag(name, flag)) {
                let before = snapshot(scratch.dir());
                let output = run(&with_value(good, flag, &path));
                let what = format!("{name} {flag} {}", path.display());
                assert_error(&output, &what, &path.display().to_string(), &[says]);
                assert!(
                    snapshot(scratch.dir()) == before,
                    "{what}: something was written"
                );
            }
        }
    }
}

/// True when a directory without write permission refuses new files here: false for root,
/// which ignores permissions.
fn permissions_are_enforced(scratch: &Scratch) -> bool {
    use std::os::unix::fs::PermissionsExt;
    let probe = scratch.path("probe");
    fs::create_dir(&probe).unwrap();
    fs::set_permissions(&probe, fs::Permissions::from_mode(0o555)).unwrap();
    let refused = fs::write(probe.join("file"), b"").is_err();
    fs::set_permissions(&probe, fs::Permissions::from_mode(0o755)).unwrap();
    fs::remove_dir_all(&probe).unwrap();
    refused
}

#[test]
fn a_read_only_directory_is_named_when_permissions_apply() {
    use std::os::unix::fs::PermissionsExt;
    let (scratch, a, b, out) = pair_scratch("readonly");
    if !permissions_are_enforced(&scratch) {
        // Running as root: the cases above cover outputs that no one can write.
        return;
    }
    let frames = scratch.path("frames");
    write_frames(&frames, FRAMES);
    let locked = scratch.path("locked");
    fs::create_dir(&locked).unwrap();
    fs::set_permissions(&locked, fs::Permissions::from_mode(0o555)).unwrap();
    let commands: Vec<(&str, Vec<OsString>)> = PAIR_COMMANDS
        .iter()
        .map(|c| (c.name, (c.args)(&a, &b, &out)))
        .chain(
            SEQUENCE_COMMANDS
                .iter()
                .map(|c| (c.name, (c.args)(&frames, &out))),
        )
        .collect();
    for (name, good) in &commands {
        for &flag in output_flags(name) {
            let path = locked.join("out");
            let before = snapshot(scratch.dir());
            let output = run(&with_value(good, flag, &path));
            let what = format!("{name} {flag} {}", path.display());
            assert_error(
                &output,
                &what,
                &path.display().to_string(),
                &["permission denied"],
            );
            assert!(
                snapshot(scratch.dir()) == before,
                "{what}: something was written"
            );
        }
    }
    fs::set_permissions(&locked, fs::Permissions::from_mode(0o755)).unwrap();
}

// ---------------------------------------------------------------------------------------------
// CSV inputs: the points of `flow` and the gyro log of `egomotion`.

/// Malformed points files, with the words the error must contain.
const BAD_POINTS: &[(&str, &str, &[&str])] = &[
    (
        "bad number",
        "x,y\n10,10\n20,1.2.3\n",
        &["line 3", "column 2 (y)", "\"1.2.3\" is not a number"],
    ),
    (
        "decimal commas",
        "x,y\n10,5,20,5\n",
        &["line 2", "expected 2 fields like the header, found 4"],
    ),
    (
        "missing column",
        "x\n10\n",
        &["line 1", "header starting with \"x,y\""],
    ),
    (
        "short record",
        "x,y\n10,10\n20\n",
        &["line 3", "expected 2 fields like the header, found 1"],
    ),
    (
        "long record",
        "x,y\n10,10,5\n",
        &["line 2", "expected 2 fields like the header, found 3"],
    ),
    (
        "empty field",
        "x,y\n,10\n",
        &["line 2", "column 1 (x)", "\"\" is not a number"],
    ),
    (
        "NaN",
        "x,y\n10,NaN\n",
        &["line 2", "column 2 (y)", "\"NaN\" is not a finite number"],
    ),
    (
        "infinity",
        "x,y\ninf,10\n",
        &["line 2", "column 1 (x)", "\"inf\" is not a finite number"],
    ),
    (
        "negative infinity",
        "x,y\n10,-infinity\n",
        &["column 2 (y)", "is not a finite number"],
    ),
    (
        "overflow to infinity",
        "x,y\n1e39,10\n",
        &["column 1 (x)", "\"1e39\" is not a finite number"],
    ),
    (
        "empty file",
        "",
        &["empty file", "expected a header line \"x,y\""],
    ),
    (
        "header swapped",
        "y,x\n1,2\n",
        &["line 1", "header starting with \"x,y\""],
    ),
    ("no header", "10,10\n", &["line 1", "header"]),
];

#[test]
fn malformed_points_files_are_named_to_the_cell_and_flow_writes_nothing() {
    let (scratch, a, b, out) = pair_scratch("points");
    let points = scratch.path("p.csv");
    for (what, text, says) in BAD_POINTS {
        fs::write(&points, text).unwrap();
        let output = run(&(PAIR_COMMANDS[0].args)(&a, &b, &out));
        assert_error(&output, what, "p.csv", says);
        assert!(snapshot(&out).is_empty(), "{what}");
    }
    fs::write(&points, b"x,y\n\xff\xfe,1\n").unwrap();
    let output = run(&(PAIR_COMMANDS[0].args)(&a, &b, &out));
    assert_error(&output, "not UTF-8", "p.csv", &["not a text file"]);
    fs::remove_file(&points).unwrap();
    let output = run(&(PAIR_COMMANDS[0].args)(&a, &b, &out));
    assert_error(&output, "missing", "p.csv", &["no such file"]);
    assert!(snapshot(&out).is_empty());
}

#[test]
fn points_far_outside_the_frame_are_not_an_error_but_not_tracked() {
    let (scratch, a, b, out) = pair_scratch("far-points");
    fs::write(
        scratch.path("p.csv"),
        "x,y\n1e30,10\n-3e38,-3e38\n40000,40000\n64,48\n",
    )
    .unwrap();
    for reference in [false, true] {
        let mut args = (PAIR_COMMANDS[0].args)(&a, &b, &out);
        if reference {
            args.push("--reference".into());
        }
        assert_success(&run(&args), "far points");
        let csv = fs::read_to_string(out.join("o.csv")).unwrap();
        let ok: Vec<&str> = csv
            .lines()
            .skip(1)
            .map(|line| line.split(',').nth(4).unwrap())
            .collect();
        assert_eq!(ok, ["0", "0", "0", "1"], "reference {reference}: {csv}");
    }
}

/// Malformed gyro logs, with the words the error must contain.
const BAD_GYRO: &[(&str, &str, &[&str])] = &[
    (
        "bad number",
        "t_us,gx,gy,gz\n0,0,0,0\n1000,0,zero,0\n",
        &["line 3", "column 3 (gy)", "\"zero\" is not a number"],
    ),
    (
        "missing column",
        "t_us,gx,gy\n0,0,0\n",
        &["line 1", "header starting with \"t_us,gx,gy,gz\""],
    ),
    (
        "short record",
        "t_us,gx,gy,gz\n0,0,0,0\n1000,0,0\n",
        &["line 3", "expected 4 fields"],
    ),
    (
        "NaN time",
        "t_us,gx,gy,gz\nNaN,0,0,0\n",
        &["line 2", "column 1 (t_us)", "not a finite number"],
    ),
    (
        "infinite time",
        "t_us,gx,gy,gz\n0,0,0,0\ninf,0,0,0\n",
        &["line 3", "column 1 (t_us)", "not a finite number"],
    ),
    (
        "time going back",
        "t_us,gx,gy,gz\n0,0,0,0\n1000,0,0,0\n500,0,0,0\n",
        &["line 4", "times must increase"],
    ),
    ("empty file", "", &["empty file"]),
    ("header only", "t_us,gx,gy,gz\n", &["no gyro samples"]),
];

#[test]
fn malformed_gyro_logs_are_named_to_the_cell_and_egomotion_writes_nothing() {
    let scratch = Scratch::new("gyro");
    let frames = scratch.path("frames");
    write_frames(&frames, FRAMES);
    let gyro = scratch.path("gyro.csv");
    let out = scratch.path("out");
    fresh_dir(&out);
    let mut args = (SEQUENCE_COMMANDS[2].args)(&frames, &out);
    args.extend(["--gyro".into(), gyro.clone().into_os_string()]);
    for (what, text, says) in BAD_GYRO {
        fs::write(&gyro, text).unwrap();
        let output = run(&args);
        assert_error(&output, what, "gyro.csv", says);
        assert!(file_names(&snapshot(&out)).is_empty(), "{what}");
    }
    // Rates are passed on as they are: a NaN rate spoils the frames it falls in, not the run.
    fs::write(&gyro, "t_us,gx,gy,gz\n0,0,NaN,0\n1000000,0,0,0\n").unwrap();
    assert_success(&run(&args), "NaN rate");
}
