"""Every kind of bad input is a Python exception with a message naming the problem."""

import numpy as np
import pytest

import kestrel
from conftest import shifted, texture

A = texture(11)
B = shifted(A, 1.0, 0.5)
PTS = np.float32([[[100, 100]], [[200, 120]]])


def lk(**kw):
    args = dict(prev=A, next=B, prev_pts=PTS)
    args.update(kw)
    return kestrel.calc_optical_flow_pyr_lk(**args)


LK_CASES = [
    # frames
    (dict(prev=A.astype(np.float32)), TypeError, "prev must be a uint8 array"),
    (dict(next=A.astype(np.int16)), TypeError, "next must be a uint8 array"),
    (dict(prev=A.tolist()), TypeError, "prev must be a numpy array"),
    (dict(prev=np.dstack([A, A, A])), ValueError, r"prev must be a 2-D array .* shape \(240, 320, 3\)"),
    (dict(prev=A[0]), ValueError, r"prev must be a 2-D array .* shape \(320,\)"),
    (dict(prev=A[:, ::2], next=B[:, ::2]), ValueError, r"prev has strides \(320, 2\)"),
    (dict(prev=A.T, next=B.T), ValueError, "prev has strides"),
    (dict(prev=A[::-1], next=B[::-1]), ValueError, r"prev has strides \(-320, 1\)"),
    (dict(prev=np.zeros((0, 5), np.uint8)), ValueError, "prev is empty"),
    (dict(prev=np.zeros((5000, 10), np.uint8)), ValueError, "at most 4096 px"),
    (dict(next=B[:200]), ValueError, "prev is 320x240 but next is 320x200"),
    # points
    (dict(prev_pts=np.zeros((0, 1, 2), np.float32)), ValueError, "prev_pts is empty"),
    (dict(prev_pts=np.float32([[[np.nan, 3]]])), ValueError, r"prev_pts\[0\] is \(NaN, 3\): points must be finite"),
    (dict(prev_pts=np.float32([[[1, 2]], [[np.inf, 3]]])), ValueError, r"prev_pts\[1\].*finite"),
    (dict(prev_pts=PTS.astype(np.float64)), TypeError, "prev_pts must be a float32 array"),
    (dict(prev_pts=np.float32([[1, 2, 3]])), ValueError, r"prev_pts must have shape \(N, 1, 2\) or \(N, 2\)"),
    (dict(prev_pts=[[100.0, 100.0]]), TypeError, "prev_pts must be a numpy array"),
    (dict(prev_pts=np.float32([[1e6, 2]])), ValueError, "within"),
    # settings
    (dict(win_size=(20, 20)), ValueError, "win_size must be odd and from 3 to 63 px: got 20"),
    (dict(win_size=(65, 65)), ValueError, "win_size must be odd and from 3 to 63 px: got 65"),
    (dict(win_size=(1, 1)), ValueError, "from 3 to 63"),
    (dict(win_size=(21, 15)), ValueError, r"win_size must be square .*\(21, 15\)"),
    (dict(win_size="big"), TypeError, "win_size must be a"),
    (dict(max_level=-1), ValueError, "max_level must be from 0 to 7: got -1"),
    (dict(max_level=8), ValueError, "max_level must be from 0 to 7: got 8"),
    (dict(max_level=5), ValueError, r"max_level 5 is too deep for a 320x240 frame with a 21 px window.*use max_level <= 4"),
    (dict(criteria=(3, 0, 0.01)), ValueError, "max_count must be at least 1"),
    (dict(criteria=(3, 30, -0.1)), ValueError, "epsilon must be a finite number >= 0"),
    (dict(criteria=(0, 30, 0.01)), ValueError, "criteria type"),
    (dict(criteria=30), TypeError, "criteria must be a"),
    (dict(flags=kestrel.OPTFLOW_LK_GET_MIN_EIGENVALS), ValueError, "OPTFLOW_LK_GET_MIN_EIGENVALS"),
    (dict(flags=1), ValueError, "flags must be 0 or OPTFLOW_USE_INITIAL_FLOW"),
    (dict(flags=kestrel.OPTFLOW_USE_INITIAL_FLOW), ValueError, "next_pts is None"),
    (dict(flags=4, next_pts=PTS[:1]), ValueError, "next_pts has 1 points but prev_pts has 2"),
    (dict(min_eig_threshold=-1e-4), ValueError, "min_eig_threshold must be a finite number >= 0"),
    (dict(min_eig_threshold=float("nan")), ValueError, "min_eig_threshold"),
    (dict(illumination="auto"), ValueError, "illumination must be 'gain_bias' or 'plain'"),
]


