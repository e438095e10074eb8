//! `host-sim synth-sequence`'s mover flags: walkers, blobs, stops and starts, shadows, each off
//! by default (the frames and files of runs without them are those recorded before the flags),
//! and objects.csv's box around the whole of each object.

mod common;

use std::fs;
use std::path::Path;

use common::{
    assert_one_line_error, host_sim, synth, synth_frame as frame, synth_run_hash as run_hash,
    Scratch,
};
use host_sim::Frame;

/// objects.csv's rows: (frame, id, x, y, w, h, dx, dy).
fn objects(dir: &Path) -> Vec<(usize, usize, [f64; 6])> {
    let text = fs::read_to_string(dir.join("objects.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let v: Vec<f64> = f[2..].iter().map(|s| s.parse().unwrap()).collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                v.try_into().unwrap(),
            )
        })
        .collect()
}

/// Runs without any mover flag and the hashes of their outputs, recorded with the host-sim of
/// commit 5d41653, before the flags (small objects; objects filmed by a real camera).
const UNCHANGED_RUNS: [(&[&str], u64); 2] = [
    (
        &[
            "--width",
            "160",
            "--height",
            "120",
            "--path",
            "pan",
            "--frames",
            "6",
            "--objects",
            "3",
            "--object-size",
            "10-12",
            "--noise",
            "1.5",
            "--seed",
            "4",
        ],
        0x885e_184d_b604_7bfa,
    ),
    (
        &[
            "--width",
            "96",
            "--height",
            "72",
            "--path",
            "yaw",
            "--frames",
            "5",
            "--objects",
            "2",
            "--exposure",
            "20",
            "--rolling-shutter",
            "10",
            "--jpeg",
            "70",
            "--noise",
            "1",
            "--seed",
            "2",
        ],
        0x027b_b466_027a_98e9,
    ),
];

#[test]
fn without_mover_flags_the_outputs_are_byte_for_byte_unchanged() {
    let scratch = Scratch::new("movers-unchanged");
    common::assert_synth_hashes(&scratch, &UNCHANGED_RUNS);
    // The block is the default kind.
    let mut block = UNCHANGED_RUNS[0].0.to_vec();
    block.extend(["--object-kind", "block"]);
    assert_eq!(
        run_hash(&synth(&scratch, "block", &block)),
        UNCHANGED_RUNS[0].1
    );
}

/// A still camera at 160 x 120 without noise, `frames` frames, 3 objects of `size` px, and
/// `more`.
fn still<'a>(frames: &'a str, size: &'a str, more: &[&'a str]) -> Vec<&'a str> {
    let base = [
        "--path",
        "still",
        "--width",
        "160",
        "--height",
        "120",
        "--noise",
        "0",
        "--seed",
        "3",
        "--frames",
        frames,
        "--objects",
        "3",
        "--object-size",
        size,
    ];
    base.iter().chain(more).copied().collect()
}

/// The pixels of `a` and `b` that differ by more than 2 grey levels.
fn changed(a: &Frame, b: &Frame) -> Vec<(usize, usize)> {
    let mut pixels = Vec::new();
    for y in 0..a.height {
        for x in 0..a.width {
            if (i32::from(a.at(x, y)) - i32::from(b.at(x, y))).abs() > 2 {
                pixels.push((x, y));
            }
        }
    }
    pixels
}

/// True when pixel (`x`, `y`) lies in box `b` (x, y, w, h in pixel edges) grown by `margin`.
fn inside(b: &[f64; 6], x: usize, y: usize, margin: f64) -> bool {
    let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
    cx >= b[0] - margin
        && cx <= b[0] + b[2] + margin
        && cy >= b[1] - margin
        && cy <= b[1] + b[3] + margin
}

