"""Detection's pixel statistics computed on less data give the whole image's values, bit
for bit: grey-level percentiles from the histogram, the 99.5th percentile from the values
above a threshold, the blur of a box around the corners, and the edge width and corners of
a detection against the whole-image computation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from kinecal.vision import detect as det
from kinecal.vision.boards import parse_board
from kinecal.vision.pixels import blurred_around, percentiles_of_levels, upper_percentile
from kinecal.vision.render import ImageConditions, render_handeye_scene


def test_percentiles_of_grey_levels_are_numpys():
    rng = np.random.default_rng(0)
    for n in (16, 17, 1000, 54321, 200_000):
        for v in (rng.integers(0, 256, n), np.clip(rng.normal(120, 40, n), 0, 255).round()):
            counts = np.bincount(v.astype(int), minlength=256)
            got = percentiles_of_levels(counts, (2.0, 98.0))
            assert np.array_equal(got, np.percentile(v.astype(np.float32), [2.0, 98.0]))


def test_upper_percentile_is_numpys():
    rng = np.random.default_rng(1)
    for n in (20, 4095, 4096, 60_000, 250_000):
        for x in (rng.gamma(0.5, 20, n), rng.uniform(0, 100, n), rng.normal(0, 30, n).round()):
            x = x.astype(np.float32)
            assert upper_percentile(x, 99.5) == float(np.percentile(x, 99.5))


@pytest.fixture(scope="module")
def scene():
    K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
    board = parse_board("chessboard:9x6:20")
    sc = render_handeye_scene(board, K, np.array([-0.1, 0.03, 0, 0, 0]), (640, 480), 4,
                              conditions=ImageConditions(blur=0.8, noise=3.0), seed=4)
    return board, sc


def test_blur_of_a_box_is_the_whole_images_within_reach(scene):
    _, sc = scene
    img = sc.images[0]
    pts = np.array([[200.3, 150.8], [420.0, 300.5]])
    got = blurred_around(img, pts, 1.5, 20)
    full = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.5)
    for p in pts:
        x, y = np.round(p).astype(int)
        assert np.array_equal(got[y - 20:y + 21, x - 20:x + 21], full[y - 20:y + 21, x - 20:x + 21])


def test_detection_equals_the_whole_image_computation(scene, monkeypatch):
    board, sc = scene
    fast = [det.detect(im, board) for im in sc.images]
    for im, d in zip(sc.images, fast, strict=True):
        assert d.ok
        assert d.edge_width == det.edge_width(im, det._hull_mask(im.shape, d.corners, 1.15))
    monkeypatch.setattr(det, "blurred_around", lambda gray, pts, sigma, reach:
                        cv2.GaussianBlur(gray.astype(np.float32), (0, 0), sigma))
    for im, d in zip(sc.images, fast, strict=True):
        assert np.array_equal(det.detect(im, board).corners, d.corners)
