"""kinecal.spatial: round trips, conventions, validators (property-based where it helps)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from kinecal import spatial as sp
from kinecal.errors import InputError

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
quats = arrays(float, 4, elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 1e-3)
rotvecs = arrays(float, 3, elements=st.floats(-3.1, 3.1))


@given(quats)
def test_quaternion_matrix_round_trip(q):
    q = q / np.linalg.norm(q)
    R = sp.matrix_from_quaternion(q)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    back = sp.quaternion_from_matrix(R)
    assert back[0] >= 0
    # q and -q are the same rotation: equal up to sign
    assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-9
    np.testing.assert_allclose(sp.matrix_from_quaternion(back), R, atol=1e-12)


@given(rotvecs)
def test_axis_angle_matches_scipy_and_round_trips(v):
    R = sp.matrix_from_axis_angle(v)
    np.testing.assert_allclose(R, Rotation.from_rotvec(v).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(sp.matrix_from_axis_angle(sp.axis_angle_from_matrix(R)), R,
                               atol=1e-9)
    assert sp.rotation_angle(R) == pytest.approx(min(np.linalg.norm(v),
                                                     2 * np.pi - np.linalg.norm(v)), abs=1e-9)


@given(arrays(float, 3, elements=st.floats(-1.5, 1.5)))
def test_rpy_is_extrinsic_xyz_and_round_trips(a):
    R = sp.matrix_from_rpy(a)
    np.testing.assert_allclose(R, sp.rot_z(a[2]) @ sp.rot_y(a[1]) @ sp.rot_x(a[0]), atol=1e-15)
    np.testing.assert_allclose(R, Rotation.from_euler("xyz", a).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(sp.rpy_from_matrix(R), a, atol=1e-9)


def test_quaternion_convention_matches_scipy_scalar_first():
    R = Rotation.random(50, random_state=1).as_matrix()
    q = sp.quaternion_from_matrix(R)
    qs = Rotation.from_matrix(R).as_quat()  # (x, y, z, w)
    qs = np.column_stack([qs[:, 3], qs[:, :3]]) * np.sign(qs[:, 3:4])
    np.testing.assert_allclose(q, qs, atol=1e-12)


@settings(max_examples=50)
@given(rotvecs, arrays(float, 3, elements=finite))
def test_transform_inverse_and_pq_round_trip(v, t):
    T = sp.transform_from(sp.matrix_from_axis_angle(v), t)
    np.testing.assert_allclose(sp.invert_transform(T) @ T, np.eye(4), atol=1e-9)
    np.testing.assert_allclose(sp.transform_from_pq(sp.pq_from_transform(T)), T, atol=1e-9)
    np.testing.assert_allclose(sp.transform_from_xyz_rpy(sp.xyz_rpy_from_transform(T)), T,
                               atol=1e-9)


def test_batches_over_leading_axes():
    rng = np.random.default_rng(2)
    v = rng.uniform(-2, 2, (4, 5, 3))
    R = sp.matrix_from_axis_angle(v)
    assert R.shape == (4, 5, 3, 3)
    np.testing.assert_allclose(R[2, 3], sp.matrix_from_axis_angle(v[2, 3]), atol=1e-15)
    q = sp.quaternion_from_matrix(R)
    assert q.shape == (4, 5, 4)
    T = sp.transform_from(R, rng.normal(size=(4, 5, 3)))
    rot, trans = sp.pose_errors(T, T)
    assert rot.shape == (4, 5) and np.abs(rot).max() < 1e-7 and np.abs(trans).max() == 0


def test_project_to_rotation_is_nearest_proper_rotation():
    rng = np.random.default_rng(3)
    R = Rotation.random(20, random_state=4).as_matrix()
    noisy = R + rng.normal(0, 1e-3, R.shape)
    P = sp.project_to_rotation(noisy)
    np.testing.assert_allclose(np.swapaxes(P, 1, 2) @ P, np.broadcast_to(np.eye(3), P.shape),
                               atol=1e-12)
    assert (np.linalg.det(P) > 0).all()
    assert sp.rotation_angle(np.swapaxes(P, 1, 2) @ R).max() < 5e-3
    reflection = np.diag([1.0, 1.0, -1.0])
    assert np.linalg.det(sp.project_to_rotation(reflection)) == pytest.approx(1.0)


def test_skew_is_the_cross_product():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(2, 7, 3))
    np.testing.assert_allclose((sp.skew(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-12)


def test_validators_name_the_problem():
    R = np.stack([np.eye(3)] * 3)
    R[1] *= 1.01
    with pytest.raises(InputError, match=r"rotation 1: not orthonormal"):
        sp.check_rotation(R)
    with pytest.raises(InputError, match="reflection"):
        sp.check_rotation(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InputError, match="NaN"):
        sp.check_rotation(np.full((3, 3), np.nan))
    with pytest.raises(InputError, match=r"\(\.\.\., 3, 3\)"):
        sp.check_rotation(np.eye(4))
    T = np.eye(4)
    T[3, 0] = 1
    with pytest.raises(InputError, match="last row"):
        sp.check_transform(T)
    with pytest.raises(InputError, match="unit quaternion"):
        sp.check_quaternion([1.0, 0.5, 0.0, 0.0])
    np.testing.assert_allclose(sp.check_quaternion([1.0, 1e-4, 0.0, 0.0])[0], 1.0, atol=1e-8)
