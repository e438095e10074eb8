"""good_features_to_track and fast against OpenCV's detectors."""

import cv2
import numpy as np
import pytest

import kestrel
from conftest import texture


def pixels(points):
    return {(int(round(x)), int(round(y))) for x, y in points.reshape(-1, 2)}


# Measured on texture(3): 292 of the 300 corners in common (97.3 %) with maxCorners 300, 435 of
# 447 / 451 with no limit at quality 0.05 and distance 10; the bound allows twice the misses.
def test_good_features_match_opencv():
    a = texture(3)
    mine = kestrel.good_features_to_track(a, 300, 0.01, 7)
    theirs = cv2.goodFeaturesToTrack(a, 300, 0.01, 7)
    assert mine.shape == theirs.shape == (300, 1, 2) and mine.dtype == theirs.dtype
    assert len(pixels(mine) & pixels(theirs)) >= 284
    mine = kestrel.good_features_to_track(a, 0, 0.05, 10)
    theirs = cv2.goodFeaturesToTrack(a, 0, 0.05, 10)
    assert abs(len(mine) - len(theirs)) <= 10
    assert len(pixels(mine) & pixels(theirs)) >= 0.94 * len(theirs)
    # Strongest first, and spaced by the minimum distance.
    d = np.linalg.norm(mine[:, None, 0] - mine[None, :, 0], axis=-1)
    assert d[~np.eye(len(mine), dtype=bool)].min() >= 10


def test_good_features_in_a_rectangular_mask():
    a = texture(4)
    mask = np.zeros_like(a)
    mask[50:150, 100:220] = 255
    pts = kestrel.good_features_to_track(a, 100, 0.01, 5, mask=mask).reshape(-1, 2)
    assert len(pts) > 10
    assert pts[:, 0].min() >= 100 and pts[:, 0].max() < 220
    assert pts[:, 1].min() >= 50 and pts[:, 1].max() < 150
    empty = kestrel.good_features_to_track(a, 100, 0.01, 5, mask=np.zeros_like(a))
    assert empty.shape == (0, 1, 2)


def test_a_flat_frame_has_no_corners():
    flat = np.full((120, 160), 90, np.uint8)
    assert kestrel.good_features_to_track(flat, 50, 0.01, 5).shape == (0, 1, 2)
    assert kestrel.fast(flat).shape == (0, 2)


# Measured on texture(3): the same corners as cv2.FastFeatureDetector (TYPE_9_16) at thresholds
# 10 and 20, with and without non-maximum suppression (2,302 / 28,440 / 1,604 / 12,178).
@pytest.mark.parametrize("threshold", [10, 20])
@pytest.mark.parametrize("nonmax", [True, False])
def test_fast_matches_opencv(threshold, nonmax):
    a = texture(3)
    det = cv2.FastFeatureDetector_create(
        threshold=threshold, nonmaxSuppression=nonmax, type=cv2.FAST_FEATURE_DETECTOR_TYPE_9_16
    )
    theirs = {(int(k.pt[0]), int(k.pt[1])) for k in det.detect(a)}
    mine = kestrel.fast(a, threshold=threshold, nonmax_suppression=nonmax)
    assert mine.dtype == np.float32 and mine.shape[1] == 2
    assert pixels(mine) == theirs


def test_fast_scores_are_strongest_first():
    a = texture(3)
    pts, scores = kestrel.fast(a, max_keypoints=50, return_scores=True)
    assert pts.shape == (50, 2) and scores.shape == (50,) and scores.dtype == np.uint32
    assert np.all(np.diff(scores.astype(np.int64)) <= 0)
    assert scores.min() >= 10
