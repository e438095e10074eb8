"""dense_flow, flow_to_color, MotionDetector, estimate_motion and FlowSensor."""

import numpy as np
import pytest

import kestrel
from conftest import shifted, texture


def test_dense_flow_measures_a_known_shift():
    a = texture(3)
    b = shifted(a, 1.5, -0.75)
    flow, valid = kestrel.dense_flow(a, b)
    assert flow.shape == (30, 40, 2) and flow.dtype == np.float32
    assert valid.shape == (30, 40) and valid.dtype == bool
    # Measured: every node measured, 95 % within 0.028 px of the shift, all within 0.125 px.
    assert valid.mean() > 0.95
    err = np.abs(flow[valid] - np.float32([1.5, -0.75]))
    assert np.percentile(err, 95) < 0.06 and err.max() < 0.25
    full, known = kestrel.dense_flow(a, b, cell=16, full_resolution=True)
    assert full.shape == (240, 320, 2) and known.shape == (240, 320)
    assert np.abs(np.nanmedian(full.reshape(-1, 2), axis=0) - [1.5, -0.75]).max() < 0.02


def test_dense_flow_on_a_flat_frame_is_unknown():
    flat = np.full((120, 160), 50, np.uint8)
    flow, valid = kestrel.dense_flow(flat, flat)
    assert not valid.any() and np.isnan(flow).all()


def test_flow_to_color_uses_the_middlebury_wheel():
    flow = np.zeros((4, 4, 2), np.float32)
    flow[0, 0] = (1, 0)  # right: red
    flow[0, 1] = (-1, 0)  # left: cyan-blue
    flow[0, 2] = (0, 1)  # down: yellow-orange
    flow[1, 0] = np.nan  # unknown: black
    img = kestrel.flow_to_color(flow)
    assert img.shape == (4, 4, 3) and img.dtype == np.uint8
    assert img[0, 0].tolist()[:2] == [255, 0] and img[0, 0, 2] < 50
    assert img[0, 1, 0] == 0 and img[0, 1, 2] == 255
    assert img[0, 2, 0] == 255 and img[0, 2, 2] == 0
    assert img[1, 0].tolist() == [0, 0, 0]
    assert img[3, 3].tolist() == [255, 255, 255]  # at rest: white
    assert kestrel.flow_to_color(flow, bgr=True)[0, 0].tolist() == img[0, 0, ::-1].tolist()
    half = kestrel.flow_to_color(flow, max_speed=2.0)
    assert half[0, 0, 1] > 100  # half the full speed: paler red
    assert kestrel.flow_to_color(np.zeros((60, 80, 2), np.float32), legend=True).shape == (60, 80, 3)


def test_motion_detector_boxes_a_moving_square():
    bg, obj = texture(9), texture(10, 40, 40)

    def frame(k):
        f = shifted(bg, 0.5 * k, 0).copy()
        x = 60 + 4 * k
        f[100:140, x:x + 40] = obj
        return f

    detector = kestrel.MotionDetector()
    assert detector.push(frame(0)) is None
    results = [detector.push(frame(k)) for k in range(1, 6)]
    # Measured: one box from the second pair on (persistence of two pairs), about 42 x 42 px at
    # the square, moving 4.0 px right; the camera's pan 0.5 px.
    for k, r in enumerate(results[1:], start=2):
        assert r.boxes.shape == (1, 4) and r.boxes.dtype == np.int32
        x, y, w, h = r.boxes[0]
        square_x = 60 + 4 * (k - 1)
        assert abs(x - square_x) <= 6 and abs(y - 100) <= 4 and 36 <= w <= 50 and 36 <= h <= 50
        assert abs(r.box_flow[0, 0] - 4.0) < 0.3 and abs(r.box_flow[0, 1]) < 0.3
        assert abs(r.camera[0, 0] - 0.5) < 0.05


def test_estimate_motion_finds_the_shift_and_its_outliers():
    rng = np.random.default_rng(0)
    p0 = rng.uniform(20, 300, (50, 2)).astype(np.float32)
    p1 = p0 + np.float32([2.0, -1.0])
    p1[:5] += 10
    m = kestrel.estimate_motion(p0, p1, model="similarity")
    assert m.ok and m.status == "ok" and m.model == "similarity"
    assert m.inlier_count == 45 and m.inliers.tolist() == [False] * 5 + [True] * 45
    np.testing.assert_allclose(m.matrix, [[1, 0, 2], [0, 1, -1], [0, 0, 1]], atol=1e-3)
    few = kestrel.estimate_motion(p0[:2], p1[:2])
    assert not few.ok and few.status == "too_few_tracks" and few.quality == 0