@pytest.mark.parametrize("kwargs, error, message", LK_CASES)
def test_lk_refuses(kwargs, error, message):
    with pytest.raises(error, match=message):
        lk(**kwargs)


def test_a_tiny_frame_refuses_a_large_window():
    tiny = np.full((8, 8), 7, np.uint8)
    with pytest.raises(ValueError, match="21 px window is too large for a 8x8 frame"):
        kestrel.calc_optical_flow_pyr_lk(tiny, tiny, PTS, max_level=0)


DETECT_CASES = [
    (lambda: kestrel.good_features_to_track(A.astype(float), 10, 0.01, 5), TypeError, "image must be a uint8 array"),
    (lambda: kestrel.good_features_to_track(A, 10, 1.5, 5), ValueError, "quality_level must be from 0 to 1"),
    (lambda: kestrel.good_features_to_track(A, 10, -0.1, 5), ValueError, "quality_level"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, -3), ValueError, "min_distance must be a whole number"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 7.5), ValueError, "min_distance must be a whole number.*7.5"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, block_size=4), ValueError, "block_size must be odd and from 3 to 7: got 4"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, block_size=9), ValueError, "block_size"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, use_harris_detector=True), ValueError, "Harris"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, mask=np.ones((10, 10), np.uint8)), ValueError, "mask has shape"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, mask=np.eye(240, 320, dtype=np.uint8)), ValueError, "mask must select one rectangle"),
    (lambda: kestrel.good_features_to_track(A, 10, 0.01, 5, mask=np.ones((240, 320), bool)), TypeError, "mask must be a uint8 array"),
    (lambda: kestrel.fast(A, threshold=300), ValueError, "threshold must be from 0 to 255: got 300"),
    (lambda: kestrel.fast(A, threshold=-1), ValueError, "threshold must be from 0 to 255"),
    (lambda: kestrel.fast(A, max_keypoints=0), ValueError, "max_keypoints must be at least 1"),
    (lambda: kestrel.fast(A[:, ::3]), ValueError, "image has strides"),
]


@pytest.mark.parametrize("call, error, message", DETECT_CASES)
def test_detectors_refuse(call, error, message):
    with pytest.raises(error, match=message):
        call()


