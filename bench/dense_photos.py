#!/usr/bin/env python3
"""Grid flow on photographs: Kestrel's grid beside Farneback on real images under known warps.

Photographs: the samples bundled with scikit-image, in grey: ground textures seen from above
(grass, gravel, brick) and scenes (camera, astronaut, coffee, chelsea, rocket, coins,
motorcycle_left). Each is scaled down (area averaging) until the frame and a 16 px margin cover
its centre. Frame A is that centre; frame B is the scaled photograph resampled (bilinear) under
a seeded warp about the frame's centre drawn as `host-sim synth` draws its own: a translation
up to 8 px in any direction, a rotation within 1 degree and a zoom within 2 %. Sensor noise of
1.5 grey levels is added to both frames, which are rounded to 8 bits.

Scored at the nodes of the 8 px grid against the exact warp: Kestrel's `host-sim dense` with its
defaults at its valid nodes, and Farneback (OpenCV, as in bench/dense_vs_opencv.py) at the
same nodes and at every node; the share of nodes valid, per photograph and over all.

Needs: python3 with numpy, opencv-python-headless and scikit-image (for the photographs).
Usage: bench/dense_photos.py [--warps N] [--no-build] [dense flags ...]
(arguments after the known ones go to `host-sim dense`, e.g. --smooth-passes 0).
"""

import argparse
import datetime
import os
import sys
import tempfile

import cv2
import numpy as np

from dense_vs_opencv import HOST_SIM, ROOT, farneback, nodes, read_csv, run

try:
    import skimage
    import skimage.data
except ImportError:
    sys.exit("bench/dense_photos.py needs scikit-image for its photographs: pip install scikit-image")

PHOTOS = ("grass", "gravel", "brick", "camera", "astronaut", "coffee", "chelsea", "rocket",
          "coins", "motorcycle_left")
MARGIN = 16
NOISE = 1.5


def photograph(name, width, height):
    """The photograph in grey, scaled and cropped to the frame plus the margin on every side."""
    if name == "motorcycle_left":
        image = skimage.data.stereo_motorcycle()[0]
    else:
        image = getattr(skimage.data, name)()
    if image.ndim == 3:
        image = cv2.cvtColor(image[..., :3], cv2.COLOR_RGB2GRAY)
    big_w, big_h = width + 2 * MARGIN, height + 2 * MARGIN
    scale = max(big_w / image.shape[1], big_h / image.shape[0])
    size = (max(big_w, round(image.shape[1] * scale)), max(big_h, round(image.shape[0] * scale)))
    scaled = cv2.resize(image, size, interpolation=cv2.INTER_AREA).astype(np.float32)
    x0, y0 = (size[0] - big_w) // 2, (size[1] - big_h) // 2
    return scaled[y0:y0 + big_h, x0:x0 + big_w]


def random_warp(rng):
    """(shift, angle in radians, scale), drawn as host-sim synth draws its warps."""
    length, direction = rng.uniform(0.0, 8.0), rng.uniform(0.0, 2 * np.pi)
    return (np.array([length * np.cos(direction), length * np.sin(direction)]),
            np.radians(rng.uniform(-1.0, 1.0)), rng.uniform(0.98, 1.02))


def pair(big, width, height, warp, rng):
    """Frames A and B (8-bit) and the forward warp of frame coordinates."""
    shift, angle, scale = warp
    rot = scale * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    # The same warp in the coordinates of the photograph with its margin.
    big_centre = centre + MARGIN
    forward = np.hstack([rot, (big_centre + shift - rot @ big_centre).reshape(2, 1)])
    moved = cv2.warpAffine(big, forward, (big.shape[1], big.shape[0]), flags=cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REFLECT)
    crop = (slice(MARGIN, MARGIN + height), slice(MARGIN, MARGIN + width))

    def sensor(frame):
        noisy = frame[crop] + rng.normal(0.0, NOISE, (height, width))
        return np.clip(np.round(noisy), 0, 255).astype(np.uint8)

    def true_flow(points):
        return (points - centre) @ rot.T + centre + shift - points

    return sensor(big), sensor(moved), true_flow


