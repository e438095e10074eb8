#!/usr/bin/env python3
"""Sparse pyramidal LK: Kestrel (Q16), its f32 reference and OpenCV on the same frames.

Accuracy: seeded synthetic pairs from `host-sim synth` (translations up to 20 px in any
direction, rotation within 1 degree, zoom within 2%, sensor noise 1.5 grey levels), once with
unchanged lighting and once with gain 1.25 and bias +15 on the second frame. All three trackers
get the same frames and points with the same parameters (21x21 window, max level 3, 30
iterations, epsilon 0.01 px, OpenCV's default minimum eigenvalue).

Speed: 300 points (a 20 x 15 grid) on one 320x240 pair, windows 21 and 9, max level 3. Both
sides time the whole core: both pyramids and the tracking, from decoded frames; OpenCV with one
thread (cv2.setNumThreads(1)).

Needs: python3 with numpy and opencv-python-headless (pip install numpy opencv-python-headless).
Usage: bench/lk_vs_opencv.py [--pairs N] [--repeat N] [--no-build]
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
WINDOW, LEVELS, ITERATIONS, EPSILON = 21, 3, 30, 0.01


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def synth(out, seed, pairs, gain=1.0, bias=0.0):
    run(HOST_SIM, "synth", "--out", out, "--pairs", str(pairs), "--seed", str(seed),
        "--gain", str(gain), "--bias", str(bias))
    return read_csv(os.path.join(out, "manifest.csv"))


def kestrel_flow(directory, pair, out, reference=False, window=WINDOW, extra=()):
    args = [HOST_SIM, "flow", "--prev", os.path.join(directory, pair["a"]),
            "--next", os.path.join(directory, pair["b"]),
            "--points", os.path.join(directory, pair["points"]), "--out", out,
            "--window", str(window), "--levels", str(LEVELS)]
    if reference:
        args.append("--reference")
    run(*args, *extra)
    rows = read_csv(out)
    moved = np.array([[float(r["nx"]), float(r["ny"])] for r in rows], dtype=np.float64)
    ok = np.array([r["ok"] == "1" for r in rows])
    return moved.reshape(-1, 2), ok


def opencv_flow(a, b, points, window=WINDOW):
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, ITERATIONS, EPSILON)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(
        a, b, points.reshape(-1, 1, 2).astype(np.float32), None,
        winSize=(window, window), maxLevel=LEVELS, criteria=criteria)
    return moved.reshape(-1, 2).astype(np.float64), status.ravel() == 1


def accuracy(directory, manifest):
    """Endpoint errors of tracked points and tracked shares for the three trackers."""
    results = {"Kestrel Q16": ([], 0, 0), "f32 reference": ([], 0, 0), "OpenCV": ([], 0, 0)}
    with tempfile.TemporaryDirectory() as scratch:
        for pair in manifest:
            truth_rows = read_csv(os.path.join(directory, pair["truth"]))
            if not truth_rows:
                continue
            start = np.array([[float(r["x"]), float(r["y"])] for r in truth_rows])
            truth = np.array([[float(r["tx"]), float(r["ty"])] for r in truth_rows])
            a = cv2.imread(os.path.join(directory, pair["a"]), cv2.IMREAD_GRAYSCALE)
            b = cv2.imread(os.path.join(directory, pair["b"]), cv2.IMREAD_GRAYSCALE)
            out = os.path.join(scratch, "o.csv")
            for name, (moved, ok) in {
                "Kestrel Q16": kestrel_flow(directory, pair, out),
                "f32 reference": kestrel_flow(directory, pair, out, reference=True),
                "OpenCV": opencv_flow(a, b, start),
            }.items():
                errors, tracked, total = results[name]
                error = np.linalg.norm(moved - truth, axis=1)
                errors.extend(error[ok].tolist())
                results[name] = (errors, tracked + int(ok.sum()), total + len(ok))
    table = {}
    for name, (errors, tracked, total) in results.items():
        e = np.array(errors)
        table[name] = {
            "median": float(np.median(e)) if len(e) else float("nan"),
            "p95": float(np.percentile(e, 95)) if len(e) else float("nan"),
            "tracked": tracked / total if total else 0.0,
            "off1": float((e > 1.0).mean()) if len(e) else float("nan"),
            "points": total,
        }
    return table


def speed(directory, pair, repeat):
    a = cv2.imread(os.path.join(directory, pair["a"]), cv2.IMREAD_GRAYSCALE)
    b = cv2.imread(os.path.join(directory, pair["b"]), cv2.IMREAD_GRAYSCALE)
    h, w = a.shape
    xs, ys = np.linspace(12, w - 13, 20), np.linspace(12, h - 13, 15)
    grid = np.array([(x, y) for y in ys for x in xs], dtype=np.float32)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        points = os.path.join(scratch, "grid.csv")
        np.savetxt(points, grid, delimiter=",", header="x,y", comments="", fmt="%.3f")
        grid_pair = dict(pair, points=points)
        for window in (21, 9):
            stats = os.path.join(scratch, "stats.json")
            kestrel_flow(directory, grid_pair, os.path.join(scratch, "o.csv"), window=window,
                         extra=("--repeat", str(repeat), "--stats", stats))
            with open(stats) as f:
                kestrel_s = json.load(f)["median_core_seconds"]
            cv2.setNumThreads(1)
            times = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                opencv_flow(a, b, grid, window=window)
                times.append(time.perf_counter() - t0)
            opencv_s = float(np.median(times))
            n = len(grid)
            rows.append((window, kestrel_s / n * 1e6, opencv_s / n * 1e6, opencv_s / kestrel_s))
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim")

    print(f"# Sparse LK benchmark, {datetime.date.today()}: bench/lk_vs_opencv.py "
          f"--pairs {options.pairs} --repeat {options.repeat}")
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}")
    with tempfile.TemporaryDirectory() as work:
        plain_dir, lit_dir = os.path.join(work, "plain"), os.path.join(work, "lit")
        plain = synth(plain_dir, seed=1, pairs=options.pairs)
        lit = synth(lit_dir, seed=2, pairs=options.pairs, gain=1.25, bias=15.0)

        print("\n## Speed: 300 points, 320x240, max level 3, both pyramids included, one thread")
        print("| window | Kestrel us/point | OpenCV us/point | OpenCV time / Kestrel time |")
        print("|---|---|---|---|")
        for window, kestrel_us, opencv_us, ratio in speed(plain_dir, plain[0], options.repeat):
            print(f"| {window}x{window} | {kestrel_us:.2f} | {opencv_us:.2f} | {ratio:.2f} |")

        for title, directory, manifest in (
            ("unchanged lighting", plain_dir, plain),
            ("gain 1.25, bias +15 on the second frame", lit_dir, lit),
        ):
            table = accuracy(directory, manifest)
            points = next(iter(table.values()))["points"]
            print(f"\n## Accuracy, {title}: {len(manifest)} pairs, {points} points, "
                  "endpoint error of tracked points")
            print("| tracker | median px | 95th pct px | tracked | tracked and off > 1 px |")
            print("|---|---|---|---|---|")
            for name, row in table.items():
                print(f"| {name} | {row['median']:.4f} | {row['p95']:.4f} | "
                      f"{100 * row['tracked']:.1f}% | {100 * row['off1']:.2f}% |")


if __name__ == "__main__":
    main()
