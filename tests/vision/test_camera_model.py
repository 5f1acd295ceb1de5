"""kinecal's numpy camera model against cv2.projectPoints and finite differences."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye.camera import (
    check_camera,
    intrinsic_vector,
    project,
    project_jacobian,
    with_intrinsics,
)
from kinecal.vision.render import undistort_normalized

K = np.array([[820.0, 0.0, 330.2], [0.0, 815.0, 241.7], [0.0, 0.0, 1.0]])
D5 = np.array([-0.21, 0.09, 0.0012, -0.0007, -0.02])
D8 = np.array([-0.21, 0.09, 0.0012, -0.0007, -0.02, 0.05, -0.01, 0.004])


def _points(n=200, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-110, 110, n),
                            rng.uniform(300, 700, n)])


@pytest.mark.parametrize("dist", [None, D5, D8])
def test_project_matches_opencv(dist):
    P = _points()
    ours = project(K, dist, P)
    cvp, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K,
                               np.zeros(5) if dist is None else dist)
    assert np.abs(ours - cvp.reshape(-1, 2)).max() < 1e-9


@pytest.mark.parametrize("dist,rational", [(D5, False), (D8, True)])
def test_jacobians_match_finite_differences(dist, rational):
    Kc, d8 = check_camera(K, dist)
    P = _points(20, 1)
    _, Jp, Ji = project_jacobian(Kc, d8, P, rational=rational)
    h = 1e-6
    for k in range(3):
        dP = np.zeros(3)
        dP[k] = h * 100
        num = (project(Kc, d8, P + dP) - project(Kc, d8, P - dP)) / (2 * h * 100)
        assert np.abs(num - Jp[:, :, k]).max() < 1e-6 * np.abs(Jp).max()
    p0 = intrinsic_vector(Kc, d8, rational)
    for k in range(len(p0)):
        step = np.zeros_like(p0)
        step[k] = h * max(1.0, abs(p0[k]))
        Ka, da = with_intrinsics(Kc, d8, p0 + step)
        Kb, db = with_intrinsics(Kc, d8, p0 - step)
        num = (project(Ka, da, P) - project(Kb, db, P)) / (2 * step[k])
        assert np.abs(num - Ji[:, :, k]).max() < 1e-5 * max(1.0, np.abs(Ji[:, :, k]).max())


def test_undistort_inverts_project():
    P = _points(500, 2)
    uv = project(K, D8, P)
    Kc, d8 = check_camera(K, D8)
    xy = undistort_normalized(uv, Kc, d8)
    assert np.abs(xy - P[:, :2] / P[:, 2:]).max() < 1e-12


def test_bad_cameras():
    with pytest.raises(InputError, match="3x3"):
        check_camera(np.eye(2), None)
    with pytest.raises(InputError, match="fx, fy > 0"):
        check_camera(np.diag([-1.0, 1.0, 1.0]), None)
    with pytest.raises(InputError, match="thin-prism"):
        check_camera(K, np.r_[D8, 0.1, 0, 0, 0])
    assert check_camera(K, np.r_[D8, 0, 0, 0, 0])[1].size == 8


def test_opencv_is_optional(monkeypatch):
    """The core install works without OpenCV; image functions then name the extra."""
    import subprocess
    import sys

    code = ("import sys, kinecal, kinecal.vision.pipeline, kinecal.vision.render, "
            "kinecal.calibration.handeye.images; from kinecal.cli import _load_commands; "
            "_load_commands(); print('cv2' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
    monkeypatch.setitem(sys.modules, "cv2", None)
    from kinecal.vision import require_cv2

    with pytest.raises(InputError, match=r"kinecal\[vision\]"):
        require_cv2()