/// Checks that every pixel the objects change lies in a box of its frame (within a pixel, the
/// area sampling of an edge) and that every box's sides are touched by changed pixels (within
/// 1.5 px); returns each object's smallest and largest box width.
fn boxes_enclose_the_objects(with: &Path, without: &Path, frames: usize) -> Vec<(f64, f64)> {
    let rows = objects(with);
    let mut widths = vec![(f64::INFINITY, 0.0f64); 3];
    for k in 1..frames {
        let boxes: Vec<[f64; 6]> = rows.iter().filter(|r| r.0 == k).map(|r| r.2).collect();
        let pixels = changed(&frame(with, k), &frame(without, k));
        for &(x, y) in &pixels {
            assert!(
                boxes.iter().any(|b| inside(b, x, y, 1.0)),
                "frame {k}: pixel ({x}, {y}) outside every box {boxes:?}"
            );
        }
        for (id, b) in boxes.iter().enumerate() {
            let mine: Vec<&(usize, usize)> = pixels
                .iter()
                .filter(|&&(x, y)| inside(b, x, y, 0.0))
                .collect();
            let reach = |f: &dyn Fn(&(usize, usize)) -> f64| {
                mine.iter().map(|p| f(p)).fold(f64::NAN, f64::min)
            };
            let gaps = [
                reach(&|p| p.0 as f64 + 0.5 - b[0]),
                reach(&|p| b[0] + b[2] - (p.0 as f64 + 0.5)),
                reach(&|p| p.1 as f64 + 0.5 - b[1]),
                reach(&|p| b[1] + b[3] - (p.1 as f64 + 0.5)),
            ];
            // An object partly out of the frame, or hidden by another, leaves its sides alone.
            let shows = b[0] > 1.0 && b[1] > 1.0 && b[0] + b[2] < 159.0 && b[1] + b[3] < 119.0;
            let alone = boxes.iter().enumerate().all(|(j, o)| {
                j == id
                    || o[0] > b[0] + b[2] + 2.0
                    || b[0] > o[0] + o[2] + 2.0
                    || o[1] > b[1] + b[3] + 2.0
                    || b[1] > o[1] + o[3] + 2.0
            });
            if shows && alone {
                assert!(
                    gaps.iter().all(|&g| g <= 1.5),
                    "frame {k} object {id}: {gaps:?} {b:?}"
                );
            }
            widths[id] = (widths[id].0.min(b[2]), widths[id].1.max(b[2]));
        }
    }
    widths
}

#[test]
fn a_walkers_box_encloses_its_swinging_limbs_and_a_blobs_its_stretch() {
    let scratch = Scratch::new("movers-boxes");
    let frames = 24;
    let ground = synth(&scratch, "ground", &{
        let mut args = still("24", "40", &[]);
        args[13] = "0";
        args
    });
    let walkers = synth(
        &scratch,
        "walkers",
        &still("24", "36-44", &["--object-kind", "walker"]),
    );
    for (id, (narrow, wide)) in boxes_enclose_the_objects(&walkers, &ground, frames)
        .into_iter()
        .enumerate()
    {
        // Standing a walker is 0.4 times as tall as it is wide; its stride widens its box.
        assert!(
            wide > 1.3 * narrow,
            "walker {id}: {narrow} to {wide} px wide"
        );
    }
    let heights: Vec<f64> = objects(&walkers).iter().map(|r| r.2[3]).collect();
    assert!(
        heights.iter().all(|h| (33.0..=44.5).contains(h)),
        "{heights:?}"
    );
    let blobs = synth(
        &scratch,
        "blobs",
        &still("24", "30", &["--object-kind", "blob"]),
    );
    for (id, (narrow, wide)) in boxes_enclose_the_objects(&blobs, &ground, frames)
        .into_iter()
        .enumerate()
    {
        assert!(wide > 1.3 * narrow, "blob {id}: {narrow} to {wide} px wide");
    }
}

