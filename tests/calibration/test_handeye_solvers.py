"""Hand-eye closed forms: recovery of a known X, OpenCV cross-checks, degeneracy errors."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye import METHODS, calibrate_handeye, solve
from kinecal.calibration.handeye.errors import axxb_residuals, pose_error
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    rot_z,
    transform_from,
)

cv2 = pytest.importorskip("cv2")

X_TRUE = transform_from(matrix_from_rpy([0.3, -0.2, 1.1]), [32.0, -18.0, 95.0])  # cam2flange, mm
Y_TRUE = transform_from(matrix_from_rpy([0.05, 0.02, 0.7]), [650.0, 120.0, -40.0])  # target2base


def synthetic(n: int = 12, seed: int = 0, spread: float = 0.6):
    """Noise-free eye-in-hand stations (mm): flange2base, target2cam."""
    rng = np.random.default_rng(seed)
    cam = transform_from(
        matrix_from_axis_angle(rng.normal(size=(n, 3)) * spread) @ matrix_from_rpy([np.pi, 0, 0]),
        rng.normal(size=(n, 3)) * 80.0 + [0.0, 0.0, 400.0],
    )  # cam2target
    C = invert_transform(cam)
    G = Y_TRUE @ cam @ invert_transform(X_TRUE)
    return G, C


@pytest.mark.parametrize("method", METHODS)
def test_closed_form_recovers_x_noise_free(method):
    G, C = synthetic()
    res = calibrate_handeye(G, C, method=method, refine="none")
    assert np.abs(res.X - X_TRUE).max() < 1e-8
    assert np.abs(res.target - Y_TRUE).max() < 1e-8
    R = res.X[:3, :3]
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12) and np.linalg.det(R) > 0
    assert res.rotation_rms_deg < 1e-8 and res.translation_rms < 1e-8
    assert res.outliers == []


@pytest.mark.parametrize("pairs", ["all", "consecutive"])
def test_pairs_modes_noise_free(pairs):
    G, C = synthetic(seed=3)
    for method in ("tsai", "park", "horaud", "andreff", "daniilidis"):
        X, _ = solve(G, C, method, pairs)
        rot, tr = pose_error(X, X_TRUE)
        assert rot < 1e-8 and tr < 1e-8, method


_CV_AXXB = {"tsai": "TSAI", "park": "PARK", "horaud": "HORAUD", "andreff": "ANDREFF",
            "daniilidis": "DANIILIDIS"}


@pytest.mark.parametrize("method", list(_CV_AXXB))
def test_matches_opencv_calibrate_hand_eye(method):
    if not hasattr(cv2, "calibrateHandEye"):
        pytest.skip("cv2 without calibrateHandEye")
    G, C = synthetic(seed=1)
    flag = getattr(cv2, "CALIB_HAND_EYE_" + _CV_AXXB[method])
    R, t = cv2.calibrateHandEye(G[:, :3, :3], G[:, :3, 3], C[:, :3, :3], C[:, :3, 3],
                                method=flag)
    ours = calibrate_handeye(G, C, method=method, refine="none").X
    assert np.abs(ours[:3, :3] - R).max() < 1e-8
    assert np.abs(ours[:3, 3] - t.ravel()).max() < 1e-8


@pytest.mark.parametrize("method", ["shah", "li"])
def test_matches_opencv_robot_world_hand_eye(method):
    if not hasattr(cv2, "calibrateRobotWorldHandEye"):
        pytest.skip("cv2 without calibrateRobotWorldHandEye")
    G, C = synthetic(seed=2)
    Bi = invert_transform(G)  # base2gripper
    flag = getattr(cv2, "CALIB_ROBOT_WORLD_HAND_EYE_" + method.upper())
    _, _, Rg, tg = cv2.calibrateRobotWorldHandEye(C[:, :3, :3], C[:, :3, 3], Bi[:, :3, :3],
                                                  Bi[:, :3, 3], method=flag)
    ours = invert_transform(calibrate_handeye(G, C, method=method, refine="none").X)
    assert np.abs(ours[:3, :3] - Rg).max() < 1e-8
    assert np.abs(ours[:3, 3] - tg.ravel()).max() < 1e-8


def test_opencv_park_identical_on_noisy_data():
    """Same formulation, same pairs: PARK agrees with OpenCV even with noise."""
    G, C = synthetic(n=15, seed=4)
    rng = np.random.default_rng(9)
    C = C @ transform_from(matrix_from_axis_angle(rng.normal(size=(15, 3)) * 2e-3),
                           rng.normal(size=(15, 3)) * 0.5)
    R, t = cv2.calibrateHandEye(G[:, :3, :3], G[:, :3, 3], C[:, :3, :3], C[:, :3, 3],
                                method=cv2.CALIB_HAND_EYE_PARK)
    ours = calibrate_handeye(G, C, method="park", refine="none").X
    assert np.abs(ours[:3, :3] - R).max() < 1e-10
    assert np.abs(ours[:3, 3] - t.ravel()).max() < 1e-8


def test_unit_independence_andreff_and_li():
    """Millimetres vs metres: kinecal's ANDREFF and LI give the same X (scaled)."""
    G, C = synthetic(seed=5, spread=0.15)
    for method in ("andreff", "li", "daniilidis"):
        Xmm = calibrate_handeye(G, C, method=method, refine="none").X
        Gm, Cm = G.copy(), C.copy()
        Gm[:, :3, 3] /= 1000.0
        Cm[:, :3, 3] /= 1000.0
        Xm = calibrate_handeye(Gm, Cm, method=method, refine="none").X
        assert np.abs(Xm[:3, :3] - Xmm[:3, :3]).max() < 1e-9
        assert np.abs(Xm[:3, 3] * 1000.0 - Xmm[:3, 3]).max() < 1e-6


