#!/usr/bin/env python3
"""Camera motion between frames: Kestrel (`host-sim egomotion`) and OpenCV on the same frames.

Frames: seeded synthetic flights from `host-sim synth-sequence` over textured ground, with two
independently moving textured objects (20-30% of the tracks are outliers) and sensor noise of
1 grey level; camera paths pan, yaw, climb and perspective; 160x120 and 320x240.

Both sides measure the homography of every consecutive frame pair the same way:
- Kestrel: the library's Shi-Tomasi corners spread by a grid (at most 200), Q16 pyramidal LK,
  RANSAC homography (0.5 px threshold, the default) with a least-squares refit, as
  `host-sim egomotion` runs them. Time per pair from `--stats`: building the new frame's pyramid (the previous one is
  kept), detection, tracking and the fit.
- OpenCV: goodFeaturesToTrack (200 corners, quality 0.01, the same minimum distance),
  calcOpticalFlowPyrLK (21x21 window, max level 3, 30 iterations, epsilon 0.01),
  findHomography with RANSAC (the same 0.5 px threshold), one thread. Time per pair: all three
  calls (calcOpticalFlowPyrLK builds both pyramids itself).

Corner error: the mean distance between the images of the four frame corners under the
estimated and the exact homography; the median and 95th percentile over all pairs of a path are
reported. Time: the median over the pairs of a flight, in each of `--repeat` runs; the median
of those runs; the median over the flights of a row. Outlier tracks: the share of OpenCV's LK tracks more than 1 px from where the exact
camera motion takes them (the moving objects, and the tracks LK loses). Decoding is never timed.

Needs: python3 with numpy and opencv-python-headless (pip install numpy opencv-python-headless).
Usage: bench/ego_vs_opencv.py [--sequences N] [--frames N] [--repeat N] [--no-build]
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
PATHS = ("pan", "yaw", "climb", "perspective")
SIZES = ((160, 120), (320, 240))
MAX_POINTS, WINDOW, LEVELS, ITERATIONS, EPSILON, THRESHOLD = 200, 21, 3, 30, 0.01, 0.5


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def homographies(path):
    """frame -> 3x3 homography, from ego.csv or truth.csv."""
    names = [f"h{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
    return {int(r["frame"]): np.array([float(r[n]) for n in names]).reshape(3, 3)
            for r in read_csv(path)}


def corner_error(estimate, truth, width, height):
    corners = np.array([[0, 0, 1], [width - 1, 0, 1], [0, height - 1, 1],
                        [width - 1, height - 1, 1]], dtype=np.float64).T
    a, b = estimate @ corners, truth @ corners
    return float(np.mean(np.hypot(*(a[:2] / a[2] - b[:2] / b[2]))))


def min_distance(width, height):
    """Kestrel's corner spacing: room for twice the points, between 3 and 10 px."""
    return int(min(10.0, max(3.0, (width * height / (2 * MAX_POINTS)) ** 0.5)))


def kestrel(directory, repeat):
    """Per-pair homographies, and the median over `repeat` runs of the median seconds per pair."""
    ego, stats = os.path.join(directory, "ego.csv"), os.path.join(directory, "stats.json")
    seconds = []
    for _ in range(repeat):
        run(HOST_SIM, "egomotion", os.path.join(directory, "frames"), "--out", ego,
            "--stats", stats, "--max-points", str(MAX_POINTS))
        with open(stats) as f:
            seconds.append(json.load(f)["median_pair_seconds"])
    return homographies(ego), float(np.median(seconds))


def opencv_pair(prev, nxt, spacing):
    """The homography (None when none was found) and the tracks it was fitted to."""
    corners = cv2.goodFeaturesToTrack(prev, MAX_POINTS, 0.01, spacing)
    if corners is None or len(corners) < 4:
        return None, None
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, ITERATIONS, EPSILON)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(prev, nxt, corners, None,
                                               winSize=(WINDOW, WINDOW), maxLevel=LEVELS,
                                               criteria=criteria)
    ok = status.ravel() == 1
    tracks = (corners[ok].reshape(-1, 2), moved[ok].reshape(-1, 2))
    if ok.sum() < 4:
        return None, tracks
    h, _ = cv2.findHomography(corners[ok], moved[ok], cv2.RANSAC, THRESHOLD)
    return (None if h is None else h / h[2, 2]), tracks