#[test]
fn movers_stop_and_start_and_their_shadows_stay_off_their_boxes() {
    let scratch = Scratch::new("movers-stop-go");
    let walkers = ["--object-kind", "walker"];
    let plain = synth(&scratch, "plain", &still("60", "12-16", &walkers));
    let stopping = synth(
        &scratch,
        "stopping",
        &still("60", "12-16", &[&walkers[..], &["--stop-go"]].concat()),
    );
    let rows = objects(&stopping);
    for id in 0..3 {
        let moves: Vec<bool> = rows
            .iter()
            .filter(|r| r.1 == id)
            .map(|r| r.2[4] != 0.0 || r.2[5] != 0.0)
            .collect();
        let stands = moves.iter().filter(|&&m| !m).count();
        assert!(
            (5..=50).contains(&stands),
            "object {id} stands in {stands} of 59 frames"
        );
        // Each stop lasts at least 7 pairs, each run at least 11.
        let mut runs = vec![1];
        for pair in moves.windows(2) {
            match pair[0] == pair[1] {
                true => *runs.last_mut().unwrap() += 1,
                false => runs.push(1),
            }
        }
        assert!(runs.len() >= 2, "object {id}: {runs:?}");
        let inner = &runs[1..runs.len() - 1];
        assert!(inner.iter().all(|&n| n >= 7), "object {id}: {runs:?}");
    }
    // Standing, a walker's frame does not change at all (away from the others).
    let apart = |k: usize, b: &[f64; 6]| {
        rows.iter()
            .filter(|r| (r.0 == k || r.0 + 1 == k) && r.2 != *b)
            .all(|r| {
                let o = r.2;
                o[0] > b[0] + b[2] + 2.0
                    || b[0] > o[0] + o[2] + 2.0
                    || o[1] > b[1] + b[3] + 2.0
                    || b[1] > o[1] + o[3] + 2.0
            })
    };
    let standing = rows
        .iter()
        .find(|r| r.0 >= 2 && r.2[4] == 0.0 && r.2[5] == 0.0 && apart(r.0, &r.2))
        .unwrap();
    let (k, b) = (standing.0, standing.2);
    let (x0, y0) = (b[0].max(0.0) as usize, b[1].max(0.0) as usize);
    let (x1, y1) = (
        ((b[0] + b[2]) as usize).min(159),
        ((b[1] + b[3]) as usize).min(119),
    );
    let (a, c) = (frame(&stopping, k - 1), frame(&stopping, k));
    let moved = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .filter(|&(x, y)| a.at(x, y) != c.at(x, y))
        .count();
    assert_eq!(
        moved, 0,
        "frame {k}: a standing walker changed {moved} pixels"
    );
    // Shadows darken the ground outside the boxes and leave objects.csv alone.
    let shaded = synth(
        &scratch,
        "shaded",
        &still("60", "12-16", &[&walkers[..], &["--shadows"]].concat()),
    );
    assert_eq!(
        fs::read(plain.join("objects.csv")).unwrap(),
        fs::read(shaded.join("objects.csv")).unwrap()
    );
    let rows = objects(&plain);
    let (mut darker, mut outside) = (0, 0);
    for k in [5, 20, 40] {
        let (lit, dark) = (frame(&plain, k), frame(&shaded, k));
        let boxes: Vec<[f64; 6]> = rows.iter().filter(|r| r.0 == k).map(|r| r.2).collect();
        for (x, y) in changed(&lit, &dark) {
            assert!(
                dark.at(x, y) < lit.at(x, y),
                "frame {k} ({x}, {y}) brighter"
            );
            darker += 1;
            outside += usize::from(!boxes.iter().any(|b| inside(b, x, y, 0.0)));
        }
    }
    // Shifted by a third of a height or more, most of a shadow falls outside its box.
    assert!(darker > 3 * 3 * 15, "{darker} shaded pixels");
    assert!(
        outside * 2 > darker,
        "{outside} of {darker} shaded pixels outside the boxes"
    );
}

#[test]
fn a_still_camera_does_not_move_and_mover_flags_need_objects() {
    let scratch = Scratch::new("movers-still");
    let args = [
        "--path", "still", "--width", "64", "--height", "48", "--frames", "3", "--noise", "0",
    ];
    let dir = synth(&scratch, "still", &args);
    let truth = fs::read_to_string(dir.join("truth.csv")).unwrap();
    assert!(
        truth
            .lines()
            .nth(1)
            .unwrap()
            .starts_with("1,1e0,0e0,0e0,0e0,1e0,0e0,0e0,0e0,1e0"),
        "{truth}"
    );
    assert_eq!(frame(&dir, 0), frame(&dir, 2));
    let out = scratch.path("lonely");
    let output = host_sim(&[&"synth-sequence", &"--out", &out, &"--shadows"]);
    assert_one_line_error(&output, 2, "--objects");
    let output = host_sim(&[
        &"synth-sequence",
        &"--out",
        &out,
        &"--objects",
        &"1",
        &"--object-kind",
        &"car",
    ]);
    assert_one_line_error(&output, 2, "--object-kind");
}
