"""Hand-eye calibration of SCARA / 4-axis arms (rotations about one axis only): Ulrich &
Steger's closed form, the height along the axis from a stated camera height or a board
contact, eye-in-hand and eye-to-hand, with and without noise."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import InputError, diagnostics
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye._motions import motion_pairs
from kinecal.calibration.handeye.errors import pose_error
from kinecal.calibration.handeye.scara import detect_one_axis, ulrich_steger
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    rot_z,
    transform_from,
)

UP = np.array([0.0, 0.0, 1.0])
X_EIH = transform_from(matrix_from_rpy([0.05, -0.03, 0.4]), [40.0, -25.0, -60.0])  # cam2flange
Y_EIH = transform_from(matrix_from_rpy([np.pi + 0.02, 0.01, 0.3]), [500.0, 100.0, -300.0])
X_ETH = transform_from(matrix_from_rpy([np.pi - 0.1, 0.05, 0.2]), [600.0, 50.0, 1200.0])
Y_ETH = transform_from(matrix_from_rpy([0.02, -0.01, 0.5]), [10.0, -5.0, 40.0])  # target2flange


def scara(n: int, seed: int = 0) -> np.ndarray:
    """flange2base of a SCARA (350 + 300 mm arms, tool flange facing down), mm."""
    rng = np.random.default_rng(seed)
    q = np.column_stack([rng.uniform(-1.2, 1.2, n), rng.uniform(-1.5, 1.5, n),
                         rng.uniform(-150, -50, n), rng.uniform(-2.5, 2.5, n)])
    down = matrix_from_rpy([np.pi, 0.0, 0.0])
    return np.array([transform_from(rot_z(a), [0, 0, 400.0])
                     @ transform_from(rot_z(b), [350.0, 0, 0])
                     @ transform_from(rot_z(d) @ down, [300.0, 0, z]) for a, b, z, d in q])


def stations(setup: str, n: int = 15, seed: int = 0):
    F = scara(n, seed)
    if setup == "eye-in-hand":
        return F, invert_transform(X_EIH) @ invert_transform(F) @ Y_EIH, X_EIH, Y_EIH
    return F, invert_transform(X_ETH) @ F @ Y_ETH, X_ETH, Y_ETH


def run(F, C, **kw):
    with diagnostics.collect() as found:
        res = calibrate_handeye(F, C, **kw)
    return res, [d.code for d in found]


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_noise_free_exact_with_the_stated_height_or_contact(setup):
    F, C, X, Y = stations(setup)
    # eye-in-hand: flange z points down, so the base's +z is the flange's -z
    cam = float(-X[2, 3]) if setup == "eye-in-hand" else float(X[2, 3])
    contact = (Y @ [30.0, -20.0, 0.0, 1.0])[:3]  # a point of the board plane
    for kw in ({"camera_height": cam}, {"board_contact": contact}):
        res, codes = run(F, C, setup=setup, **kw)
        assert res.method == "ulrich-steger" and codes == [], codes
        r, t = pose_error(res.X, X)
        assert r < 1e-9 and t < 1e-8, (kw, r, t)
        assert pose_error(res.target, Y)[1] < 1e-8
        one = res.one_axis
        assert np.allclose(one["axis_base"], UP) and one["spread_deg"] < 1e-6
        assert one["camera_height"] == pytest.approx(cam, abs=1e-9)
        assert one["height_from"] == next(iter(kw)).replace("_", "-")
    # the closed form alone: everything but the height exact, the height zero
    res, _ = run(F, C, setup=setup, camera_height=cam, refine="none")
    assert pose_error(res.X, X)[1] < 1e-8


def test_closed_form_sets_the_unseen_component_to_zero():
    """ulrich_steger: exact rotation and translation across the axis; along it, zero."""
    F, C, X, _ = stations("eye-in-hand")
    axis = detect_one_axis(F, "eye-in-hand")
    A, B = motion_pairs(F, C)
    Xs = ulrich_steger(A, B, axis.moving)
    assert pose_error(Xs, X)[0] < 1e-9
    d = Xs[:3, 3] - X[:3, 3]
    assert abs(axis.moving @ Xs[:3, 3]) < 1e-9
    assert np.linalg.norm(d - (d @ axis.moving) * axis.moving) < 1e-8


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_missing_height_is_named_and_only_the_height_is_assumed(setup):
    F, C, X, _ = stations(setup)
    res, codes = run(F, C, setup=setup)
    assert codes == ["handeye-one-axis"]
    assert "(+0.000, +0.000, +1.000) in the base frame" in res.warnings[0].message
    k = detect_one_axis(F if setup == "eye-in-hand" else invert_transform(F), setup).moving
    d = res.X[:3, 3] - X[:3, 3]
    assert pose_error(res.X, X)[0] < 1e-9 and abs(k @ res.X[:3, 3]) < 1e-9
    assert np.linalg.norm(d - (d @ k) * k) < 1e-8
    assert res.one_axis["height_from"] == "none"
    with diagnostics.strict(), pytest.raises(InputError, match="handeye-one-axis"):
        calibrate_handeye(F, C, setup=setup)


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_noisy_errors_are_what_the_noise_explains(setup):
    """Target poses with 0.05 deg / 0.2 mm noise, 25 trials: the error of X across the axis
    and in rotation follows the predicted standard deviations (chi-square per trial; mean
    about 1 when the uncertainty is honest), and the stated height holds exactly."""
    F, C0, X, _ = stations(setup, n=20)
    cam = float(-X[2, 3]) if setup == "eye-in-hand" else float(X[2, 3])
    rng = np.random.default_rng(7)
    ratios, turns = [], []
    for _ in range(25):
        E = transform_from(matrix_from_axis_angle(rng.normal(size=(20, 3)) * np.radians(0.05)),
                           rng.normal(size=(20, 3)) * 0.2)
        res, codes = run(F, C0 @ E, setup=setup, camera_height=cam)
        assert codes == [] and res.one_axis["camera_height"] == pytest.approx(cam, abs=1e-9)
        unc = res.x_uncertainty
        ratios.append(pose_error(res.X, X)[1] / unc.translation)
        turns.append(pose_error(res.X, X)[0] / unc.rotation_deg)
    # |error| / rms sigma: about 1 on average when the uncertainty is right (measured 1.16
    # and 0.83 for the translation, 1.09 and 0.86 for the rotation)
    for r in (np.array(ratios), np.array(turns)):
        assert 0.5 < np.sqrt(np.mean(r**2)) < 1.6 and r.max() < 4.0


def test_near_half_turns_and_robot_rounding():
    """Motions of almost 180 deg (the quaternion sign decided by noise) and robot poses
    rounded to 1e-6 (axis spread far below the one-axis limit) still give X."""
    F, C, X, Y = stations("eye-in-hand", n=12, seed=3)
    F = F.copy()
    F[1, :3, :3] = F[0, :3, :3] @ rot_z(np.pi - 1e-7)
    C = invert_transform(X) @ invert_transform(F) @ Y
    F = np.round(F, 6)
    res, codes = run(F, C, camera_height=float(-X[2, 3]))
    assert codes == [] and pose_error(res.X, X)[0] < 1e-3 and pose_error(res.X, X)[1] < 0.01


def test_heights_are_checked():
    F, C, X, Y = stations("eye-in-hand")
    with pytest.raises(InputError, match="not both"):
        calibrate_handeye(F, C, camera_height=1.0, board_contact=[0, 0, 0])
    with pytest.raises(InputError, match="three finite"):
        calibrate_handeye(F, C, board_contact=[0, 0])
    with pytest.raises(InputError, match="finite length"):
        calibrate_handeye(F, C, camera_height=float("nan"))
    # a board standing on edge (its plane along the axis) cannot give the height
    Yv = transform_from(matrix_from_rpy([np.pi / 2, 0, 0]), Y[:3, 3])
    Cv = invert_transform(X) @ invert_transform(F) @ Yv
    with pytest.raises(InputError, match="parallel to the robot's rotation axis"):
        calibrate_handeye(F, Cv, board_contact=Yv[:3, 3])


def test_height_given_for_a_six_axis_robot_is_named_unused():
    rng = np.random.default_rng(0)
    F = transform_from(matrix_from_axis_angle(rng.normal(size=(12, 3)) * 0.5),
                       rng.normal(size=(12, 3)) * 100 + [500, 0, 400])
    C = invert_transform(X_EIH) @ invert_transform(F) @ Y_EIH
    res, codes = run(F, C, camera_height=12.0)
    assert codes == ["handeye-height-unused"] and res.one_axis is None
    assert pose_error(res.X, X_EIH)[1] < 1e-8  # the data's own height, not 12


def test_flange_turning_in_place_is_refused():
    """One axis and one line: X's rotation about the axis is unobservable as well."""
    n = 6
    F = transform_from(rot_z(np.linspace(0, 2, n)), np.zeros((n, 3)) + [500.0, 0, 0])
    C = invert_transform(X_EIH) @ invert_transform(F) @ Y_EIH
    with pytest.raises(InputError, match="one axis and about one line"):
        calibrate_handeye(F, C, camera_height=0.0)