def test_flow_sensor_reads_out_the_pan_and_encodes_mavlink():
    bg = texture(9)
    sensor = kestrel.FlowSensor(fov=1.0)
    pairs = []
    for k in range(6):
        frame = np.ascontiguousarray(shifted(bg, 1.0 * k, 0.5 * k)[60:180, 80:240])
        pairs.append(sensor.push(frame, 10_000))
    assert pairs[0] is None and all(p.ok for p in pairs[1:])
    r = sensor.readout(50_000)
    assert r.integration_time_us == 50_000 and r.quality > 0 and r.integrated_gyro is None
    # 5 px right and 2.5 px down over 5 frames, focal 80 / tan(0.5) = 146.4 px: flow about +X
    # for image motion to the right, about +Y for down (the library's sign conventions).
    # Measured 0.03420 and 0.01674 rad against 0.03414 and 0.01707: off by 0.00006 and 0.00033.
    focal = 80 / np.tan(0.5)
    assert abs(r.integrated_x - 5.0 / focal) < 0.0007
    assert abs(r.integrated_y - 2.5 / focal) < 0.0007
    frame = r.optical_flow_rad_mavlink(system_id=7, sequence=3)
    # MAVLink 2: magic, payload length, flags, sequence, system, component, message id 106.
    assert frame[0] == 0xFD and frame[4] == 3 and frame[5] == 7 and frame[6] == 100
    assert int.from_bytes(frame[7:10], "little") == 106 and len(frame) == 12 + frame[1]
    flow = r.optical_flow_mavlink()
    assert int.from_bytes(flow[7:10], "little") == 100
    assert int.from_bytes(kestrel.heartbeat_mavlink()[7:10], "little") == 0
    # The next readout starts a new integration.
    assert sensor.readout(60_000).integration_time_us == 0


def test_mavlink_frames_decode_with_pymavlink():
    mavlink = pytest.importorskip("pymavlink.dialects.v20.common")
    bg = texture(9)
    sensor = kestrel.FlowSensor(sensor_id=3)
    for k in range(3):
        sensor.push(np.ascontiguousarray(shifted(bg, 1.0 * k, 0.5 * k)[60:180, 80:240]), 10_000)
    r = sensor.readout(20_000)
    parser = mavlink.MAVLink(None)
    (rad,) = parser.parse_buffer(r.optical_flow_rad_mavlink(system_id=5, sequence=9))
    assert rad.get_type() == "OPTICAL_FLOW_RAD" and rad.get_srcSystem() == 5
    assert rad.get_seq() == 9 and rad.sensor_id == 3 and rad.quality == r.quality
    assert rad.integration_time_us == 20_000
    assert rad.integrated_x == pytest.approx(r.integrated_x) and rad.integrated_x > 0
    assert rad.integrated_y == pytest.approx(r.integrated_y) and rad.integrated_y > 0
    (flow,) = parser.parse_buffer(r.optical_flow_mavlink())
    assert flow.get_type() == "OPTICAL_FLOW" and flow.quality == r.quality
    assert (flow.flow_rate_x, flow.flow_rate_y) == pytest.approx(r.flow_rate)
    (beat,) = parser.parse_buffer(kestrel.heartbeat_mavlink())
    assert beat.get_type() == "HEARTBEAT" and beat.type == 30  # MAV_TYPE_CAMERA


def test_a_refused_frame_spoils_the_flow_sensors_reading():
    bg = texture(9)
    sensor = kestrel.FlowSensor(160, 120)
    for k in range(3):
        sensor.push(np.ascontiguousarray(shifted(bg, 1.0 * k, 0.0)[60:180, 80:240]), 10_000)
    assert sensor.tracker_report[0] == 25
    assert sensor.readout(20_000).quality > 0
    sensor.push(np.ascontiguousarray(shifted(bg, 3.0, 0.0)[60:180, 80:240]), 10_000)
    with pytest.raises(ValueError, match="frame is 320x240 but the sensor was made for 160x120"):
        sensor.push(bg, 10_000)
    r = sensor.readout(40_000)
    assert r.quality == 0 and r.integration_time_us == 20_000
    assert sensor.frames == 4
