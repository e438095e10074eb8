#!/usr/bin/env python3
"""Reads the firmware's live MAVLink stream from QEMU's USART2 and checks every message.

Listens on a TCP port of 127.0.0.1, runs the built firmware through its QEMU runner
(firmware/.cargo/config.toml) with USART2 connected to that port (`-serial null -serial
tcp:...`), and parses the bytes with pymavlink's MAVLink 2 parser as they arrive. Checks:

- every frame's CRC (pymavlink's bad-data count) and one sequence from 0 without gaps;
- HEARTBEAT: a camera (MAV_TYPE 30) that is not an autopilot (8), one per second of the frame
  clock, before the first readout of that second;
- OPTICAL_FLOW_RAD: 10 ms integration, time stamps 10 ms apart, no gyro (NaN), distance
  unknown (-1); flow at quality > 0 within 0.05 px (at the principal point) of the scene's
  motion from firmware/src/scene.rs, forwards or backwards (the firmware flies the frames back
  and forth); zero flow at quality 0;
- OPTICAL_FLOW after each OPTICAL_FLOW_RAD: the same time and quality, flow_rate_x/y the same
  flow per second, flow_x/y the same flow in deci-pixels;
- the counts against the firmware's own `link` record, nothing dropped, and `result pass`.

With `--example NAME` it runs firmware/examples/NAME.rs instead (bench/mavlink_link.sh --example flow_sensor: the
template `flow_sensor`), which prints only `link bytes=N frame_clock_us=N` and exits with
success at the end of its recording. Its camera may lose a frame: a readout after one may
integrate several frame intervals (its flow then that many steps of the motion), and at least
one readout must be of quality 0. The counts are checked against its frame clock and bytes.

The last line is `heartbeat=N optical_flow_rad=N optical_flow=N crc_errors=N gaps=N`; the exit
status is non-zero when any check fails. Usage: bench/mavlink_link.py [--example NAME] (after
building the firmware; bench/mavlink_link.sh (with or without `--example NAME`) does both).
"""

import argparse
import math
import os
import re
import select
import socket
import subprocess
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
# A run takes about a second; far above that, far below CI's limit.
RUN_TIMEOUT = 120
FLOW_TOLERANCE_PX = 0.05
MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID = 30, 8


def scene():
    """The scene's constants from firmware/src/scene.rs, the firmware's own ground truth."""
    with open(os.path.join(FIRMWARE, "src", "scene.rs")) as f:
        text = f.read()

    def const(name):
        match = re.search(rf"pub const {name}: [^=]+= ([^;]+);", text)
        if not match:
            raise SystemExit(f"error: {name} not found in firmware/src/scene.rs")
        return match.group(1)

    motion = [int(v) for v in re.findall(r"-?\d+", const("MOTION_MILLIPX").replace("_", ""))]
    width = int(const("WIDTH"))
    fov = float(const("FIELD_OF_VIEW_DEGREES"))
    interval = int(const("FRAME_INTERVAL_US").replace("_", ""))
    focal = width / 2.0 / math.tan(math.radians(fov) / 2.0)
    return {
        "motion_px": (motion[0] / 1000.0, motion[1] / 1000.0),
        "tolerance": math.atan(FLOW_TOLERANCE_PX / focal),
        "focal": focal,
        "interval_us": interval,
    }