def outlier_share(tracks, truth):
    """Share of the tracks more than 1 px from where the camera's motion takes them: the
    contamination of the data, whoever estimates from it."""
    start, end = tracks
    if len(start) == 0:
        return 0.0
    p = truth @ np.vstack([start.T, np.ones(len(start))])
    error = np.hypot(*(p[:2] / p[2] - end.T))
    return float((error > 1.0).mean())


def opencv(directory, truth, repeat, spacing):
    """Per-pair homographies (identity when none was found), the share of outlier tracks, and
    the median over `repeat` runs of the median seconds per pair, as for Kestrel."""
    frames_dir = os.path.join(directory, "frames")
    frames = [cv2.imread(os.path.join(frames_dir, name), cv2.IMREAD_GRAYSCALE)
              for name in sorted(os.listdir(frames_dir))]
    estimates, outliers, run_medians = {}, [], []
    for _ in range(repeat):
        seconds = []
        for k in range(1, len(frames)):
            t0 = time.perf_counter()
            h, tracks = opencv_pair(frames[k - 1], frames[k], spacing)
            seconds.append(time.perf_counter() - t0)
            estimates[k] = h if h is not None else np.eye(3)
            if tracks is not None and len(run_medians) == 0:
                outliers.append(outlier_share(tracks, truth[k]))
        run_medians.append(float(np.median(seconds)))
    return estimates, float(np.mean(outliers)), float(np.median(run_medians))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sequences", type=int, default=3, help="seeded flights per path")
    parser.add_argument("--frames", type=int, default=20, help="frames per flight")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of each flight")
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim")
    cv2.setNumThreads(1)

    print(f"# Ego-motion benchmark, {datetime.date.today()}: bench/ego_vs_opencv.py "
          f"--sequences {options.sequences} --frames {options.frames} --repeat {options.repeat}")
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}; "
          f"{options.sequences} flights x {options.frames - 1} pairs per row, "
          "two moving objects, noise 1 grey level")
    print()
    print("| size | path | outlier tracks | corner error median px: Kestrel / OpenCV "
          "| 95th pct px: Kestrel / OpenCV | ms per pair: Kestrel / OpenCV |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for width, height in SIZES:
            spacing = min_distance(width, height)
            for path in PATHS:
                errors = {"Kestrel": [], "OpenCV": []}
                seconds = {"Kestrel": [], "OpenCV": []}
                outliers = []
                for seed in range(1, options.sequences + 1):
                    directory = os.path.join(work, f"{path}-{width}-{seed}")
                    run(HOST_SIM, "synth-sequence", "--out", directory, "--path", path,
                        "--frames", str(options.frames), "--width", str(width),
                        "--height", str(height), "--seed", str(seed), "--objects", "2")
                    truth = homographies(os.path.join(directory, "truth.csv"))
                    k_h, k_s = kestrel(directory, options.repeat)
                    o_h, o_out, o_s = opencv(directory, truth, options.repeat, spacing)
                    outliers.append(o_out)
                    for name, estimates in (("Kestrel", k_h), ("OpenCV", o_h)):
                        errors[name] += [corner_error(estimates[k], truth[k], width, height)
                                         for k in truth]
                    seconds["Kestrel"].append(k_s)
                    seconds["OpenCV"].append(o_s)
                med = {n: np.median(e) for n, e in errors.items()}
                p95 = {n: np.percentile(e, 95) for n, e in errors.items()}
                ms = {n: 1e3 * np.median(s) for n, s in seconds.items()}
                print(f"| {width}x{height} | {path} | {100 * np.mean(outliers):.0f}% "
                      f"| {med['Kestrel']:.3f} / {med['OpenCV']:.3f} "
                      f"| {p95['Kestrel']:.3f} / {p95['OpenCV']:.3f} "
                      f"| {ms['Kestrel']:.2f} / {ms['OpenCV']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
