#!/usr/bin/env python3
"""Sparse LK speed through the Python API: kestrel.calc_optical_flow_pyr_lk beside
cv2.calcOpticalFlowPyrLK, and the library's own time from Rust (host-sim flow) in the same run.

The pair and points are bench/lk_vs_opencv.py's: 300 points (a 20 x 15 grid) on the first
320x240 pair of `host-sim synth --seed 1`, windows 21 and 9, max level 3, 30 iterations,
epsilon 0.01 px. Every side times the whole call: both pyramids and the tracking; the Python
times include the conversion of the arrays in and out. OpenCV runs on one thread
(cv2.setNumThreads(1)). The Python calls of the two libraries alternate, median of --repeat.

Needs: the kestrel package (pip install ./python), numpy and opencv-python-headless.
Usage: bench/lk_vs_opencv_python.py [--repeat N] [--no-build]
"""

import argparse
import datetime
import os
import sys
import tempfile
import time

import cv2
import numpy as np

import kestrel

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lk_vs_opencv as rust  # noqa: E402  (the Rust side: host-sim synth and flow)

LEVELS, ITERATIONS, EPSILON = 3, 30, 0.01
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, ITERATIONS, EPSILON)


def grid_points(w, h):
    xs, ys = np.linspace(12, w - 13, 20), np.linspace(12, h - 13, 15)
    return np.array([(x, y) for y in ys for x in xs], dtype=np.float32).reshape(-1, 1, 2)


def median_us_per_point(call, n, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / n * 1e6


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    if not options.no_build:
        rust.run("cargo", "build", "--release", "-q", "-p", "host-sim")
    cv2.setNumThreads(1)

    print(f"# Sparse LK through Python, {datetime.date.today()}: bench/lk_vs_opencv_python.py "
          f"--repeat {options.repeat}")
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, kestrel {kestrel.__version__}, "
          f"python {sys.version.split()[0]}")
    print("\n## 300 points, 320x240, max level 3, both pyramids included, one thread, "
          "median us per point")
    print("| window | Kestrel (Rust) | Kestrel from Python, gain_bias | Kestrel from Python, plain "
          "| OpenCV from Python | Python gain_bias / OpenCV | Python plain / OpenCV |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        manifest = rust.synth(work, seed=1, pairs=1)
        pair = manifest[0]
        a = cv2.imread(os.path.join(work, pair["a"]), cv2.IMREAD_GRAYSCALE)
        b = cv2.imread(os.path.join(work, pair["b"]), cv2.IMREAD_GRAYSCALE)
        points = grid_points(a.shape[1], a.shape[0])
        n = len(points)
        rust_rows = {w: k for w, k, _, _ in rust.speed(work, pair, options.repeat)}
        for window in (21, 9):
            size = (window, window)

            def mine(illumination):
                return lambda: kestrel.calc_optical_flow_pyr_lk(
                    a, b, points, None, win_size=size, max_level=LEVELS, criteria=CRITERIA,
                    illumination=illumination)

            def theirs():
                cv2.calcOpticalFlowPyrLK(a, b, points, None, winSize=size, maxLevel=LEVELS,
                                         criteria=CRITERIA)

            gain, plain, opencv = [], [], []
            for _ in range(options.repeat):
                gain.append(median_us_per_point(mine("gain_bias"), n, 1))
                plain.append(median_us_per_point(mine("plain"), n, 1))
                opencv.append(median_us_per_point(theirs, n, 1))
            g, p, o = (float(np.median(x)) for x in (gain, plain, opencv))
            print(f"| {window}x{window} | {rust_rows[window]:.2f} | {g:.2f} | {p:.2f} | {o:.2f} "
                  f"| {g / o:.2f} | {p / o:.2f} |")


if __name__ == "__main__":
    main()
