#!/usr/bin/env python3
"""KLT tracking over 100 frames: Kestrel's tracker beside OpenCV's classic KLT loop.

Both get the same seeded synthetic flights from `host-sim synth-sequence` (101 frames, noise 1
grey level, exact homography between every pair of frames) and aim for 100 tracks.

- Kestrel: `host-sim track --max-tracks 100 --refill-below 100 --stats`: refilled whenever
  fewer than 100 tracks are live, as OpenCV's loop below is, since a track's life depends on
  how often new ones start; the library's time per frame (pyramid, forward and backward LK,
  gates, detection when refilling), decoding excluded.
- OpenCV: the loop of OpenCV's `lk_track.py` sample: calcOpticalFlowPyrLK forward and back
  (window 21, max level 3, as Kestrel's tracker), tracks kept when the round trip ends within
  1 px, and goodFeaturesToTrack (quality 0.01, min distance 5, masked around live tracks) to
  refill up to 100 whenever fewer are alive; one thread. Timed around the OpenCV calls.

Ground truth: a track born at frame b at p is expected at H(b -> k) p in frame k. Besides the
state at the last frame: the mean track life (frames a track is live in, its first included),
the share of track-frames more than 2 px from that truth, the median error at their last frame
of the tracks that lived 10 frames or more, and Kestrel's drops by gate.

Needs: python3 with numpy and opencv-python-headless.
Usage: bench/track_vs_opencv.py [--frames N] [--no-build]
"""

