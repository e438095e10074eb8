#!/usr/bin/env python3
"""Decodes `host-sim egomotion --mavlink` output with a real MAVLink parser (pymavlink).

For seeded synthetic flights written by `host-sim synth-sequence`, runs `host-sim egomotion
--mavlink` and parses the frames with pymavlink's MAVLink 2 common dialect, checking every frame:
message id 106 (OPTICAL_FLOW_RAD), the CRC (by pymavlink and recomputed here), sender and
increasing sequence numbers, the timestamps and integration time of the frame clock, and that
the fields equal what ego.csv says (quality, integrated_x/y, zero flow at quality 0) and the gyro
log implies (integrated gyro, NaN without a gyro).

Each frame is one case; the last line is `N passed, M failed`, and the exit status is non-zero
on any failure.

Needs: python3 with pymavlink (pip install pymavlink).
Usage: tests/mavlink_decode.py [--no-build]
"""

import argparse
import csv
import math
import os
import struct
import subprocess
import sys
import tempfile

from pymavlink.dialects.v20 import common as mavlink2
from pymavlink.generator.mavcrc import x25crc

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
FPS = 30.0
SYSTEM_ID, COMPONENT_ID = 1, 100


def run(*args):
    subprocess.run(args, check=True, cwd=ROOT)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def frame_time_us(k):
    return round(k * 1e6 / FPS)


def float32(value):
    return struct.unpack("<f", struct.pack("<f", float(value)))[0]


def frames_of(data):
    """Splits a MAVLink 2 byte stream into frames (unsigned: header, payload, CRC)."""
    frames, offset = [], 0
    while offset < len(data):
        length = 10 + data[offset + 1] + 2
        frames.append(bytes(data[offset:offset + length]))
        offset += length
    return frames


def crc_is_valid(frame):
    crc = x25crc(frame[1:-2])
    crc.accumulate([mavlink2.MAVLink_optical_flow_rad_message.crc_extra])
    return crc.crc == struct.unpack("<H", frame[-2:])[0]


class Checks:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def case(self, name, problems):
        if problems:
            self.failed += 1
            print(f"FAIL {name}: {'; '.join(problems)}")
        else:
            self.passed += 1


def gyro_integral(gyro_rows, k):
    """The constant gyro rates of a synth-sequence log over frame interval k, rad."""
    if gyro_rows is None:
        return None
    rates = [float(gyro_rows[0][axis]) for axis in ("gx", "gy", "gz")]
    seconds = (frame_time_us(k) - frame_time_us(k - 1)) * 1e-6
    return [r * seconds for r in rates]


def check_frame(k, index, frame, message, row, gyro):
    """Problems with MAVLink frame `index` (of frame pair ending at frame `k`)."""
    problems = []

    def expect(ok, what):
        if not ok:
            problems.append(what)

    expect(frame[0] == 0xFD, f"magic {frame[0]:#x}, not MAVLink 2")
    expect(crc_is_valid(frame), "CRC does not match")
    expect(message.get_msgId() == 106, f"message id {message.get_msgId()}")
    expect(message.get_type() == "OPTICAL_FLOW_RAD", f"type {message.get_type()}")
    expect(message.get_seq() == index % 256, f"sequence {message.get_seq()}, expected {index % 256}")
    expect((message.get_srcSystem(), message.get_srcComponent()) == (SYSTEM_ID, COMPONENT_ID),
           f"sender {message.get_srcSystem()}/{message.get_srcComponent()}")
    expect(message.time_usec == frame_time_us(k), f"time_usec {message.time_usec}")
    interval = frame_time_us(k) - frame_time_us(k - 1)
    expect(message.integration_time_us > 0 and message.integration_time_us == interval,
           f"integration_time_us {message.integration_time_us}, expected {interval}")
    expect(int(row["frame"]) == k, f"ego.csv row is frame {row['frame']}")
    expect(message.quality == int(row["quality"]),
           f"quality {message.quality}, ego.csv says {row['quality']}")
    for axis in ("x", "y"):
        value = getattr(message, f"integrated_{axis}")
        expect(math.isfinite(value), f"integrated_{axis} is {value}")
        expect(value == float32(row[f"integrated_{axis}"]),
               f"integrated_{axis} {value}, ego.csv says {row[f'integrated_{axis}']}")
        if message.quality == 0:
            expect(value == 0.0, f"integrated_{axis} {value} at quality 0")
    gyro_fields = [message.integrated_xgyro, message.integrated_ygyro, message.integrated_zgyro]
    if gyro is None:
        expect(all(math.isnan(g) for g in gyro_fields), f"gyro {gyro_fields} without a gyro log")
    elif row["status"] != "bad_gyro":
        expect(all(abs(g - e) < 1e-6 for g, e in zip(gyro_fields, gyro)),
               f"gyro {gyro_fields}, expected {gyro}")
    expect(message.distance == -1.0, f"distance {message.distance}, expected -1 (unknown)")
    return problems