def test_eye_to_hand_convention():
    """Camera fixed in the base, target on the flange: X = cam2base (OpenCV's convention)."""
    rng = np.random.default_rng(7)
    cam2base = transform_from(matrix_from_rpy([2.5, 0.1, -0.4]), [900.0, 50.0, 600.0])
    target2flange = transform_from(matrix_from_rpy([0.1, 0.2, 0.3]), [5.0, 10.0, 60.0])
    F = transform_from(matrix_from_axis_angle(rng.normal(size=(10, 3)) * 0.5),
                       rng.normal(size=(10, 3)) * 100 + [700.0, 0.0, 300.0])  # flange2base
    C = invert_transform(cam2base) @ F @ target2flange  # target2cam
    for method in METHODS:
        res = calibrate_handeye(F, C, setup="eye-to-hand", method=method, refine="none")
        assert np.abs(res.X - cam2base).max() < 1e-8, method
        assert np.abs(res.target - target2flange).max() < 1e-8, method
    B = invert_transform(F)  # OpenCV's eye-to-hand recipe: pass base2gripper
    R, t = cv2.calibrateHandEye(B[:, :3, :3], B[:, :3, 3], C[:, :3, :3], C[:, :3, 3],
                                method=cv2.CALIB_HAND_EYE_PARK)
    assert np.abs(R - cam2base[:3, :3]).max() < 1e-8
    assert np.abs(t.ravel() - cam2base[:3, 3]).max() < 1e-8


def test_axxb_residuals_zero_at_truth():
    from kinecal.calibration.handeye._motions import motion_pairs

    G, C = synthetic()
    A, B = motion_pairs(G, C)
    rot, tr = axxb_residuals(A, B, X_TRUE)
    assert rot.max() < 1e-9 and tr.max() < 1e-9
    rot, tr = axxb_residuals(A, B, X_TRUE @ transform_from(np.eye(3), [1.0, 0, 0]))
    assert tr.max() > 0.1


def test_degenerate_single_axis_raises():
    n = 6
    G = transform_from(rot_z(np.linspace(0, 2, n)), np.zeros((n, 3)) + [500.0, 0, 0])
    C = invert_transform(X_TRUE) @ invert_transform(G) @ Y_TRUE
    with pytest.raises(InputError, match="one axis"):
        calibrate_handeye(G, C, refine="none")


