#!/usr/bin/env python3
"""Packs a directory of grey frames (as `host-sim synth-sequence` writes them) into one y4m
file (C420jpeg, grey chroma), the INPUT of host-sim's sequence commands.

Needs: python3 with numpy and opencv-python-headless.
Usage: bench/frames_to_y4m.py FRAMES_DIR OUT.y4m [--fps 30]
"""

import argparse
import os

import cv2
import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("frames")
    parser.add_argument("out")
    parser.add_argument("--fps", type=int, default=30)
    options = parser.parse_args()
    names = sorted(n for n in os.listdir(options.frames) if not n.startswith("."))
    first = cv2.imread(os.path.join(options.frames, names[0]), cv2.IMREAD_GRAYSCALE)
    height, width = first.shape
    chroma = np.full(2 * ((width + 1) // 2) * ((height + 1) // 2), 128, np.uint8).tobytes()
    with open(options.out, "wb") as out:
        out.write(f"YUV4MPEG2 W{width} H{height} F{options.fps}:1 Ip A1:1 C420jpeg\n".encode())
        for name in names:
            frame = cv2.imread(os.path.join(options.frames, name), cv2.IMREAD_GRAYSCALE)
            out.write(b"FRAME\n" + frame.tobytes() + chroma)
    print(f"wrote {options.out}: {len(names)} frames of {width}x{height}")


if __name__ == "__main__":
    main()