def check_run(checks, name, ego_csv, mavlink_bin, gyro_rows):
    rows = read_csv(ego_csv)
    with open(mavlink_bin, "rb") as f:
        data = f.read()
    frames = frames_of(data)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = False
    messages = parser.parse_buffer(data) or []
    checks.case(f"{name}: one frame per pair",
                [] if len(frames) == len(messages) == len(rows) > 0 else
                [f"{len(frames)} frames, {len(messages)} decoded, {len(rows)} rows in ego.csv"])
    for index, (frame, message, row) in enumerate(zip(frames, messages, rows)):
        k = index + 1
        gyro = gyro_integral(gyro_rows, k) if gyro_rows is not None else None
        checks.case(f"{name}: frame {k}", check_frame(k, index, frame, message, row, gyro))
    return frames


def flight(scratch, name, path, frames, size, objects=0):
    out = os.path.join(scratch, name)
    run(HOST_SIM, "synth-sequence", "--out", out, "--path", path, "--frames", str(frames),
        "--width", str(size[0]), "--height", str(size[1]), "--objects", str(objects),
        "--seed", "5")
    return out


def egomotion(directory, gyro=None, tag="ego"):
    ego_csv = os.path.join(directory, f"{tag}.csv")
    mavlink_bin = os.path.join(directory, f"{tag}.bin")
    args = [HOST_SIM, "egomotion", os.path.join(directory, "frames"), "--out", ego_csv,
            "--mavlink", mavlink_bin]
    if gyro:
        args += ["--gyro", gyro]
    run(*args)
    return ego_csv, mavlink_bin


def spoil_gyro(directory):
    """A copy of the flight's gyro log with a NaN in frame interval 3 and 1000 rad/s in 6.

    Only samples more than a sample period from the frame times are spoiled: rates are linear
    between samples, so a sample also weighs on the interval next to it when it is that close.
    """
    rows = read_csv(os.path.join(directory, "gyro.csv"))

    def inside(t, k):
        return frame_time_us(k - 1) + 1000 < t < frame_time_us(k) - 1000

    for row in rows:
        t = float(row["t_us"])
        if inside(t, 3):
            row["gx"] = "NaN"
        if inside(t, 6):
            row["gz"] = "1000"
    path = os.path.join(directory, "spoiled.csv")
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["t_us", "gx", "gy", "gz"], lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--no-build", action="store_true", help="use the built host-sim as is")
    options = parser.parse_args()
    if not options.no_build:
        run("cargo", "build", "--release", "--quiet", "-p", "host-sim")

    checks = Checks()
    with tempfile.TemporaryDirectory() as scratch:
        # Pure rotation with its exact gyro: the integrated gyro is on the wire.
        rotation = flight(scratch, "rotation", "rotation", 10, (160, 120), objects=1)
        gyro_rows = read_csv(os.path.join(rotation, "gyro.csv"))
        ego_csv, mavlink_bin = egomotion(rotation, os.path.join(rotation, "gyro.csv"))
        frames = check_run(checks, "rotation with gyro", ego_csv, mavlink_bin, gyro_rows)

        # A corrupted byte must fail the CRC in pymavlink (the checker can see a bad frame).
        corrupted = bytearray(frames[0])
        corrupted[20] ^= 0x40
        strict = mavlink2.MAVLink(None)
        strict.robust_parsing = False
        try:
            strict.parse_buffer(bytes(corrupted))
            problems = ["a corrupted frame was accepted"]
        except mavlink2.MAVError:
            problems = []
        checks.case("corrupted frame is rejected", problems + (
            ["recomputed CRC accepts it"] if crc_is_valid(bytes(corrupted)) else []))

        # NaN and absurd gyro values: quality 0 and zero flow for those intervals only.
        spoiled = spoil_gyro(rotation)
        ego_csv, mavlink_bin = egomotion(rotation, spoiled, tag="spoiled")
        check_run(checks, "spoiled gyro", ego_csv, mavlink_bin, gyro_rows)
        statuses = [row["status"] for row in read_csv(ego_csv)]
        checks.case("spoiled gyro: bad intervals flagged",
                    [] if statuses[2] == statuses[5] == "bad_gyro" and statuses[0] == "ok"
                    else [f"statuses {statuses}"])

        # Perspective with moving objects and no gyro: NaN gyro fields on the wire.
        perspective = flight(scratch, "perspective", "perspective", 10, (160, 120), objects=2)
        ego_csv, mavlink_bin = egomotion(perspective)
        check_run(checks, "perspective without gyro", ego_csv, mavlink_bin, None)

        # More than 256 frames: the sequence number wraps.
        long_flight = flight(scratch, "long", "shake", 260, (64, 48))
        ego_csv, mavlink_bin = egomotion(long_flight)
        check_run(checks, "260 frames", ego_csv, mavlink_bin, None)

    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