import argparse
import csv
import datetime
import json
import os
import subprocess
import tempfile
import time

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
MAX_TRACKS = 100
SIZES = ((160, 120), (320, 240))
PATHS = ("pan", "yaw", "climb")


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def flight(out, path, width, height, frames):
    run(HOST_SIM, "synth-sequence", "--out", out, "--path", path, "--frames", str(frames),
        "--width", str(width), "--height", str(height), "--seed", "1")
    with open(os.path.join(out, "truth.csv"), newline="") as f:
        steps = [np.array([float(r[f"h{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)])
                 .reshape(3, 3) for r in csv.DictReader(f)]
    # to_frame[k] maps frame 0 to frame k.
    to_frame = [np.eye(3)]
    for step in steps:
        to_frame.append(step @ to_frame[-1])
    names = sorted(os.listdir(os.path.join(out, "frames")))
    images = [cv2.imread(os.path.join(out, "frames", n), cv2.IMREAD_GRAYSCALE) for n in names]
    return images, to_frame


def expected(to_frame, born, point, frame):
    h = to_frame[frame] @ np.linalg.inv(to_frame[born])
    x, y, w = h @ np.array([point[0], point[1], 1.0])
    return np.array([x / w, y / w])


def kestrel(directory, extra=()):
    tracks_csv = os.path.join(directory, "tracks.csv")
    stats = os.path.join(directory, "stats.json")
    run(HOST_SIM, "track", os.path.join(directory, "frames"), "--out", tracks_csv,
        "--max-tracks", str(MAX_TRACKS), "--refill-below", str(MAX_TRACKS), "--stats", stats,
        *extra)
    history, summary = read_kestrel(tracks_csv, stats)
    return history, summary["median_frame_seconds"], summary.get("drops", {})


def read_kestrel(tracks_csv, stats):
    """`host-sim track`'s tracks as {id: {frame: (x, y)}}, and its --stats summary."""
    history = {}
    with open(tracks_csv, newline="") as f:
        for r in csv.DictReader(f):
            history.setdefault(int(r["id"]), {})[int(r["frame"])] = (float(r["x"]), float(r["y"]))
    with open(stats) as f:
        return history, json.load(f)


def opencv(images, refill_below=MAX_TRACKS):
    """OpenCV's lk_track loop, refilled up to MAX_TRACKS whenever fewer than `refill_below`
    tracks are live: the tracks as {id: {frame: (x, y)}}, the median seconds per frame, and no
    drops by gate (it has none)."""
    cv2.setNumThreads(1)
    lk = dict(winSize=(21, 21), maxLevel=3,
              criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    history, live, next_id, seconds = {}, [], 0, []
    for k, frame in enumerate(images):
        start = time.perf_counter()
        if live and k > 0:
            p0 = np.float32([history[i][k - 1] for i in live]).reshape(-1, 1, 2)
            p1, _, _ = cv2.calcOpticalFlowPyrLK(images[k - 1], frame, p0, None, **lk)
            back, _, _ = cv2.calcOpticalFlowPyrLK(frame, images[k - 1], p1, None, **lk)
            good = np.abs(p0 - back).reshape(-1, 2).max(-1) < 1.0
            kept = []
            for i, p, ok in zip(live, p1.reshape(-1, 2), good):
                h, w = frame.shape
                if ok and 0 <= p[0] <= w - 1 and 0 <= p[1] <= h - 1:
                    history[i][k] = (float(p[0]), float(p[1]))
                    kept.append(i)
            live = kept
        if len(live) < refill_below:
            mask = np.full_like(frame, 255)
            for i in live:
                cv2.circle(mask, tuple(int(v) for v in history[i][k]), 5, 0, -1)
            corners = cv2.goodFeaturesToTrack(frame, MAX_TRACKS - len(live), 0.01, 5,
                                              mask=mask, blockSize=7)
            for p in ([] if corners is None else corners.reshape(-1, 2)):
                history[next_id] = {k: (float(p[0]), float(p[1]))}
                live.append(next_id)
                next_id += 1
        seconds.append(time.perf_counter() - start)
    return history, float(np.median(seconds)), {}


def score(history, to_frame, last):
    births = {i: min(frames) for i, frames in history.items()}
    first = [i for i, b in births.items() if b == 0]
    alive_last = [i for i, frames in history.items() if last in frames]
    errors = np.array([np.linalg.norm(np.array(history[i][last])
                                      - expected(to_frame, births[i], history[i][births[i]], last))
                       for i in alive_last])
    live_counts = [sum(1 for frames in history.values() if k in frames) for k in range(last + 1)]
    # Every track-frame against where the track's birth point is in that frame.
    def error(i, k):
        truth = expected(to_frame, births[i], history[i][births[i]], k)
        return float(np.linalg.norm(np.array(history[i][k]) - truth))
    track_frames = [error(i, k) for i, frames in history.items() for k in frames if k != births[i]]
    long_lived = [error(i, max(frames)) for i, frames in history.items() if len(frames) >= 11]
    return {
        "life": float(np.mean([len(frames) for frames in history.values()])),
        "off2": float(np.mean(np.array(track_frames) > 2.0)) if track_frames else 0.0,
        "drift": float(np.median(long_lived)) if long_lived else float("nan"),
        "live": float(np.mean(live_counts)),
        "survival": sum(1 for i in first if last in history[i]) / max(1, len(first)),
        "within1": float((errors <= 1.0).mean()) if len(errors) else 0.0,
        "median": float(np.median(errors)) if len(errors) else float("nan"),
        "ids": len(history),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=101)
    parser.add_argument("--no-build", action="store_true")
    parser.add_argument("--kestrel-only", action="store_true", help="skip OpenCV's loop")
    parser.add_argument("--kestrel-args", default="",
                        help="extra flags for host-sim track, e.g. \"--window 15\"")
    options = parser.parse_args()
    extra = options.kestrel_args.split()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim")
    last = options.frames - 1
    print(f"# KLT tracking benchmark, {datetime.date.today()}: bench/track_vs_opencv.py "
          f"--frames {options.frames}; OpenCV {cv2.__version__}")
    print(f"\n| size | path | tracker | ms per frame | live tracks (mean) | frame-0 tracks alive "
          f"at frame {last} | tracks within 1 px at frame {last} | median error | ids used "
          f"| mean track life, frames | track-frames off by > 2 px | median drift of tracks of "
          f"10+ frames |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    drops_rows = []
    with tempfile.TemporaryDirectory() as work:
        for width, height in SIZES:
            for path in PATHS:
                directory = os.path.join(work, f"{path}{width}")
                images, to_frame = flight(directory, path, width, height, options.frames)
                runs = [("Kestrel", lambda: kestrel(directory, extra))]
                if not options.kestrel_only:
                    runs.append(("OpenCV", lambda: opencv(images)))
                for name, result in runs:
                    history, seconds, drops = result()
                    s = score(history, to_frame, last)
                    print(f"| {width}x{height} | {path} | {name} | {1e3 * seconds:.2f} | "
                          f"{s['live']:.1f} | {100 * s['survival']:.0f}% | "
                          f"{100 * s['within1']:.1f}% | {s['median']:.3f} px | {s['ids']} | "
                          f"{s['life']:.1f} | {100 * s['off2']:.1f}% | {s['drift']:.2f} px |")
                    if drops:
                        drops_rows.append((width, height, path, drops))
    print("\nKestrel's tracks dropped by gate (`host-sim track --stats`):\n")
    reasons = ("lost", "out_of_frame", "residual", "appearance", "relocation", "forward_backward")
    print("| size | path | " + " | ".join(r.replace("_", " ") for r in reasons) + " |")
    print("|---|---|" + "---|" * len(reasons))
    for width, height, path, d in drops_rows:
        counts = " | ".join(str(d.get(r, 0)) for r in reasons)
        print(f"| {width}x{height} | {path} | {counts} |")


if __name__ == "__main__":
    main()
