"""Same images, same bits: the camera path's results do not depend on threads.

``cv2.calibrateCamera`` on OpenCV's default worker threads returned intrinsics differing
in the last digits from call to call on the same corners, so ``calibrate --images`` and
``handeye-images`` without ``--intrinsics`` wrote different JSON on identical runs
(`kinecal.vision.opencv_one_thread`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

import kinecal
from kinecal.cli import main
from kinecal.vision import opencv_one_thread
from kinecal.vision.boards import parse_board
from kinecal.vision.detect import detect
from kinecal.vision.intrinsics import CameraIntrinsics, estimate_intrinsics, write_intrinsics
from kinecal.vision.render import ImageConditions, render_handeye_scene, write_scene

from .conftest import DIST, SIZE, K

SPEC = "chessboard:9x6:20"
SRC = str(Path(kinecal.__file__).parents[1])


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    board = parse_board(SPEC)
    sc = render_handeye_scene(board, K, DIST, SIZE, 8,
                              conditions=ImageConditions(blur=0.7, noise=2.0), seed=21,
                              supersample=2)
    return board, sc, write_scene(sc, tmp_path_factory.mktemp("he") / "scene")


def test_estimated_intrinsics_same_bits_every_call(scene):
    board, sc, _ = scene
    dets = [detect(im, board) for im in sc.images]
    assert all(d.ok for d in dets)
    obj = [d.object_points(board) for d in dets]
    pix = [d.corners for d in dets]
    before = cv2.getNumThreads()
    first = estimate_intrinsics(obj, pix, SIZE)
    assert abs(first.K[0, 0] - K[0, 0]) < 2.0  # a real calibration, not a degenerate one
    for _ in range(30):  # on OpenCV's threads one call in 3-10 differed
        again = estimate_intrinsics(obj, pix, SIZE)
        assert again.K.tobytes() == first.K.tobytes()
        assert again.dist.tobytes() == first.dist.tobytes()
        assert again.rms_px == first.rms_px
    assert cv2.getNumThreads() == before  # the caller's setting is back


def test_one_thread_blocks_nest_and_restore():
    before = cv2.getNumThreads()
    with opencv_one_thread():
        with opencv_one_thread():
            assert cv2.getNumThreads() == 1
        assert cv2.getNumThreads() == 1
    assert cv2.getNumThreads() == before


def _run_twice(argv: list[str], out: Path) -> tuple[bytes, bytes]:
    env = {**os.environ, "PYTHONPATH": SRC, "SOURCE_DATE_EPOCH": "1700000000"}
    got = []
    for _ in range(2):
        p = subprocess.run([sys.executable, "-m", "kinecal", *argv], capture_output=True,
                           text=True, env=env, timeout=300)
        assert p.returncode == 0, p.stderr
        got.append(out.read_bytes())
    return got[0], got[1]


def test_handeye_images_same_bytes_in_two_processes(scene, tmp_path):
    """Intrinsics estimated from the images (the calibrateCamera path) and refined."""
    folder = scene[2]
    out = tmp_path / "x.json"
    a, b = _run_twice(["handeye-images", str(folder / "images"),
                       str(folder / "robot_poses.csv"), "--board", SPEC, "--out", str(out),
                       "--quiet"], out)
    assert b"estimated from 8 images" in a
    assert a == b


def test_calibrate_images_same_bytes_in_two_processes(tmp_path):
    d = tmp_path
    write_intrinsics(d / "cam.yaml", CameraIntrinsics(K, DIST, SIZE))
    assert main(["simulate", "kr6-craig", "--images", str(d / "images"), "--board", SPEC,
                 "--poses", "8", "--home", "0,15,15,0,60,0", "--seed", "5", "--noise", "2",
                 "--blur", "0.7", "--intrinsics", str(d / "cam.yaml"),
                 "--out", str(d / "stations.csv"), "--quiet"]) == 0
    out = d / "r.json"
    a, b = _run_twice(["calibrate", "kr6-craig", str(d / "stations.csv"), "--images",
                       str(d / "images"), "--board", SPEC, "--out", str(out), "--quiet"], out)
    assert b'"kind": "camera"' in a and b"estimated from 8 images" in a
    assert a == b
