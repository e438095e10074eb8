#!/usr/bin/env python3
"""docs/accuracy_vs_opencv.png: how far tracked points are from the ground truth, Kestrel's
KLT tracker beside OpenCV's classic KLT loop.

The flights, the two trackers and the truth are those of bench/track_vs_opencv.py (seeded
`host-sim synth-sequence` flights, 320x240, 101 frames, 100 tracks aimed for): every frame of
every track after its first is compared with where its birth point truly is in that frame
(the exact homography). The plot is the share of track-frames within each error, per flight
path, for both trackers.

Needs: python3 with numpy, opencv-python-headless and matplotlib.
Usage: bench/accuracy_plot.py [--frames N] [--out docs/accuracy_vs_opencv.png] [--no-build]
"""

import argparse
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import track_vs_opencv as bench  # noqa: E402

PATHS = ("pan", "yaw", "climb")
WIDTH, HEIGHT = 320, 240


def errors(history, to_frame):
    """Distance to the truth of every track-frame after each track's first, px."""
    out = []
    for frames in history.values():
        born = min(frames)
        for k, p in frames.items():
            if k != born:
                truth = bench.expected(to_frame, born, frames[born], k)
                out.append(float(np.hypot(p[0] - truth[0], p[1] - truth[1])))
    return np.sort(np.array(out))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=101)
    parser.add_argument("--out", default=os.path.join(bench.ROOT, "docs", "accuracy_vs_opencv.png"))
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    if not options.no_build:
        bench.run("cargo", "build", "--release", "-q", "-p", "host-sim")
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    colours = dict(zip(PATHS, ("tab:blue", "tab:orange", "tab:green")))
    with tempfile.TemporaryDirectory() as work:
        for path in PATHS:
            directory = os.path.join(work, path)
            images, to_frame = bench.flight(directory, path, WIDTH, HEIGHT, options.frames)
            for name, style, (history, _, _) in (("Kestrel", "-", bench.kestrel(directory)),
                                                  ("OpenCV", "--", bench.opencv(images))):
                e = errors(history, to_frame)
                share = np.arange(1, len(e) + 1) / len(e)
                median = float(np.median(e))
                ax.plot(np.maximum(e, 1e-3), share, style, color=colours[path],
                        label=f"{name}, {path} (median {median:.3f} px)")
                print(f"{path:6s} {name:8s} track-frames {len(e):6d}  median {median:.3f} px  "
                      f"within 0.5 px {100 * np.mean(e <= 0.5):.1f}%  "
                      f"within 2 px {100 * np.mean(e <= 2):.1f}%")
    ax.set_xscale("log")
    ax.set_xlim(1e-3, 20)
    ax.set_ylim(0, 1)
    ax.set_xlabel("error against ground truth, px (log scale)")
    ax.set_ylabel("share of track-frames within that error")
    ax.set_title(f"KLT tracking, {WIDTH}x{HEIGHT}, {options.frames} frames, 100 tracks: "
                 "Kestrel (solid) and OpenCV (dashed)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    os.makedirs(os.path.dirname(options.out), exist_ok=True)
    fig.savefig(options.out)
    print(f"wrote {options.out}")


if __name__ == "__main__":
    main()