def run_firmware(server, example=None):
    """Runs the firmware (or its example) with USART2 on the server's port; returns (bytes,
    messages, log, status)."""
    port = server.getsockname()[1]
    target = ["--example", example] if example else []
    command = ["cargo", "run", "--release", "--quiet", *target, "--", "-serial", "null",
               "-serial", f"tcp:127.0.0.1:{port}", "-monitor", "none"]
    name = f"{example}_link.log" if example else "mavlink_link.log"
    log = open(os.path.join(FIRMWARE, "target", name), "w+")
    qemu = subprocess.Popen(command, cwd=FIRMWARE, stdin=subprocess.DEVNULL, stdout=log,
                            stderr=subprocess.STDOUT)
    deadline = time.monotonic() + RUN_TIMEOUT
    data = bytearray()
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    messages = []
    connection = None
    try:
        while time.monotonic() < deadline:
            sockets = [connection or server]
            ready, _, _ = select.select(sockets, [], [], 0.2)
            if not ready:
                if qemu.poll() is not None and connection is None:
                    break
                continue
            if connection is None:
                connection, _ = server.accept()
                continue
            chunk = connection.recv(65536)
            if not chunk:
                break
            data += chunk
            # Parsed live, as the bytes arrive.
            messages += parser.parse_buffer(chunk) or []
        else:
            print(f"error: no end of stream within {RUN_TIMEOUT} s", file=sys.stderr)
        try:
            status = qemu.wait(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            qemu.kill()
            status = "timeout"
    finally:
        if qemu.poll() is None:
            qemu.kill()
        if connection is not None:
            connection.close()
    log.seek(0)
    return bytes(data), messages, log.read(), status


def record(log, kind):
    for line in log.splitlines():
        words = line.split()
        if words and words[0] == kind:
            return dict(w.split("=", 1) for w in words[1:] if "=" in w)
    return None


class Checks:
    def __init__(self):
        self.problems = []
        # The largest distance of a reading from the motion, px at the principal point.
        self.worst_error_px = 0.0

    def expect(self, ok, what):
        if not ok and len(self.problems) < 1000:
            self.problems.append(what)


def check_rad(checks, m, truth, previous_time, lost_frames):
    """Checks one OPTICAL_FLOW_RAD; returns the frame intervals it integrates."""
    name = f"OPTICAL_FLOW_RAD seq {m.get_seq()}"
    steps, rest = divmod(m.integration_time_us, truth["interval_us"])
    checks.expect(rest == 0 and (steps == 1 or (lost_frames and steps > 1)),
                  f"{name}: integration_time_us {m.integration_time_us}")
    if previous_time is not None:
        checks.expect(m.time_usec == previous_time + truth["interval_us"],
                      f"{name}: time_usec {m.time_usec} after {previous_time}")
    gyro = (m.integrated_xgyro, m.integrated_ygyro, m.integrated_zgyro)
    checks.expect(all(math.isnan(g) for g in gyro), f"{name}: gyro {gyro} without a gyro")
    checks.expect(m.distance == -1.0, f"{name}: distance {m.distance}")
    flow = (m.integrated_x, m.integrated_y)
    checks.expect(all(math.isfinite(v) for v in flow), f"{name}: flow {flow}")
    if m.quality == 0:
        checks.expect(flow == (0.0, 0.0), f"{name}: flow {flow} at quality 0")
        return steps
    mx, my = truth["motion_px"]
    focal = truth["focal"]
    ex, ey = math.atan(steps * mx / focal), math.atan(steps * my / focal)
    tol = truth["tolerance"]
    near = [max(abs(flow[0] - s * ex), abs(flow[1] - s * ey)) for s in (1.0, -1.0)]
    checks.expect(min(near) <= tol,
                  f"{name}: flow {flow} rad, expected +-({ex:.6f}, {ey:.6f}) within {tol:.6f}")
    if all(math.isfinite(v) for v in flow):
        px = (focal * math.tan(flow[0]), focal * math.tan(flow[1]))
        error = min(max(abs(px[0] - s * steps * mx), abs(px[1] - s * steps * my))
                    for s in (1.0, -1.0))
        checks.worst_error_px = max(checks.worst_error_px, error)
    return steps


def check_flow(checks, m, rad, truth):
    name = f"OPTICAL_FLOW seq {m.get_seq()}"
    if rad is None:
        checks.expect(False, f"{name}: no OPTICAL_FLOW_RAD before it")
        return
    checks.expect((m.time_usec, m.quality, m.sensor_id) == (rad.time_usec, rad.quality,
                                                           rad.sensor_id),
                  f"{name}: time/quality/sensor {m.time_usec}/{m.quality}/{m.sensor_id}")
    checks.expect(m.ground_distance == -1.0, f"{name}: ground_distance {m.ground_distance}")
    seconds = rad.integration_time_us * 1e-6
    for axis in ("x", "y"):
        integrated = getattr(rad, f"integrated_{axis}")
        rate = getattr(m, f"flow_rate_{axis}")
        dpix = getattr(m, f"flow_{axis}")
        expected_rate = integrated / seconds if rad.quality else 0.0
        checks.expect(abs(rate - expected_rate) <= 1e-6 * max(1.0, abs(expected_rate)),
                      f"{name}: flow_rate_{axis} {rate}, expected {expected_rate}")
        expected_dpix = 10.0 * truth["focal"] * math.tan(integrated) if rad.quality else 0.0
        checks.expect(abs(dpix - expected_dpix) <= 0.5 + 1e-3,
                      f"{name}: flow_{axis} {dpix} dpix, expected {expected_dpix:.2f}")


def check_stream(messages, truth, lost_frames=False):
    checks = Checks()
    counts = {"HEARTBEAT": 0, "OPTICAL_FLOW_RAD": 0, "OPTICAL_FLOW": 0, "BAD_DATA": 0}
    gaps, expected_seq, rad, previous_time, invalid, spans = 0, 0, None, None, 0, 0
    heartbeat_due = False
    for m in messages:
        kind = m.get_type()
        counts[kind] = counts.get(kind, 0) + 1
        if kind == "BAD_DATA":
            continue
        if m.get_seq() != expected_seq:
            gaps += 1
            checks.expect(False, f"{kind}: sequence {m.get_seq()}, expected {expected_seq}")
        expected_seq = (m.get_seq() + 1) % 256
        checks.expect((m.get_srcSystem(), m.get_srcComponent()) == (1, 100),
                      f"{kind}: sender {m.get_srcSystem()}/{m.get_srcComponent()}")
        if kind == "HEARTBEAT":
            checks.expect((m.type, m.autopilot) == (MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID),
                          f"HEARTBEAT: type/autopilot {m.type}/{m.autopilot}")
            heartbeat_due = False
        elif kind == "OPTICAL_FLOW_RAD":
            second = m.time_usec // 1_000_000
            new_second = previous_time is None or second > previous_time // 1_000_000
            checks.expect(new_second == (counts["HEARTBEAT"] > 0 and not heartbeat_due),
                          f"OPTICAL_FLOW_RAD seq {m.get_seq()}: heartbeat missing or extra "
                          f"at {m.time_usec} us")
            spans += check_rad(checks, m, truth, previous_time, lost_frames) > 1
            invalid += m.quality == 0
            rad, previous_time, heartbeat_due = m, m.time_usec, True
        elif kind == "OPTICAL_FLOW":
            check_flow(checks, m, rad, truth)
            rad = None
        else:
            checks.expect(False, f"unexpected message {kind}")
    return checks, counts, gaps, invalid, spans


def check_example(checks, log, data, counts, invalid, spans, truth, example):
    """The example's counts against its `link` record: its bytes and its frame clock."""
    link = record(log, "link")
    if link is None:
        checks.expect(False, f"{example} printed no link record")
        return
    checks.expect(int(link["bytes"]) == len(data),
                  f"{len(data)} bytes received, {example} sent {link['bytes']}")
    clock_us = int(link["frame_clock_us"])
    readouts = clock_us // truth["interval_us"]
    checks.expect(counts["OPTICAL_FLOW_RAD"] == readouts == counts["OPTICAL_FLOW"],
                  f"{counts['OPTICAL_FLOW_RAD']} OPTICAL_FLOW_RAD and {counts['OPTICAL_FLOW']} "
                  f"OPTICAL_FLOW in {clock_us} us of frame clock, expected {readouts}")
    checks.expect(counts["HEARTBEAT"] == clock_us // 1_000_000 + 1,
                  f"{counts['HEARTBEAT']} heartbeats in {clock_us} us of frame clock")
    checks.expect(invalid >= 1, "no readout of quality 0: the bad frame was not reported")
    print(f"{example}: {readouts} readouts in {clock_us / 1e6} s of frame clock, "
          f"{link['bytes']} bytes; {invalid} of quality 0, {spans} over a lost frame")


def main():
    parser = argparse.ArgumentParser(description="Checks the firmware's MAVLink stream.")
    parser.add_argument("--example", help="run firmware/examples/EXAMPLE.rs instead")
    example = parser.parse_args().example
    truth = scene()
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        data, messages, log, status = run_firmware(server, example)
    checks, counts, gaps, invalid, spans = check_stream(messages, truth, example is not None)
    checks.expect(status == 0, f"the firmware failed (QEMU status {status})")
    checks.expect(len(data) > 0, "no bytes arrived from USART2")
    link = record(log, "link")
    if example:
        check_example(checks, log, data, counts, invalid, spans, truth, example)
    elif link is None:
        checks.expect(False, "the firmware printed no link record")
    else:
        checks.expect("result pass" in log, "the firmware did not report result pass")
        for key, kind in (("heartbeats", "HEARTBEAT"), ("optical_flow_rad", "OPTICAL_FLOW_RAD"),
                          ("optical_flow", "OPTICAL_FLOW")):
            checks.expect(int(link[key]) == counts[kind],
                          f"{kind}: {counts[kind]} received, the firmware sent {link[key]}")
        checks.expect(int(link["bytes"]) == len(data),
                      f"{len(data)} bytes received, the firmware sent {link['bytes']}")
        checks.expect(link["dropped"] == "0", f"the firmware dropped {link['dropped']} frames")
        checks.expect(int(link["invalid"]) == invalid,
                      f"{invalid} readouts of quality 0, the firmware sent {link['invalid']}")
        seconds = float(link["seconds"])
        checks.expect(counts["HEARTBEAT"] == math.floor(seconds) + 1,
                      f"{counts['HEARTBEAT']} heartbeats in {seconds} s of frame clock")
        print(f"firmware: {link['readouts']} readouts in {seconds} s of frame clock, "
              f"{link['bytes']} bytes; sending {link['instructions_per_frame']} instructions "
              f"per readout (worst {link['worst']})")
    print(f"flow: worst reading {checks.worst_error_px:.4f} px from the scene's motion "
          f"({truth['motion_px'][0]:+.3f}, {truth['motion_px'][1]:+.3f}) px per frame at the "
          f"principal point, tolerance {FLOW_TOLERANCE_PX} px")
    for problem in checks.problems[:20]:
        print(f"FAIL {problem}")
    if len(checks.problems) > 20:
        print(f"... and {len(checks.problems) - 20} more")
    print(f"heartbeat={counts['HEARTBEAT']} optical_flow_rad={counts['OPTICAL_FLOW_RAD']} "
          f"optical_flow={counts['OPTICAL_FLOW']} crc_errors={counts['BAD_DATA']} gaps={gaps}")
    return 1 if checks.problems or counts["BAD_DATA"] or gaps else 0


if __name__ == "__main__":
    sys.exit(main())
