#!/usr/bin/env python3
"""Decodes `host-sim egomotion --mavlink` output with a real MAVLink parser (pymavlink).

For seeded synthetic flights written by `host-sim synth-sequence`, runs `host-sim egomotion
--mavlink` and parses the frames with pymavlink's MAVLink 2 common dialect, checking every frame:
the order (a HEARTBEAT at each new second of the frame clock, then OPTICAL_FLOW_RAD and
OPTICAL_FLOW per pair), the CRC (by pymavlink and recomputed here with CRC_EXTRA 50, 138 and
175), sender and one sequence without gaps, the timestamps and integration time of the frame
clock, and that the fields equal what ego.csv says (quality, integrated_x/y, zero flow at quality
0) and the gyro log implies (integrated gyro, NaN without a gyro); OPTICAL_FLOW must carry the
same flow as rates (rad/s) and deci-pixels, and HEARTBEAT a camera that is not an autopilot.

The same checks run on a live stream: `--mavlink udp:127.0.0.1:PORT --rate R` to a pymavlink
`udpin` listener, whose messages are checked against the ego.csv of the same run; and a listener
that starts late must see a gap-free tail of the stream while host-sim succeeds.

Each frame is one case; the last line is `N passed, M failed`, and the exit status is non-zero
on any failure.

Needs: python3 with pymavlink (pip install pymavlink).
Usage: tests/mavlink_decode.py [--no-build]
"""

import argparse
import csv
import math
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402
from pymavlink.generator.mavcrc import x25crc  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HOST_SIM = os.path.join(ROOT, "target", "release", "host-sim")
FPS = 30.0
SYSTEM_ID, COMPONENT_ID = 1, 100
# The focal length of a 60 degree horizontal field of view at 160 px (host-sim's default).
FOCAL_160 = 80.0 / math.tan(math.radians(30.0))
CRC_EXTRA = {0: 50, 100: 175, 106: 138}
MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID, MAV_STATE_ACTIVE = 30, 8, 4


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


def message_id(frame):
    return frame[7] | frame[8] << 8 | frame[9] << 16


def crc_is_valid(frame):
    crc = x25crc(frame[1:-2])
    crc.accumulate([CRC_EXTRA.get(message_id(frame), 0)])
    return crc.crc == struct.unpack("<H", frame[-2:])[0]


