"""Intrinsics files (ROS YAML, OpenCV FileStorage YAML/XML, JSON), estimation, PnP pose and
its covariance."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye.camera import project
from kinecal.spatial import matrix_from_axis_angle, transform_from
from kinecal.vision.boards import Chessboard
from kinecal.vision.intrinsics import (
    CameraIntrinsics,
    estimate_intrinsics,
    read_intrinsics,
    write_intrinsics,
)
from kinecal.vision.pnp import board_pose
from kinecal.vision.render import plan_views

ROS = """image_width: 480
image_height: 360
camera_name: wrist
camera_matrix:
  rows: 3
  cols: 3
  data: [700.0, 0.0, 239.5, 0.0, 701.0, 179.5, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.12, 0.04, 0.0005, -0.0003, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


def _check(intr):
    assert np.allclose(intr.K, [[700, 0, 239.5], [0, 701, 179.5], [0, 0, 1]])
    assert np.allclose(intr.dist[:5], [-0.12, 0.04, 0.0005, -0.0003, 0.0])
    assert intr.size == (480, 360)


def test_read_ros_yaml_and_round_trip(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text(ROS)
    intr = read_intrinsics(p)
    _check(intr)
    q = tmp_path / "out.yaml"
    write_intrinsics(q, intr)
    _check(read_intrinsics(q))


@pytest.mark.parametrize("suffix", [".yml", ".xml"])
def test_read_opencv_filestorage(tmp_path, suffix):
    p = tmp_path / f"calib{suffix}"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 480)
    fs.write("image_height", 360)
    fs.write("camera_matrix", np.array([[700, 0, 239.5], [0, 701, 179.5], [0, 0, 1.0]]))
    fs.write("distortion_coefficients", np.array([[-0.12, 0.04, 0.0005, -0.0003, 0.0]]))
    fs.release()
    _check(read_intrinsics(p))


def test_read_json(tmp_path):
    p = tmp_path / "cam.json"
    p.write_text(json.dumps({"image_width": 480, "image_height": 360,
                             "camera_matrix": [[700, 0, 239.5], [0, 701, 179.5], [0, 0, 1]],
                             "distortion_coefficients": [-0.12, 0.04, 0.0005, -0.0003, 0.0]}))
    _check(read_intrinsics(p))


@pytest.mark.parametrize("text,match", [
    ("image_width: 10\n", "no camera matrix"),
    (ROS.replace("plumb_bob", "equidistant"), "fisheye"),
    (ROS.replace("data: [700.0, 0.0, 239.5, 0.0, 701.0, 179.5, 0.0, 0.0, 1.0]",
                 "data: [700.0, 0.0, 239.5]"), "camera_matrix"),
    ("camera_matrix: [[1, 2], [3, 4]]\n", "expected 9"),
    ("- a\n- b\n", "mapping"),
])
def test_bad_intrinsics_files(tmp_path, text, match):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(InputError, match=match):
        read_intrinsics(p)
    with pytest.raises(InputError, match="not found"):
        read_intrinsics(tmp_path / "missing.yaml")


def test_estimate_intrinsics_recovers_the_camera(camera):
    K, dist, size = camera
    board = Chessboard(9, 6, 20.0)
    rng = np.random.default_rng(0)
    obj, img = [], []
    for T in plan_views(board, K, dist, size, 12, rng=1):
        uv = project(K, dist, board.object_points @ T[:3, :3].T + T[:3, 3])
        obj.append(board.object_points)
        img.append(uv + rng.normal(scale=0.05, size=uv.shape))
    intr = estimate_intrinsics(obj, img, size)
    assert isinstance(intr, CameraIntrinsics)
    assert abs(intr.rms_px - 0.05 * np.sqrt(2)) < 0.02 and len(intr.per_view_rms) == 12
    assert np.abs(intr.K - K).max() < 3.0 and abs(intr.dist[0] - dist[0]) < 0.02
    with pytest.raises(InputError, match="at least 3"):
        estimate_intrinsics(obj[:2], img[:2], size)


def test_pnp_recovers_pose_and_its_covariance_is_right(camera):
    """Monte Carlo: the spread of the PnP pose over noise draws matches its covariance."""
    K, dist, size = camera
    board = Chessboard(9, 6, 20.0)
    T = plan_views(board, K, dist, size, 1, rng=7)[0]
    uv = project(K, dist, board.object_points @ T[:3, :3].T + T[:3, 3])
    exact = board_pose(board.object_points, uv, K, dist)
    assert np.abs(exact.target2cam - T).max() < 1e-8 and exact.rms_px < 1e-8
    rng = np.random.default_rng(1)
    sigma = 0.2
    devs, stds = [], []
    for _ in range(150):
        p = board_pose(board.object_points, uv + rng.normal(scale=sigma, size=uv.shape), K, dist)
        dR = T[:3, :3].T @ p.target2cam[:3, :3]  # R = R_true Exp(omega)
        w = cv2.Rodrigues(dR)[0].ravel()
        devs.append(np.r_[w, p.target2cam[:3, 3] - T[:3, 3]])
        stds.append(np.sqrt(np.diag(p.cov)))
    ratio = np.std(devs, axis=0) / np.mean(stds, axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.3)), ratio
    assert 0 < p.tilt_deg < 90
    with pytest.raises(InputError, match="at least 4"):
        board_pose(board.object_points[:3], uv[:3], K, dist)


def test_tilt_of_a_frontal_view_is_zero(camera):
    K, dist, _ = camera
    board = Chessboard(9, 6, 20.0)
    T = transform_from(matrix_from_axis_angle([0, 0, 0.3]), [-80.0, -50.0, 400.0])
    uv = project(K, dist, board.object_points @ T[:3, :3].T + T[:3, 3])
    assert board_pose(board.object_points, uv, K, dist).tilt_deg < 15