def test_arm_kept_in_a_corner_is_named_ill_conditioned():
    """Shoulder and elbow moved by +-0.03 rad only: the motions' turning lines lie within
    about 20 mm, X's rotation about the axis is poorly determined (the tilt is not), and
    `handeye-conditioning` says so with the advice for a SCARA; the stated uncertainty is
    the size of the actual error."""
    rng = np.random.default_rng(4)
    n = 15
    q = np.column_stack([rng.uniform(-0.03, 0.03, n), 1.0 + rng.uniform(-0.03, 0.03, n),
                         rng.uniform(-150, -50, n), rng.uniform(-2.5, 2.5, n)])
    down = matrix_from_rpy([np.pi, 0.0, 0.0])
    F = np.array([transform_from(rot_z(a), [0, 0, 400.0]) @ transform_from(rot_z(b), [350.0, 0, 0])
                  @ transform_from(rot_z(d) @ down, [300.0, 0, z]) for a, b, z, d in q])
    E = transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.05)),
                       rng.normal(size=(n, 3)) * 0.2)
    C = invert_transform(X_EIH) @ invert_transform(F) @ Y_EIH @ E
    res, codes = run(F, C, camera_height=60.0)
    assert codes == ["handeye-conditioning"]
    message = res.warnings[0].message
    assert "rotation is" in message and "shoulder and elbow" in message
    unc = res.x_uncertainty
    assert unc.rotation_anisotropy > 10
    assert pose_error(res.X, X_EIH)[0] < 3 * unc.rotation_deg