OTHER_CASES = [
    (lambda: kestrel.dense_flow(A, B[:, :300]), ValueError, "prev is 320x240 but next is 300x240"),
    (lambda: kestrel.dense_flow(A, B, cell=0), ValueError, "cell must be from 1 px"),
    (lambda: kestrel.dense_flow(A, B, cell=500), ValueError, "cell must be from 1 px to the frame's smaller side"),
    (lambda: kestrel.dense_flow(A, B, window=8), ValueError, "window must be odd"),
    (lambda: kestrel.dense_flow(A, B, max_residual=-1.0), ValueError, "max_residual must be a finite number >= 0"),
    (lambda: kestrel.dense_flow(A, B, fill_passes=300), ValueError, "fill_passes must be 0 to 255"),
    (lambda: kestrel.flow_to_color(np.zeros((4, 4, 3), np.float32)), ValueError, r"flow must have shape \(H, W, 2\)"),
    (lambda: kestrel.flow_to_color(np.zeros((4, 4, 2), np.float64)), TypeError, "flow must be a float32 array"),
    (lambda: kestrel.flow_to_color(np.zeros((4, 4, 2), np.float32), max_speed=-1), ValueError, "max_speed must be a finite number > 0"),
    (lambda: kestrel.Tracker(320), ValueError, "give both width and height"),
    (lambda: kestrel.Tracker(0, 10), ValueError, "width and height must be 1 to 4096 px"),
    (lambda: kestrel.Tracker(max_tracks=0), ValueError, "max_tracks must be 1 to 1000: got 0"),
    (lambda: kestrel.Tracker(max_tracks=5000), ValueError, "max_tracks must be 1 to 1000"),
    (lambda: kestrel.Tracker(preset="drone"), ValueError, "preset must be None or 'flow_sensor'"),
    (lambda: kestrel.Tracker(window=4), ValueError, "window must be odd"),
    (lambda: kestrel.Tracker(fb_threshold=-1.0), ValueError, "fb_threshold must be a finite number >= 0"),
    (lambda: kestrel.Tracker(min_correlation=2.0), ValueError, "min_correlation must be from -1 to 1"),
    (lambda: kestrel.Tracker(least_correlation=float("nan")), ValueError, "least_correlation must be from -1 to 1"),
    (lambda: kestrel.Tracker(refill_cooldown=-1), ValueError, "refill_cooldown must be 0 to 65535 frames: got -1"),
    (lambda: kestrel.Tracker(refill_cooldown=65536), ValueError, "refill_cooldown must be 0 to 65535"),
    (lambda: kestrel.Tracker(revive_within=-1), ValueError, "revive_within must be 0 to 65535 frames: got -1"),
    (lambda: kestrel.Tracker(max_tracks=40, refill_below=41), ValueError, "refill_below must be 0 to max_tracks, 40: got 41"),
    (lambda: kestrel.Tracker(preset="flow_sensor", refill_below=30), ValueError, "refill_below must be 0 to max_tracks, 25: got 30"),
    (lambda: kestrel.Tracker(leaving_within=70000), ValueError, "leaving_within must be 0 to 65535 frames: got 70000"),
    (lambda: kestrel.MotionDetector(persist_pairs=0), ValueError, "persist_pairs must be 1 to 255"),
    (lambda: kestrel.estimate_motion(np.float32([[0, 0]]), np.float32([[1, 1], [2, 2]])), ValueError, "prev_pts has 1 points but next_pts has 2"),
    (lambda: kestrel.estimate_motion(PTS, PTS, model="projective"), ValueError, "model must be"),
    (lambda: kestrel.estimate_motion(PTS, PTS, threshold=-1.0), ValueError, "RANSAC settings"),
    (lambda: kestrel.FlowSensor(fov=4.0), ValueError, "fov must be"),
    (lambda: kestrel.FlowSensor(sensor_id=256), ValueError, "sensor_id must be 0 to 255"),
    (lambda: kestrel.FlowSensor().readout(0), ValueError, "no frame yet"),
    (lambda: kestrel.FlowSensor().push(A, 0), ValueError, "interval_us must be 1 to 1000000: got 0"),
    (lambda: kestrel.FlowSensor().push(A, 1000, gyro=(float("nan"), 0, 0)), ValueError, "gyro must be three finite numbers"),
    (lambda: kestrel.heartbeat_mavlink(system_id=300), ValueError, "system_id must be 0 to 255"),
]


@pytest.mark.parametrize("call, error, message", OTHER_CASES)
def test_the_rest_refuses(call, error, message):
    with pytest.raises(error, match=message):
        call()


def test_frames_of_another_size_are_refused_by_stateful_objects():
    tracker = kestrel.Tracker()
    tracker.process(A)
    with pytest.raises(ValueError, match="frame is 160x120 but the tracker was made for 320x240 frames"):
        tracker.process(A[:120, :160])
    detector = kestrel.MotionDetector(320, 240)
    with pytest.raises(ValueError, match="but the detector was made for 320x240"):
        detector.push(A[:100])
    sensor = kestrel.FlowSensor(320, 240)
    with pytest.raises(ValueError, match="but the sensor was made for 320x240"):
        sensor.push(A[:100], 1000)
