#!/usr/bin/env python3
"""Moving-object boxes of `host-sim motion` scored against the truth of `host-sim synth-sequence`.

Flights: `synth-sequence --path pan|yaw|climb --objects 3 --noise 1.5`, 30 frames, seeds 1 to 4,
at 160x120 with objects of 10 to 12 px a side (`--object-size 10-12`) and at 320x240 with 20 to
24 px (`--object-size 20-24`). The objects glide on their own paths across the image while the
camera pans, yaws or climbs. Each flight's frames go to `host-sim motion` with its defaults.

Scoring, as in tests/dense_motion.rs: a box of frame k finds an object of frame k (objects.csv)
when their intersection over union is at least 0.3; each object and each box is matched at most
once, best overlaps first. An object less than half visible (outside the frame or behind a later
object, which is drawn in front) is not asked for, and a box matched to it is neither a hit nor
a false box. Recall = objects found / objects asked; precision = boxes that found an object /
boxes. Also the objects asked for whose own motion was under 0.5 px in that frame (dx, dy of
objects.csv), which no motion threshold can see, and the recall of the objects asked for that
are at least 24 px (three cells of the default 8 px grid) from every other object: the objects
glide on their own paths and often pass close by each other, where one region covers both.

Needs: python3 with numpy.
Usage: bench/motion_vs_truth.py [--seeds N] [--frames N] [--no-build] [motion flags ...]
(arguments after the known ones go to `host-sim motion`, e.g. --threshold 1.0).
"""

import argparse
import csv
import datetime
import os
import subprocess
import tempfile

import numpy as np

from boxes import iou

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
SIZES = (((160, 120), "10-12"), ((320, 240), "20-24"))
PATHS = ("pan", "yaw", "climb")
OBJECTS = 3
NOISE = 1.5
MIN_IOU = 0.3
SLOW_PX = 0.5
APART_PX = 24.0


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def visible_shares(objects, width, height):
    """The share of each object's box that shows: inside the frame and not behind a later one."""
    shares = []
    for i, (x, y, w, h) in enumerate(objects):
        # Pixel centres c + 0.5 inside the box (edges x .. x + w).
        xs = np.arange(int(np.floor(x)), int(np.ceil(x + w))) + 0.5
        ys = np.arange(int(np.floor(y)), int(np.ceil(y + h))) + 0.5
        xs, ys = xs[(xs >= x) & (xs < x + w)], ys[(ys >= y) & (ys < y + h)]
        gx, gy = np.meshgrid(xs, ys)
        total = gx.size
        shows = (gx >= 0) & (gx < width) & (gy >= 0) & (gy < height)
        for (fx, fy, fw, fh) in objects[i + 1:]:
            shows &= ~((gx >= fx) & (gx < fx + fw) & (gy >= fy) & (gy < fy + fh))
        shares.append(shows.sum() / total if total else 0.0)
    return shares


def gap(a, b):
    """The distance between two boxes along the axis they are furthest apart on (< 0 overlap)."""
    return max(b[0] - (a[0] + a[2]), a[0] - (b[0] + b[2]), b[1] - (a[1] + a[3]),
               a[1] - (b[1] + b[3]))


def totals():
    return dict(asked=0, found=0, slow=0, slow_found=0, apart=0, apart_found=0, boxes=0, false=0)