def expected_layout(pairs):
    """The message ids of a run of `pairs` frame pairs: a HEARTBEAT before the first pair and
    before each pair that starts a new second of the frame clock, then 106 and 100."""
    ids, next_heartbeat = [], 0
    for k in range(1, pairs + 1):
        if frame_time_us(k) >= next_heartbeat:
            ids.append((0, k))
            next_heartbeat = (frame_time_us(k) // 1_000_000 + 1) * 1_000_000
        ids += [(106, k), (100, k)]
    return ids


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


def check_envelope(expect, index, frame, message, msg_id):
    """The checks every frame gets: magic, CRC, id, sequence, sender."""
    expect(frame[0] == 0xFD, f"magic {frame[0]:#x}, not MAVLink 2")
    expect(crc_is_valid(frame), "CRC does not match")
    expect(message.get_msgId() == msg_id, f"message id {message.get_msgId()}, expected {msg_id}")
    expect(message.get_seq() == index % 256, f"sequence {message.get_seq()}, expected {index % 256}")
    expect((message.get_srcSystem(), message.get_srcComponent()) == (SYSTEM_ID, COMPONENT_ID),
           f"sender {message.get_srcSystem()}/{message.get_srcComponent()}")


def problems_collector():
    problems = []

    def expect(ok, what):
        if not ok:
            problems.append(what)

    return problems, expect


def check_heartbeat(index, frame, message):
    problems, expect = problems_collector()
    check_envelope(expect, index, frame, message, 0)
    expect(message.get_type() == "HEARTBEAT", f"type {message.get_type()}")
    expect((message.type, message.autopilot) == (MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID),
           f"type/autopilot {message.type}/{message.autopilot}")
    expect(message.system_status == MAV_STATE_ACTIVE, f"state {message.system_status}")
    expect(message.mavlink_version == 3, f"mavlink_version {message.mavlink_version}")
    return problems


def check_optical_flow(index, frame, message, rad, focal):
    """OPTICAL_FLOW must carry OPTICAL_FLOW_RAD's flow (`rad`, the message before it)."""
    problems, expect = problems_collector()
    check_envelope(expect, index, frame, message, 100)
    expect(message.get_type() == "OPTICAL_FLOW", f"type {message.get_type()}")
    expect(message.time_usec == rad.time_usec, f"time_usec {message.time_usec}")
    expect(message.sensor_id == rad.sensor_id, f"sensor_id {message.sensor_id}")
    expect(message.quality == rad.quality,
           f"quality {message.quality}, OPTICAL_FLOW_RAD says {rad.quality}")
    values = [message.flow_rate_x, message.flow_rate_y, message.flow_comp_m_x,
              message.flow_comp_m_y, message.ground_distance]
    expect(all(math.isfinite(v) for v in values), f"not finite: {values}")
    seconds = rad.integration_time_us * 1e-6
    for axis in ("x", "y"):
        integrated = getattr(rad, f"integrated_{axis}")
        rate = getattr(message, f"flow_rate_{axis}")
        dpix = getattr(message, f"flow_{axis}")
        if rad.quality == 0:
            expect(rate == 0.0 and dpix == 0, f"flow_{axis} {dpix}, rate {rate} at quality 0")
            continue
        expected_rate = integrated / seconds
        expect(abs(rate - expected_rate) <= 1e-6 * max(1.0, abs(expected_rate)),
               f"flow_rate_{axis} {rate}, expected {expected_rate}")
        expected_dpix = 10.0 * focal * math.tan(integrated)
        expect(abs(dpix - expected_dpix) <= 0.5 + 1e-3,
               f"flow_{axis} {dpix} dpix, expected {expected_dpix:.3f}")
    # No distance is known on the host: no speed, and the distance is "unknown".
    expect(message.ground_distance == -1.0, f"ground_distance {message.ground_distance}")
    expect((message.flow_comp_m_x, message.flow_comp_m_y) == (0.0, 0.0),
           f"flow_comp_m {message.flow_comp_m_x}, {message.flow_comp_m_y}")
    return problems


def check_frame(k, index, frame, message, row, gyro):
    """Problems with OPTICAL_FLOW_RAD frame `index` (of frame pair ending at frame `k`)."""
    problems, expect = problems_collector()
    check_envelope(expect, index, frame, message, 106)
    expect(message.get_type() == "OPTICAL_FLOW_RAD", f"type {message.get_type()}")
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


def check_stream(checks, name, rows, data, gyro_rows, focal=FOCAL_160, first_sequence=0,
                 layout=None):
    """Checks a byte stream against ego.csv's `rows`; `layout` (message id, pair) defaults to
    the whole run's."""
    frames = frames_of(data)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = False
    messages = parser.parse_buffer(data) or []
    layout = expected_layout(len(rows)) if layout is None else layout
    checks.case(f"{name}: a heartbeat each second, two messages per pair",
                [] if len(frames) == len(messages) == len(layout) > 0 and
                [message_id(f) for f in frames] == [i for i, _ in layout] else
                [f"{len(frames)} frames, {len(messages)} decoded, {len(rows)} rows in ego.csv, "
                 f"ids {[message_id(f) for f in frames][:8]}..."])
    rad = None
    for offset, (frame, message, (msg_id, k)) in enumerate(zip(frames, messages, layout)):
        index = first_sequence + offset
        if message_id(frame) != msg_id:
            break
        if msg_id == 0:
            checks.case(f"{name}: heartbeat before pair {k}", check_heartbeat(index, frame, message))
        elif msg_id == 106:
            gyro = gyro_integral(gyro_rows, k) if gyro_rows is not None else None
            rad = message
            checks.case(f"{name}: OPTICAL_FLOW_RAD {k}",
                        check_frame(k, index, frame, message, rows[k - 1], gyro))
        elif rad is not None:
            checks.case(f"{name}: OPTICAL_FLOW {k}",
                        check_optical_flow(index, frame, message, rad, focal))
    return frames


def check_run(checks, name, ego_csv, mavlink_bin, gyro_rows):
    with open(mavlink_bin, "rb") as f:
        data = f.read()
    return check_stream(checks, name, read_csv(ego_csv), data, gyro_rows)


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


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def receive(connection, process, quiet_after=1.0, limit=30.0):
    """Every message the listener gets until host-sim has exited and the link has been quiet
    for `quiet_after` s (at most `limit` s in all): their frames, back to back."""
    data, deadline, last = bytearray(), time.monotonic() + limit, time.monotonic()
    while time.monotonic() < deadline:
        message = connection.recv_match(blocking=True, timeout=0.1)
        if message is not None:
            data += message.get_msgbuf()
            last = time.monotonic()
        elif process.poll() is not None and time.monotonic() - last > quiet_after:
            break
    return bytes(data)


def run_live(directory, port, rate, tag):
    ego_csv = os.path.join(directory, f"{tag}.csv")
    args = [HOST_SIM, "egomotion", os.path.join(directory, "frames"), "--out", ego_csv,
            "--mavlink", f"udp:127.0.0.1:{port}", "--rate", str(rate)]
    return ego_csv, subprocess.Popen(args, cwd=ROOT, stderr=subprocess.PIPE)


def live_udp(checks, directory):
    """A listener up before host-sim starts must get every message, in order, intact."""
    port = free_udp_port()
    connection = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="common")
    try:
        ego_csv, process = run_live(directory, port, 120, "live")
        data = receive(connection, process)
        _, stderr = process.communicate(timeout=30)
        checks.case("udp: host-sim succeeds quietly",
                    [] if process.returncode == 0 and not stderr else
                    [f"exit {process.returncode}: {stderr.decode(errors='replace')}"])
        check_stream(checks, "udp", read_csv(ego_csv), data, None)
        errors = connection.mav.total_receive_errors
        checks.case("udp: no bad data at the listener",
                    [] if errors == 0 else [f"{errors} receive errors"])
    finally:
        connection.close()


