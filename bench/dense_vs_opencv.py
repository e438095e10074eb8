#!/usr/bin/env python3
"""Dense grid flow and moving-object boxes: Kestrel beside OpenCV on the same frames.

Speed: host time per frame at 160x120 and 320x240 with 8 px cells. Kestrel: `host-sim dense
--repeat N --stats` (both pyramids and the whole grid, from decoded frames) and `host-sim
motion --stats` (one pyramid, the grid, the camera fit, mask and boxes per frame of a
sequence). OpenCV, one thread: calcOpticalFlowPyrLK on the same grid nodes with the same
window and levels, and Farneback's dense flow over the whole frame.

Grid accuracy: seeded pairs from `host-sim synth` (shift up to 8 px in any direction, rotation
within 1 degree, zoom within 2%, sensor noise 1.5 grey levels). Endpoint error at the grid nodes
against the exact warp: Kestrel at its valid nodes; OpenCV PyrLK at its tracked nodes; Farneback
(sampled at the nodes) at every node and at Kestrel's valid nodes.

Boxes: the seeded sequences of tests/dense_motion.rs (written by the motion_sequence example):
a still camera over objects of 10 to 40 px (one standing still), and a camera panning, rolling
0.4 degrees and zooming 0.6% per frame over eight targets of 10 to 25 px. A box finds an
object at IoU >= 0.3 (one to one, best overlaps first); objects less than half in view are not
asked for and a box on one is not counted. Kestrel's `host-sim motion` with its defaults beside
the classic recipe: camera motion from goodFeaturesToTrack + PyrLK + findHomography (RANSAC),
the previous frame warped onto the next, then either the absolute frame difference or
Farneback's flow magnitude, thresholded, opened (3x3) and closed, contours, bounding boxes with
an area floor of 30 px. The classic recipe is shown with typical settings (timed), and with the
best threshold and closing of a small sweep by F1 score (chosen on these very frames, which
flatters it).

Needs: python3 with numpy and opencv-python-headless.
Usage: bench/dense_vs_opencv.py [--pairs N] [--seeds N] [--repeat N] [--no-build]
"""

import argparse
import csv
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

from boxes import iou

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
SEQUENCE = os.path.join(ROOT, "target", "release", "examples", "motion_sequence")
CELL, WINDOW, LEVELS = 8, 9, 3
MIN_IOU = 0.3
FARNEBACK = dict(pyr_scale=0.5, levels=3, winsize=15, iterations=3, poly_n=5, poly_sigma=1.2,
                 flags=0)


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def grey(path):
    return cv2.imread(path, cv2.IMREAD_GRAYSCALE)