def test_degenerate_pure_translation_raises():
    n = 5
    G = transform_from(np.eye(3), np.arange(3 * n, dtype=float).reshape(n, 3) * 10)
    C = invert_transform(X_TRUE) @ invert_transform(G) @ Y_TRUE
    with pytest.raises(InputError, match="pure translations"):
        calibrate_handeye(G, C, refine="none")


def test_bad_input_errors():
    G, C = synthetic()
    with pytest.raises(InputError, match="method"):
        calibrate_handeye(G, C, method="nope")
    with pytest.raises(InputError, match="setup"):
        calibrate_handeye(G, C, setup="eye-on-head")
    with pytest.raises(InputError, match="at least 3"):
        calibrate_handeye(G[:2], C[:2])
    with pytest.raises(InputError, match="poses"):
        calibrate_handeye(G, C[:5])
    bad = G.copy()
    bad[2, :3, :3] *= 1.1
    with pytest.raises(InputError, match="orthonormal"):
        calibrate_handeye(bad, C)


def test_axxb_station_rms_matches_loop():
    from kinecal.calibration.handeye._motions import motion_pairs
    from kinecal.calibration.handeye.errors import axxb_station_rms

    G, C = synthetic(n=6, seed=8)
    X = X_TRUE @ transform_from(matrix_from_axis_angle([0.01, 0.02, 0.0]), [1.0, 0.0, 2.0])
    rot, tr = axxb_station_rms(G, C, X)
    A, B = motion_pairs(G, C)  # pairs (i, j), i < j, in np.triu_indices order
    i, j = np.triu_indices(6, k=1)
    for s in range(6):
        mask = (i == s) | (j == s)
        r, t = axxb_residuals(A[mask], B[mask], X)
        assert rot[s] == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-12)
        assert tr[s] == pytest.approx(np.sqrt(np.mean(t**2)), rel=1e-12)
    res = calibrate_handeye(G, C, refine="none")
    assert res.axxb_rotation_deg.max() < 1e-8 and len(res.to_dict()["axxb_stations"]) == 6


def test_bad_refine_options():
    G, C = synthetic()
    with pytest.raises(InputError, match="unknown option"):
        calibrate_handeye(G, C, refine="igwo", options={"wolves": 3})
    with pytest.raises(InputError, match="rotation_weight"):
        calibrate_handeye(G, C, rotation_weight=-1.0)
    with pytest.raises(InputError, match="refine"):
        calibrate_handeye(G, C, refine="gwo")


def _near_half_turn_set():
    """Half the stations turned by 180 deg - 0.03 deg from the others: those pair motions
    have ``w ~ 3e-4``, below the noise of 1e-3 rad, so q_A and q_B signs disagree often."""
    rng = np.random.default_rng(21)
    n = 12
    ax = rng.normal(size=(n, 3))
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    ang = np.where(np.arange(n) % 2 == 0, 0.0, np.pi - 5e-4)[:, None]
    cam = transform_from(matrix_from_axis_angle(ax * ang), rng.normal(size=(n, 3)) * 80.0)
    C = invert_transform(cam)
    G = Y_TRUE @ cam @ invert_transform(X_TRUE)
    C = C @ transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * 1e-3),
                           rng.normal(size=(n, 3)) * 0.2)
    return G, C


@pytest.mark.parametrize("method", ["tsai", "park", "horaud", "daniilidis"])
def test_signs_consistent_near_half_turns(method):
    """Near 180 deg, w ~ 0 and noise can flip q_B against q_A (or send log R_B to the
    antipode); the aligned solvers stay as accurate as Shah (absolute poses, no pairs)."""
    G, C = _near_half_turn_set()
    ref = pose_error(solve(G, C, "shah")[0], X_TRUE)
    err = pose_error(solve(G, C, method)[0], X_TRUE)
    assert err[0] < 2.0 * ref[0] + 0.005 and err[1] < 2.0 * ref[1] + 0.05