def late_listener(checks, directory):
    """A listener that starts 0.2 s into a 30 Hz run costs host-sim nothing and sees a
    gap-free tail of the stream."""
    port = free_udp_port()
    ego_csv, process = run_live(directory, port, 30, "late")
    time.sleep(0.2)
    connection = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="common")
    try:
        data = receive(connection, process)
        process.communicate(timeout=30)
    finally:
        connection.close()
    frames = frames_of(data)
    layout = expected_layout(len(read_csv(ego_csv)))
    problems = [] if process.returncode == 0 else [f"exit {process.returncode}"]
    if not frames:
        problems.append("nothing received")
    else:
        first = frames[0][4]
        # The run is shorter than 256 frames: the sequence is the index in the layout.
        tail = layout[first:]
        problems += [] if len(tail) == len(frames) else [
            f"{len(frames)} messages from sequence {first}, expected {len(tail)}"]
        if not problems:
            check_stream(checks, "late listener", read_csv(ego_csv), data, None,
                         first_sequence=first, layout=tail)
    checks.case("late listener: host-sim succeeds, the tail has no gap", problems)


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
        corrupted = bytearray(frames[1])
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

        # More than 256 frames (and 8 seconds of heartbeats): the sequence number wraps.
        long_flight = flight(scratch, "long", "shake", 260, (64, 48))
        ego_csv, mavlink_bin = egomotion(long_flight)
        check_stream(checks, "260 frames", read_csv(ego_csv), open(mavlink_bin, "rb").read(),
                     None, focal=32.0 / math.tan(math.radians(30.0)))

        # Live: the perspective flight over UDP to a pymavlink listener, paced at 120 Hz.
        live_udp(checks, perspective)
        late_listener(checks, perspective)

    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
