"""Stewart-platform CMM of papers/004: geometry, inverse kinematics, Newton FK, Table 3."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from kinecal.errors import InputError
from kinecal.kinematics.stewart.forward import expmap
from kinecal.kinematics.stewart.platform import (
    StewartPlatform,
    degrees_to_radians,
    joint_angles_liu2008,
    radians_to_degrees,
)

TABLE3_LEGS = np.array([0.750, 0.780, 0.800, 0.900, 0.870, 0.850])
TABLE3_POSE_DEG = np.array([0.039860, 0.095930, 0.925235, -12.697325, 6.403095, 15.133206])


@pytest.fixture(scope="module")
def cmm() -> StewartPlatform:
    return StewartPlatform.liu2008()


def paper_rotation(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """The matrix printed in papers/004 sec. 2.1, written out element by element."""
    ca, sa, cb, sb, cg, sg = (np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta),
                              np.cos(gamma), np.sin(gamma))  # fmt: skip
    return np.array(
        [
            [cg * cb, cg * sb * sa - sg * ca, cg * sb * ca + sg * sa],
            [sg * cb, sg * sb * sa + cg * ca, sg * sb * ca - cg * sa],
            [-sb, cb * sa, cb * ca],
        ]
    )


def paper_legs(pose_deg: np.ndarray) -> np.ndarray:
    """Independent eq. 1-5 of papers/004 (Table 2 geometry), one pose, angles in deg."""
    tb = np.deg2rad([45, 75, 165, 195, 285, 315])
    tp = np.deg2rad([15, 105, 135, 225, 255, 345])
    R = paper_rotation(*np.deg2rad(pose_deg[3:]))
    s = np.array([0.0, 0.0, 0.18])
    out = []
    for i in range(6):
        b = np.array([0.5 * np.cos(tb[i]), 0.5 * np.sin(tb[i]), 0.0])
        p = np.array([0.225 * np.cos(tp[i]), 0.225 * np.sin(tp[i]), 0.0])
        out.append(np.linalg.norm(R @ p + pose_deg[:3] - R @ s - b))
    return np.array(out)


def exact_table3() -> np.ndarray:
    """Table 3 solved independently (scipy least_squares on `paper_legs`), angles in deg."""
    sol = least_squares(
        lambda x: paper_legs(x) - TABLE3_LEGS, TABLE3_POSE_DEG, xtol=1e-15, ftol=1e-15, gtol=1e-15
    )
    return sol.x


def test_joint_angles_eq2():
    tb, tp = joint_angles_liu2008(np.deg2rad(30.0), np.deg2rad(30.0))
    np.testing.assert_allclose(np.rad2deg(tb), [45, 75, 165, 195, 285, 315])
    np.testing.assert_allclose(np.rad2deg(tp), [15, 105, 135, 225, 255, 345])


def test_inverse_matches_paper_formulas(cmm):
    rng = np.random.default_rng(1)
    poses = cmm.random_poses(20, rng)
    deg = radians_to_degrees(poses)
    expected = np.array([paper_legs(p) for p in deg])
    np.testing.assert_allclose(cmm.inverse(poses), expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(degrees_to_radians(deg), poses, rtol=0, atol=1e-15)


def test_table3_printed_pose_gives_printed_legs(cmm):
    legs = cmm.inverse(degrees_to_radians(TABLE3_POSE_DEG))
    # the printed pose is rounded to 1e-6 m and 1e-6 deg
    np.testing.assert_allclose(legs, TABLE3_LEGS, rtol=0, atol=1e-6)


def test_table3_newton_reproduces_paper(cmm):
    res = cmm.forward(TABLE3_LEGS)
    assert res.converged.all() and res.residual[0] < 1e-12
    got = radians_to_degrees(res.poses[0])
    # every printed digit (rounding to 6 decimals)
    np.testing.assert_allclose(got, TABLE3_POSE_DEG, rtol=0, atol=5e-7)
    exact = exact_table3()
    assert np.abs(got[:3] - exact[:3]).max() < 1e-9
    assert np.abs(got[3:] - exact[3:]).max() < 1e-7


def test_pose_jacobian_finite_differences(cmm):
    x = degrees_to_radians(TABLE3_POSE_DEG)
    J = cmm.pose_jacobian(x)
    from kinecal.spatial import matrix_from_rpy, rpy_from_matrix

    h = 1e-6
    num = np.empty((6, 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        cols = []
        for sgn in (1.0, -1.0):
            R = expmap(sgn * d[3:]) @ matrix_from_rpy(x[3:])
            xp = np.concatenate([x[:3] + sgn * d[:3], rpy_from_matrix(R)])
            cols.append(cmm.inverse(xp))
        num[:, k] = (cols[0] - cols[1]) / (2 * h)
    np.testing.assert_allclose(J, num, rtol=0, atol=1e-8)


def test_round_trip_1000_workspace_poses(cmm):
    poses = cmm.random_poses(1000, rng=7)
    res = cmm.forward(cmm.inverse(poses))
    assert res.converged.all()
    assert np.abs(res.poses[:, :3] - poses[:, :3]).max() < 1e-9
    assert np.abs(res.poses[:, 3:] - poses[:, 3:]).max() < 1e-9


def test_batch_newton_matches_per_row_least_squares(cmm):
    poses = cmm.random_poses(25, rng=3)
    legs = cmm.inverse(poses)
    batch = cmm.forward(legs).poses
    np.testing.assert_allclose(batch, poses, rtol=0, atol=1e-10)
    x0 = cmm.neutral_pose()
    for i in range(len(legs)):
        sol = least_squares(lambda x, i=i: cmm.inverse(x) - legs[i], x0, xtol=1e-15, ftol=1e-15)
        np.testing.assert_allclose(batch[i], sol.x, rtol=0, atol=1e-8)  # scipy's own accuracy


def test_forward_x0_and_single_row(cmm):
    x = cmm.random_poses(5, rng=11)
    res = cmm.forward(cmm.inverse(x), x0=x + 1e-3)
    np.testing.assert_allclose(res.poses, x, rtol=0, atol=1e-10)
    assert res.iterations.max() <= 4  # quadratic convergence from a close start
    with pytest.raises(InputError, match="x0"):
        cmm.forward(cmm.inverse(x), x0=np.zeros(5))


def test_leg_range_and_bad_rows_name_the_row(cmm):
    legs = np.tile(TABLE3_LEGS, (4, 1))
    legs[2, 1] = 0.99
    with pytest.raises(InputError, match=r"row 3.*leg range"):
        cmm.forward(legs)
    legs[2, 1] = np.nan
    with pytest.raises(InputError, match=r"row 3.*finite"):
        cmm.forward(legs)
    with pytest.raises(InputError, match="6 columns"):
        cmm.forward(np.ones((2, 5)))


def test_unreachable_legs_raise_or_flag(cmm):
    legs = np.array([TABLE3_LEGS, [0.75, 0.97, 0.75, 0.97, 0.75, 0.97]])
    with pytest.raises(InputError, match=r"row 2.*no real solution"):
        cmm.forward(legs)
    res = cmm.forward(legs, on_failure="flag")
    assert res.converged.tolist() == [True, False]
    assert res.residual[1] > 1e-3


def test_unknown_method(cmm):
    with pytest.raises(InputError, match="method"):
        cmm.forward(TABLE3_LEGS, method="bisection")


def test_parameters_round_trip(cmm):
    v = cmm.parameters + np.linspace(-1e-3, 1e-3, 42)
    g = cmm.with_parameters(v)
    np.testing.assert_array_equal(g.parameters, v)
    x = cmm.random_poses(3, rng=2)
    # leg offsets shift the readings
    np.testing.assert_allclose(
        g.inverse(x) + g.leg_offsets,
        np.linalg.norm(g.leg_vectors(x), axis=-1),
        rtol=0,
        atol=1e-15,
    )