def kestrel_grid(a, b, scratch, extra):
    paths = [os.path.join(scratch, n) for n in ("a.png", "b.png", "grid.csv")]
    cv2.imwrite(paths[0], a)
    cv2.imwrite(paths[1], b)
    run(HOST_SIM, "dense", "--prev", paths[0], "--next", paths[1], "--out", paths[2], *extra)
    rows = read_csv(paths[2])
    flow = np.array([[float(r["dx"]), float(r["dy"])] for r in rows])
    return flow, np.array([r["ok"] == "1" for r in rows])


def benchmark(width, height, warps, scratch, extra):
    points = nodes(width, height)
    xi, yi = points[:, 0].astype(int), points[:, 1].astype(int)
    per_photo = {}
    for index, name in enumerate(PHOTOS):
        big = photograph(name, width, height)
        rng = np.random.default_rng(1000 * index + width)
        scores = {"kestrel": [], "fb_kestrel": [], "fb_all": [], "valid": 0, "nodes": 0}
        for _ in range(warps):
            a, b, true_flow = pair(big, width, height, random_warp(rng), rng)
            truth = true_flow(points)
            flow, ok = kestrel_grid(a, b, scratch, extra)
            fb = farneback(a, b)[yi, xi]
            epe = lambda f: np.linalg.norm(f - truth, axis=1)
            scores["kestrel"].extend(epe(flow)[ok])
            scores["fb_kestrel"].extend(epe(fb)[ok])
            scores["fb_all"].extend(epe(fb))
            scores["valid"] += int(ok.sum())
            scores["nodes"] += len(points)
        per_photo[name] = scores
    return per_photo


def summary(scores):
    """Valid share, then median and share above 1 px of Kestrel, Farneback at its nodes and
    Farneback everywhere."""
    cells = [f"{100 * scores['valid'] / scores['nodes']:.1f} %"]
    for key in ("kestrel", "fb_kestrel", "fb_all"):
        e = np.array(scores[key])
        cells.append(f"{np.median(e):.3f} / {100 * (e > 1).mean():.1f} %" if len(e) else "-")
    return cells


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--warps", type=int, default=10)
    parser.add_argument("--no-build", action="store_true")
    options, extra = parser.parse_known_args()
    if not options.no_build:
        run("cargo", "build", "--release", "-q", "-p", "host-sim", "--bin", "host-sim")
    print(f"# Grid flow on photographs, {datetime.date.today()}: bench/dense_photos.py "
          f"--warps {options.warps} {' '.join(extra)}".rstrip())
    print(f"OpenCV {cv2.__version__}, scikit-image {skimage.__version__}, numpy "
          f"{np.__version__}; host-sim dense defaults (8 px cells, window 9, level 3)")
    with tempfile.TemporaryDirectory() as scratch:
        for width, height in ((160, 120), (320, 240)):
            per_photo = benchmark(width, height, options.warps, scratch, extra)
            print(f"\n## {width}x{height}, {options.warps} warps per photograph (shift <= 8 px, "
                  "rotation <= 1 deg, zoom <= 2 %, noise 1.5)")
            print("| photograph | nodes valid | Kestrel, median px / > 1 px | Farneback at "
                  "Kestrel's valid nodes | Farneback at every node |")
            print("|---|---|---|---|---|")
            total = {"kestrel": [], "fb_kestrel": [], "fb_all": [], "valid": 0, "nodes": 0}
            for name, scores in per_photo.items():
                print(f"| {name} | " + " | ".join(summary(scores)) + " |")
                for key, value in scores.items():
                    total[key] = total[key] + value
            print("| all | " + " | ".join(summary(total)) + " |")


if __name__ == "__main__":
    os.chdir(ROOT)
    main()
