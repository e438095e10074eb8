"""Seeded frame pairs shared by the tests: smoothed noise shifted by a known sub-pixel amount."""

import cv2
import numpy as np
import pytest

W, H = 320, 240


def texture(seed, w=W, h=H, sigma=2.0):
    """Gaussian-smoothed uniform noise stretched to 0..255 (uint8, seeded)."""
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur((rng.random((h, w)) * 255).astype(np.float32), (0, 0), sigma)
    return cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)


def shifted(img, dx, dy):
    """`img` moved by (dx, dy) px with bilinear interpolation: a point p goes to p + (dx, dy)."""
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(
        img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
    )


def inner(points, margin=15, w=W, h=H):
    """The points at least `margin` px inside the frame (the reflected border does not move)."""
    p = points.reshape(-1, 2)
    keep = (p[:, 0] > margin) & (p[:, 0] < w - margin) & (p[:, 1] > margin) & (p[:, 1] < h - margin)
    return points[keep]


@pytest.fixture(scope="session")
def pairs():
    """Eight seeded pairs with shifts drawn from (-2.5, 2.5) px: (prev, next, (dx, dy))."""
    out = []
    for seed in range(8):
        dx, dy = np.random.default_rng(100 + seed).uniform(-2.5, 2.5, 2)
        a = texture(seed)
        out.append((a, shifted(a, dx, dy), (float(dx), float(dy))))
    return out
