"""industrial_calibration's multi-camera case against its own stated tolerances.

industrial_calibration (ros-industrial, v1.2) ships no multi-camera image set; its
multi-camera check is the unit test ``test/extrinsic_multi_static_camera_utest.cpp``
(cases ``single_camera`` and ``two_cameras``): static cameras looking down from 2 m
(turned by pi about x, at x = -0.1 and +0.1 m), a 5 x 5 grid of points 15 mm apart held
0.25 m in front of a wrist, the wrist 0.25 m above a pivot 0.25 m up, turned about y and
then about x by -10 .. +10 deg in 1 deg steps; pinhole cameras fx 1411, fy 1408, cx 807.2,
cy 615 (1600 x 1200, no distortion), every grid point inside the image kept. Its optimizer
starts from guesses 1 cm and 0.01-0.02 rad off; it expects the poses to agree with the
truth to Eigen's ``isApprox(.., 1e-8)`` (relative Frobenius norm) and a final cost per
observation below 1e-15. The same scene here, from no guess (PnP and a closed form per
camera), through the multi-camera hand-eye of ``kinecal handeye-images --camera``.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.calibration.camera.rig_handeye import calibrate_rig_handeye
from kinecal.calibration.camera.rig_pixels import RigViews
from kinecal.calibration.handeye.camera import project
from kinecal.spatial import invert_transform, matrix_from_axis_angle, transform_from
from kinecal.vision.pnp import board_pose

K = np.array([[1411.0, 0.0, 807.2], [0.0, 1408.0, 615.0], [0.0, 0.0, 1.0]])
SIZE = (1600, 1200)
GRID = np.array([[0.015 * c, 0.015 * r, 0.0] for r in range(5) for c in range(5)])
WRIST_TO_TARGET = transform_from(np.eye(3), [0.0, 0.0, 0.25])


def _is_approx(a: np.ndarray, b: np.ndarray, prec: float) -> bool:
    """Eigen's ``isApprox``: ``|a - b| <= prec * min(|a|, |b|)`` (Frobenius)."""
    return bool(np.linalg.norm(a - b) <= prec * min(np.linalg.norm(a), np.linalg.norm(b)))


def _scene(base_to_camera: list[np.ndarray]):
    names, camera, wrist, points, pixels = [], [], [], [], []
    for c, X in enumerate(base_to_camera):
        for axis in ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]):
            for deg in range(-10, 11):
                W = transform_from(np.eye(3), [0, 0, 0.25]) @ transform_from(
                    matrix_from_axis_angle(np.radians(deg) * np.asarray(axis)), [0, 0, 0.25])
                C = invert_transform(X) @ W @ WRIST_TO_TARGET
                P = GRID @ C[:3, :3].T + C[:3, 3]
                uv = project(K, np.zeros(8), P)
                inside = (P[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= SIZE[0]) & \
                    (uv[:, 1] >= 0) & (uv[:, 1] <= SIZE[1])
                if inside.sum() < 4:
                    continue
                names.append(f"c{c}_{axis.index(1.0)}_{deg}")
                camera.append(c)
                wrist.append(W)
                points.append(GRID[inside])
                pixels.append(uv[inside])
    poses = [{0: board_pose(P, uv, K, None).target2cam} for P, uv in
             zip(points, pixels, strict=True)]
    views = RigViews(names, np.array(camera), np.zeros((len(names), 0)), points, pixels,
                     [np.zeros(len(p), np.intp) for p in points], poses)
    return views, np.array(wrist)


@pytest.mark.parametrize("xs", [[0.0], [-0.1, 0.1]], ids=["single_camera", "two_cameras"])
def test_industrial_calibration_multi_static_camera(xs):
    truth = [transform_from(matrix_from_axis_angle([np.pi, 0.0, 0.0]), [x, 0.0, 2.0])
             for x in xs]
    views, wrist = _scene(truth)
    names = [f"c{i}" for i in range(len(xs))]
    res = calibrate_rig_handeye(views, wrist, names, [K] * len(xs), [None] * len(xs),
                                setup="eye-to-hand")
    assert _is_approx(res.board_poses[0], WRIST_TO_TARGET, 1e-8)
    for X, T in zip(res.camera_poses, truth, strict=True):
        assert _is_approx(X, T, 1e-8)
    # their cost per observation: half the squared pixel residual per corner
    cost = 0.5 * np.sum(res.after_px ** 2 * np.array([len(p) for p in views.points])) / \
        sum(len(p) for p in views.points)
    assert cost < 1e-15
    if len(xs) == 2:  # the pair: 0.2 m apart along x, not turned
        T, sigma = res.pairs[(0, 1)]
        assert _is_approx(T, invert_transform(truth[0]) @ truth[1], 1e-8)
        assert np.all(sigma < 1e-9)  # exact data: the stated uncertainty is round-off