def score(boxes_by_frame, objects_by_frame, width, height):
    """Totals over frames: objects asked for and found (all, slow, apart), boxes, false boxes."""
    t = totals()
    for k, objects in objects_by_frame.items():
        truth = [o[0] for o in objects]
        asked = [s >= 0.5 for s in visible_shares(truth, width, height)]
        slow = [np.hypot(o[1][0], o[1][1]) < SLOW_PX for o in objects]
        apart = [all(gap(a, b) >= APART_PX for j, b in enumerate(truth) if j != i)
                 for i, a in enumerate(truth)]
        boxes = boxes_by_frame.get(k, [])
        pairs = sorted(((iou(b, o), ti, di) for ti, o in enumerate(truth)
                        for di, b in enumerate(boxes) if iou(b, o) >= MIN_IOU), reverse=True)
        truth_hit, box_of = [False] * len(truth), [None] * len(boxes)
        for _, ti, di in pairs:
            if not truth_hit[ti] and box_of[di] is None:
                truth_hit[ti], box_of[di] = True, ti
        for ti in range(len(truth)):
            if asked[ti]:
                t["asked"] += 1
                t["found"] += truth_hit[ti]
                t["slow"] += slow[ti]
                t["slow_found"] += slow[ti] and truth_hit[ti]
                t["apart"] += apart[ti]
                t["apart_found"] += apart[ti] and truth_hit[ti]
        for ti in box_of:
            # A box on an object not asked for is neither a hit nor false.
            if ti is None or asked[ti]:
                t["boxes"] += 1
                t["false"] += ti is None
    return t


def flight(directory, path, size, sides, seed, frames, motion_flags):
    (width, height) = size
    run(HOST_SIM, "synth-sequence", "--out", directory, "--path", path, "--frames", str(frames),
        "--width", str(width), "--height", str(height), "--seed", str(seed),
        "--objects", str(OBJECTS), "--object-size", sides, "--noise", str(NOISE))
    boxes_csv = os.path.join(directory, "boxes.csv")
    run(HOST_SIM, "motion", os.path.join(directory, "frames"), "--out", boxes_csv, *motion_flags)
    boxes = {}
    for r in read_rows(boxes_csv):
        boxes.setdefault(int(r["frame"]), []).append(
            tuple(float(r[c]) for c in ("x", "y", "w", "h")))
    objects = {}
    for r in read_rows(os.path.join(directory, "objects.csv")):
        objects.setdefault(int(r["frame"]), []).append(
            (tuple(float(r[c]) for c in ("x", "y", "w", "h")), (float(r["dx"]), float(r["dy"]))))
    return score(boxes, objects, width, height)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--no-build", action="store_true")
    args, motion_flags = parser.parse_known_args()
    if not args.no_build:
        run("cargo", "build", "--release", "-p", "host-sim")
    print(f"bench/motion_vs_truth.py, {datetime.date.today()}: {OBJECTS} objects, noise {NOISE}, "
          f"{args.frames} frames, seeds 1-{args.seeds}, IoU >= {MIN_IOU}"
          + (f", motion {' '.join(motion_flags)}" if motion_flags else ""))
    print()
    print("| size | objects | path | recall | precision | boxes | false | "
          f"asked | under {SLOW_PX} px (found) | recall without them | "
          f"{APART_PX:.0f} px apart | their recall |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for size, sides in SIZES:
            every = totals()
            for path in PATHS:
                t = totals()
                for seed in range(1, args.seeds + 1):
                    directory = os.path.join(scratch, f"{path}-{size[0]}-{seed}")
                    for key, value in flight(directory, path, size, sides, seed, args.frames,
                                             motion_flags).items():
                        t[key] += value
                for key in t:
                    every[key] += t[key]
                row(size, sides, path, t)
            row(size, sides, "all", every)


def row(size, sides, path, t):
    recall = t["found"] / t["asked"] if t["asked"] else float("nan")
    precision = (t["boxes"] - t["false"]) / t["boxes"] if t["boxes"] else float("nan")
    fast = t["asked"] - t["slow"]
    fast_recall = (t["found"] - t["slow_found"]) / fast if fast else float("nan")
    apart_recall = t["apart_found"] / t["apart"] if t["apart"] else float("nan")
    print(f"| {size[0]}x{size[1]} | {sides} px | {path} | {recall:.3f} | {precision:.3f} | "
          f"{t['boxes']} | {t['false']} | {t['asked']} | {t['slow']} ({t['slow_found']}) | "
          f"{fast_recall:.3f} | {t['apart']} | {apart_recall:.3f} |", flush=True)


if __name__ == "__main__":
    main()