def nodes(width, height):
    xs = np.arange(CELL // 2, width, CELL)
    ys = np.arange(CELL // 2, height, CELL)
    return np.array([(x, y) for y in ys for x in xs], dtype=np.float32)


def opencv_lk(a, b, points):
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(
        a, b, points.reshape(-1, 1, 2), None, winSize=(WINDOW, WINDOW), maxLevel=LEVELS,
        criteria=criteria)
    return moved.reshape(-1, 2) - points, status.ravel() == 1


def farneback(a, b):
    return cv2.calcOpticalFlowFarneback(a, b, None, **FARNEBACK)


def median_seconds(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


# ---------------------------------------------------------------- grid flow: speed, accuracy

def synth_pairs(out, width, height, pairs, seed):
    run(HOST_SIM, "synth", "--out", out, "--pairs", str(pairs), "--seed", str(seed),
        "--width", str(width), "--height", str(height), "--max-shift", "8")
    return read_csv(os.path.join(out, "manifest.csv"))


def true_flow(pair, points, width, height):
    """The synth warp: p' = s R (p - c) + c + shift, c the frame centre."""
    s, angle = float(pair["scale"]), np.radians(float(pair["angle_deg"]))
    c = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    rot = s * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = (points - c) @ rot.T + c + np.array([float(pair["dx"]), float(pair["dy"])])
    return moved - points


def kestrel_dense(directory, pair, scratch, repeat=1):
    out, stats = os.path.join(scratch, "grid.csv"), os.path.join(scratch, "stats.json")
    run(HOST_SIM, "dense", "--prev", os.path.join(directory, pair["a"]),
        "--next", os.path.join(directory, pair["b"]), "--out", out, "--cell", str(CELL),
        "--window", str(WINDOW), "--levels", str(LEVELS), "--repeat", str(repeat),
        "--stats", stats)
    rows = read_csv(out)
    flow = np.array([[float(r["dx"]), float(r["dy"])] for r in rows])
    ok = np.array([r["ok"] == "1" for r in rows])
    with open(stats) as f:
        seconds = json.load(f)["median_core_seconds"]
    return flow, ok, seconds


def grid_benchmark(work, width, height, pairs, repeat):
    directory = os.path.join(work, f"pairs{width}")
    manifest = synth_pairs(directory, width, height, pairs, seed=7)
    points = nodes(width, height)
    xi, yi = points[:, 0].astype(int), points[:, 1].astype(int)
    errors = {"kestrel": [], "lk": [], "fb_all": [], "fb_kestrel": []}
    counts = {"kestrel": 0, "lk": 0, "nodes": 0}
    with tempfile.TemporaryDirectory() as scratch:
        for pair in manifest:
            a = grey(os.path.join(directory, pair["a"]))
            b = grey(os.path.join(directory, pair["b"]))
            truth = true_flow(pair, points, width, height)
            flow, ok, _ = kestrel_dense(directory, pair, scratch)
            lk_flow, lk_ok = opencv_lk(a, b, points)
            fb = farneback(a, b)[yi, xi]
            epe = lambda f: np.linalg.norm(f - truth, axis=1)
            errors["kestrel"].extend(epe(flow)[ok])
            errors["lk"].extend(epe(lk_flow)[lk_ok])
            errors["fb_all"].extend(epe(fb))
            errors["fb_kestrel"].extend(epe(fb)[ok])
            counts["kestrel"] += int(ok.sum())
            counts["lk"] += int(lk_ok.sum())
            counts["nodes"] += len(points)
        # Speed on the first pair.
        pair = manifest[0]
        _, _, kestrel_s = kestrel_dense(directory, pair, scratch, repeat)
    a = grey(os.path.join(directory, pair["a"]))
    b = grey(os.path.join(directory, pair["b"]))
    cv2.setNumThreads(1)
    lk_s = median_seconds(lambda: opencv_lk(a, b, points), repeat)
    fb_s = median_seconds(lambda: farneback(a, b), repeat)
    return errors, counts, {"kestrel": kestrel_s, "lk": lk_s, "fb": fb_s}


# ---------------------------------------------------------------- boxes

def write_sequence(work, kind, seed):
    out = os.path.join(work, f"{kind}{seed}")
    run(SEQUENCE, out, kind, *(["160", "120"] if kind == "still" else ["320", "240"]), "30",
        str(seed))
    truth = {}
    for r in read_csv(os.path.join(out, "truth.csv")):
        box = tuple(float(r[k]) for k in ("x", "y", "w", "h"))
        truth.setdefault(int(r["frame"]), []).append((box, r["moves"] == "1"))
    frames = sorted(os.listdir(os.path.join(out, "frames")))
    return out, [os.path.join(out, "frames", f) for f in frames], truth


def clip(box, width, height):
    x0, y0 = min(max(box[0], 0), width), min(max(box[1], 0), height)
    x1, y1 = min(max(box[0] + box[2], x0), width), min(max(box[1] + box[3], y0), height)
    return (x0, y0, x1 - x0, y1 - y0)


def score(truth, boxes, width, height):
    """(asked, found, boxes, false boxes) of one frame, as in tests/dense_motion.rs."""
    objects = []
    for box, moves in truth:
        if moves:
            inside = clip(box, width, height)
            objects.append((inside, inside[2] * inside[3] >= 0.5 * box[2] * box[3]))
    pairs = sorted(((iou(o, b), t, d) for t, (o, _) in enumerate(objects)
                    for d, b in enumerate(boxes) if iou(o, b) >= MIN_IOU), reverse=True)
    hit_t, hit_d = set(), set()
    for _, t, d in pairs:
        if t not in hit_t and d not in hit_d:
            hit_t.add(t)
            hit_d.add(d)
    asked = [t for t, (_, a) in enumerate(objects) if a]
    return len(asked), sum(t in hit_t for t in asked), len(boxes), len(boxes) - len(hit_d)


class Tally:
    def __init__(self):
        self.asked = self.found = self.boxes = self.false = 0
        self.seconds = []

    def add(self, s):
        self.asked += s[0]
        self.found += s[1]
        self.boxes += s[2]
        self.false += s[3]

    def recall(self):
        return self.found / self.asked if self.asked else float("nan")

    def precision(self):
        return (self.boxes - self.false) / self.boxes if self.boxes else float("nan")


def kestrel_motion(out, frames, truth, tally):
    boxes_csv, stats = os.path.join(out, "boxes.csv"), os.path.join(out, "stats.json")
    run(HOST_SIM, "motion", os.path.join(out, "frames"), "--out", boxes_csv, "--stats", stats)
    found = {}
    for r in read_csv(boxes_csv):
        found.setdefault(int(r["frame"]), []).append(tuple(float(r[k]) for k in "xywh"))
    height, width = grey(frames[0]).shape
    for k in range(1, len(frames)):
        tally.add(score(truth[k], found.get(k, []), width, height))
    with open(stats) as f:
        tally.seconds.append(json.load(f)["median_frame_seconds"])


def camera_homography(prev, nxt):
    corners = cv2.goodFeaturesToTrack(prev, maxCorners=300, qualityLevel=0.01, minDistance=7)
    if corners is None or len(corners) < 4:
        return np.eye(3)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(prev, nxt, corners, None, winSize=(21, 21),
                                                maxLevel=3)
    ok = status.ravel() == 1
    if ok.sum() < 4:
        return np.eye(3)
    h, _ = cv2.findHomography(corners[ok], moved[ok], cv2.RANSAC, 3.0)
    return np.eye(3) if h is None else h


def evidence(prev, nxt, mode):
    """The per-pixel motion evidence of the classic recipe for one pair, in the next frame:
    the absolute difference from the camera-compensated previous frame, or the magnitude of
    Farneback's flow between them; and where the warped frame is valid."""
    height, width = nxt.shape
    h = camera_homography(prev, nxt)
    warped = cv2.warpPerspective(prev, h, (width, height))
    valid = cv2.warpPerspective(np.full_like(prev, 255), h, (width, height))
    valid = cv2.erode(valid, np.ones((7, 7), np.uint8)) > 0
    if mode == "difference":
        return cv2.absdiff(nxt, warped).astype(np.float32), valid
    return np.linalg.norm(farneback(warped, nxt), axis=2), valid


def classic_boxes(evidence_map, valid, threshold, close, min_area=30):
    """Threshold, open 3x3, close `close` x `close`, contours, boxes with an area floor."""
    mask = ((evidence_map > threshold) & valid).astype(np.uint8) * 255
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((close, close), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return [tuple(float(v) for v in cv2.boundingRect(c)) for c in contours
            if cv2.contourArea(c) >= min_area]


TYPICAL = {"difference": (25, 5), "farneback": (1.0, 5)}
SWEEP = {"difference": [5, 8, 10, 15, 20, 25, 35], "farneback": [0.5, 0.75, 1.0, 1.5, 2.0, 3.0]}
CLOSINGS = [5, 9, 15]


def classic_rows(sequences, mode, label):
    """The typical settings, timed over the whole recipe, and the best of the sweep."""
    pairs = []  # (evidence, valid, truth, size) per frame pair of every sequence
    typical = Tally()
    for _, frames, truth in sequences:
        images = [grey(f) for f in frames]
        height, width = images[0].shape
        for k in range(1, len(images)):
            t0 = time.perf_counter()
            found, valid = evidence(images[k - 1], images[k], mode)
            boxes = classic_boxes(found, valid, *TYPICAL[mode])
            typical.seconds.append(time.perf_counter() - t0)
            typical.add(score(truth[k], boxes, width, height))
            pairs.append((found, valid, truth[k], (width, height)))
    best = None
    for threshold in SWEEP[mode]:
        for close in CLOSINGS:
            t = Tally()
            for found, valid, truth, (width, height) in pairs:
                t.add(score(truth, classic_boxes(found, valid, threshold, close), width, height))
            f1 = 2 * t.found / (t.asked + t.boxes) if t.asked + t.boxes else 0.0
            if best is None or f1 > best[0]:
                best = (f1, threshold, close, t)
    threshold, close = TYPICAL[mode]
    return [(f"OpenCV {label}, threshold {threshold}, closing {close}x{close}", typical),
            (f"OpenCV {label}, best of the sweep: threshold {best[1]}, closing "
             f"{best[2]}x{best[2]} (chosen on these frames)", best[3])]


def box_benchmark(work, kind, seeds):
    sequences = [write_sequence(work, kind, seed) for seed in range(1, seeds + 1)]
    cv2.setNumThreads(1)
    kestrel = Tally()
    for out, frames, truth in sequences:
        kestrel_motion(out, frames, truth, kestrel)
    rows = [("Kestrel `host-sim motion` (defaults)", kestrel)]
    rows += classic_rows(sequences, "difference", "warp + frame difference")
    rows += classic_rows(sequences, "farneback", "warp + Farneback magnitude")
    return rows


# ---------------------------------------------------------------- report

def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=30)
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim", "--bin", "host-sim",
            "--example", "motion_sequence")

    print(f"# Dense grid flow and motion boxes, {datetime.date.today()}: bench/dense_vs_opencv.py "
          f"--pairs {options.pairs} --seeds {options.seeds} --repeat {options.repeat}")
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}; "
          f"grid of {CELL} px cells, LK window {WINDOW}, max level {LEVELS}")
    with tempfile.TemporaryDirectory() as work:
        grids = {size: grid_benchmark(work, *size, options.pairs, options.repeat)
                 for size in ((160, 120), (320, 240))}
        motion_seconds = {}
        box_rows = {}
        for kind in ("still", "moving"):
            box_rows[kind] = box_benchmark(work, kind, options.seeds)
            motion_seconds[kind] = float(np.median(box_rows[kind][0][1].seconds))

        print("\n## Host time per frame, one thread")
        print("| frame | nodes | Kestrel grid (2 pyramids + grid) | Kestrel motion pipeline "
              "per frame | OpenCV PyrLK at the nodes | OpenCV Farneback (whole frame) |")
        print("|---|---|---|---|---|---|")
        for (w, h), (_, counts, speed) in grids.items():
            n = counts["nodes"] // options.pairs
            kind = "still" if w == 160 else "moving"
            print(f"| {w}x{h} | {n} | {1e3 * speed['kestrel']:.2f} ms | "
                  f"{1e3 * motion_seconds[kind]:.2f} ms ({kind} sequence) | "
                  f"{1e3 * speed['lk']:.2f} ms | {1e3 * speed['fb']:.2f} ms |")

        print(f"\n## Grid endpoint error, {options.pairs} pairs per size (shift <= 8 px, "
              "rotation <= 1 deg, zoom <= 2%, noise 1.5)")
        print("| frame | flow | nodes scored | median px | 95th pct px | > 1 px |")
        print("|---|---|---|---|---|---|")
        for (w, h), (errors, counts, _) in grids.items():
            for key, label, scored in (
                    ("kestrel", "Kestrel grid, valid nodes", counts["kestrel"]),
                    ("lk", "OpenCV PyrLK, tracked nodes", counts["lk"]),
                    ("fb_kestrel", "Farneback at Kestrel's valid nodes", counts["kestrel"]),
                    ("fb_all", "Farneback at every node", counts["nodes"])):
                e = np.array(errors[key])
                print(f"| {w}x{h} | {label} | {scored} of {counts['nodes']} | "
                      f"{np.median(e):.4f} | {np.percentile(e, 95):.4f} | "
                      f"{100 * (e > 1).mean():.2f}% |")

        for kind, title in (("still", "still camera, 160x120, objects 10-40 px (one still)"),
                            ("moving", "moving camera (pan, roll, zoom), 320x240, targets "
                                       "10-25 px")):
            rows = box_rows[kind]
            k = rows[0][1]
            print(f"\n## Boxes, {title}: {options.seeds} seeds x 29 frame pairs, "
                  f"{k.asked} objects asked for")
            print("| method | recall | precision | boxes | false boxes | time per frame |")
            print("|---|---|---|---|---|---|")
            for label, t in rows:
                seconds = f"{1e3 * float(np.median(t.seconds)):.2f} ms" if t.seconds else "-"
                print(f"| {label} | {t.recall():.3f} | {t.precision():.3f} | {t.boxes} | "
                      f"{t.false} | {seconds} |")


if __name__ == "__main__":
    main()
