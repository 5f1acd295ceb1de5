"""Rotations, quaternions and homogeneous transforms, batched over leading axes.

Conventions (see ``docs/conventions.md``):

* active rotations; a transform named ``a2b`` maps coordinates in frame *a* to frame *b*
  (it is the pose of *a* in *b*);
* quaternions are ``(w, x, y, z)``; functions returning quaternions pick ``w >= 0``;
* roll-pitch-yaw angles ``(rx, ry, rz)`` mean ``R = Rz(rz) @ Ry(ry) @ Rx(rx)``;
* a position + quaternion pose ``pq`` is ``(x, y, z, qw, qx, qy, qz)``.

Every function accepts arrays with arbitrary leading (batch) axes: a rotation stack has
shape ``(..., 3, 3)``, a transform stack ``(..., 4, 4)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

__all__ = [
    "axis_angle_from_matrix",
    "check_quaternion",
    "check_rotation",
    "check_transform",
    "invert_transform",
    "left_jacobian_inverse",
    "matrix_from_axis_angle",
    "matrix_from_quaternion",
    "matrix_from_rpy",
    "pose_errors",
    "pq_from_transform",
    "project_to_rotation",
    "quaternion_from_matrix",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_angle",
    "rpy_from_matrix",
    "skew",
    "transform_from",
    "transform_from_pq",
    "transform_from_xyz_rpy",
    "xyz_rpy_from_transform",
]

Array = NDArray[np.float64]


# --------------------------------------------------------------------------- elementary
def _elementary(angle: ArrayLike, i: int, j: int) -> Array:
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    k = 3 - i - j
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def rot_x(angle: ArrayLike) -> Array:
    """Rotation about x by `angle` (rad, shape ``(...)``) -> ``(..., 3, 3)``."""
    return _elementary(angle, 1, 2)


def rot_y(angle: ArrayLike) -> Array:
    """Rotation about y by `angle` (rad, shape ``(...)``) -> ``(..., 3, 3)``."""
    return _elementary(angle, 2, 0)


def rot_z(angle: ArrayLike) -> Array:
    """Rotation about z by `angle` (rad, shape ``(...)``) -> ``(..., 3, 3)``."""
    return _elementary(angle, 0, 1)


def skew(v: ArrayLike) -> Array:
    """Cross-product matrix of `v` ``(..., 3)`` -> ``(..., 3, 3)`` with ``skew(v) @ u = v x u``."""
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


# --------------------------------------------------------------------------- validators
def check_rotation(R: ArrayLike, tol: float = 1e-6, name: str = "rotation") -> Array:
    """Validate a stack of rotation matrices ``(..., 3, 3)``.

    Raises
    ------
    InputError
        If the shape is wrong, entries are not finite, ``R^T R`` differs from identity by
        more than `tol`, or ``det(R) <= 0``. The message names the first offending index.
    """
    R = np.asarray(R, dtype=float)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise InputError(f"{name}: expected shape (..., 3, 3), got {R.shape}")
    flat = R.reshape(-1, 3, 3)
    bad = ~np.isfinite(flat).all(axis=(1, 2))
    if bad.any():
        raise InputError(f"{name} {int(np.argmax(bad))}: contains NaN or infinite values")
    err = np.abs(flat.transpose(0, 2, 1) @ flat - np.eye(3)).max(axis=(1, 2))
    if (err > tol).any():
        i = int(np.argmax(err > tol))
        raise InputError(
            f"{name} {i}: not orthonormal (max |R^T R - I| = {err[i]:.2e}, expected <= {tol:g})"
        )
    det = np.linalg.det(flat)
    if (det <= 0).any():
        i = int(np.argmax(det <= 0))
        raise InputError(f"{name} {i}: determinant {det[i]:.3f}, expected +1 (a reflection)")
    return R


def check_transform(T: ArrayLike, tol: float = 1e-6, name: str = "transform") -> Array:
    """Validate a stack of homogeneous transforms ``(..., 4, 4)``; see `check_rotation`."""
    T = np.asarray(T, dtype=float)
    if T.ndim < 2 or T.shape[-2:] != (4, 4):
        raise InputError(f"{name}: expected shape (..., 4, 4), got {T.shape}")
    if not np.isfinite(T).all():
        raise InputError(f"{name}: contains NaN or infinite values")
    last = np.abs(T[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).reshape(-1, 4).max(axis=1)
    if (last > tol).any():
        i = int(np.argmax(last > tol))
        raise InputError(f"{name} {i}: last row must be (0, 0, 0, 1)")
    check_rotation(T[..., :3, :3], tol, name)
    return T


def check_quaternion(q: ArrayLike, tol: float = 1e-3, name: str = "quaternion") -> Array:
    """Validate quaternions ``(..., 4)`` (w, x, y, z) of unit norm within `tol`.

    Returns the normalised quaternions.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim < 1 or q.shape[-1] != 4:
        raise InputError(f"{name}: expected shape (..., 4) as (w, x, y, z), got {q.shape}")
    if not np.isfinite(q).all():
        raise InputError(f"{name}: contains NaN or infinite values")
    norm = np.linalg.norm(q, axis=-1)
    flat = norm.reshape(-1)
    if (np.abs(flat - 1.0) > tol).any():
        i = int(np.argmax(np.abs(flat - 1.0) > tol))
        raise InputError(f"{name} {i}: norm {flat[i]:.6f}, expected a unit quaternion")
    return q / norm[..., None]


# --------------------------------------------------------------------------- conversions
def matrix_from_quaternion(q: ArrayLike) -> Array:
    """Rotation matrices ``(..., 3, 3)`` from quaternions ``(..., 4)`` (w, x, y, z).

    The quaternion is normalised first.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def quaternion_from_matrix(R: ArrayLike) -> Array:
    """Quaternions ``(..., 4)`` (w, x, y, z), ``w >= 0``, from rotations ``(..., 3, 3)``.

    Uses the numerically stable branch (largest diagonal element) per matrix: the largest
    component first, ``s = 2 sqrt(1 + 2 q_k^2 - 1)``, the others from off-diagonal sums or
    differences over ``s``. Branch-free (every matrix picks its components from one table),
    so that small stacks cost a fixed, small number of numpy calls.
    """
    R = np.asarray(R, dtype=float)
    shape = R.shape[:-2]
    M = R.reshape(-1, 3, 3)
    m00, m01, m02 = M[:, 0, 0], M[:, 0, 1], M[:, 0, 2]
    m10, m11, m12 = M[:, 1, 0], M[:, 1, 1], M[:, 1, 2]
    m20, m21, m22 = M[:, 2, 0], M[:, 2, 1], M[:, 2, 2]
    tr = np.trace(M, axis1=1, axis2=2)
    k = np.argmax(np.stack([tr, m00, m11, m22], axis=1), axis=1)
    # 1 + 2 q_k^2 - 1 for each branch k (w, x, y, z largest), the chosen one per matrix
    diag = np.stack([1.0 + tr, 1.0 + m00 - m11 - m22, 1.0 + m11 - m00 - m22,
                     1.0 + m22 - m00 - m11], axis=1)
    rows = np.arange(M.shape[0])
    s = 2.0 * np.sqrt(np.maximum(diag[rows, k], 0.0))
    W = np.empty((M.shape[0], 7))
    W[:, 0] = m21 - m12
    W[:, 1] = m02 - m20
    W[:, 2] = m10 - m01
    W[:, 3] = m01 + m10
    W[:, 4] = m02 + m20
    W[:, 5] = m12 + m21
    W[:, :6] /= s[:, None]
    W[:, 6] = 0.25 * s
    q = W[rows[:, None], _QUAT_TABLE[k]]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1.0
    return q.reshape(shape + (4,))


#: columns of W (see `quaternion_from_matrix`) that make (w, x, y, z) in each branch
_QUAT_TABLE = np.array([[6, 0, 1, 2], [0, 6, 3, 4], [1, 3, 6, 5], [2, 4, 5, 6]])


def matrix_from_axis_angle(rotvec: ArrayLike) -> Array:
    """Rodrigues: rotation vectors ``(..., 3)`` (axis * angle, rad) -> ``(..., 3, 3)``."""
    v = np.asarray(rotvec, dtype=float)
    theta = np.linalg.norm(v, axis=-1)
    small = theta < 1e-8
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(theta) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(theta)) / safe**2)
    K = skew(v)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def axis_angle_from_matrix(R: ArrayLike) -> Array:
    """Logarithm map: rotations ``(..., 3, 3)`` -> rotation vectors ``(..., 3)`` (rad).

    Goes through the quaternion, which stays accurate near 0 and near pi.
    """
    return axis_angle_from_quaternion(quaternion_from_matrix(R))


def axis_angle_from_quaternion(q: ArrayLike) -> Array:
    """Rotation vectors ``(..., 3)`` (rad) of unit quaternions ``(..., 4)`` (w, x, y, z)."""
    q = np.asarray(q, dtype=float)
    w = np.clip(q[..., 0], -1.0, 1.0)
    vn = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(vn, w)
    small = vn < 1e-12
    scale = np.where(small, 2.0, angle / np.where(small, 1.0, vn))
    return q[..., 1:] * scale[..., None]


def left_jacobian_inverse(rotvec: ArrayLike) -> Array:
    """Inverse left Jacobian of SO(3) at rotation vectors ``(..., 3)`` -> ``(..., 3, 3)``.

    ``log(exp(d) exp(e)) = e + J_l^-1(e) d + O(|d|^2)``: how a rotation error
    ``e = log(R R_ref^T)`` changes when ``R`` is rotated by a small ``d`` (in the reference
    frame). ``J_l^-1 = I - [e]x / 2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [e]x^2``, t = |e|.
    """
    e = np.asarray(rotvec, dtype=float)
    t = np.linalg.norm(e, axis=-1)
    small = t < 1e-6
    ts = np.where(small, 1.0, t)
    c = np.where(small, 1.0 / 12.0 + t**2 / 720.0,
                 1.0 / ts**2 - (1.0 + np.cos(ts)) / (2.0 * ts * np.sin(ts)))
    K = skew(e)
    return np.eye(3) - 0.5 * K + c[..., None, None] * (K @ K)


def rotation_angle(R: ArrayLike) -> Array:
    """Geodesic angle (rad, in ``[0, pi]``) of rotations ``(..., 3, 3)``."""
    return np.linalg.norm(axis_angle_from_matrix(R), axis=-1)


def matrix_from_rpy(rpy: ArrayLike) -> Array:
    """``Rz(rz) @ Ry(ry) @ Rx(rx)`` from angles ``(..., 3)`` = (rx, ry, rz) in rad."""
    a = np.asarray(rpy, dtype=float)
    return rot_z(a[..., 2]) @ rot_y(a[..., 1]) @ rot_x(a[..., 0])


def rpy_from_matrix(R: ArrayLike) -> Array:
    """Inverse of `matrix_from_rpy`: ``(..., 3, 3)`` -> (rx, ry, rz) ``(..., 3)``.

    ``ry`` is returned in ``[-pi/2, pi/2]``. Accurate to round-off everywhere, also next to
    ``ry = +-pi/2`` (URDF tool frames are often at pitch ``pi/2``): ``ry`` comes from
    ``atan2`` (not ``arcsin``), ``rz`` from the first column, and ``rx`` from what is left
    of ``R`` after undoing ``rz`` and ``ry``, so that ``matrix_from_rpy`` reproduces ``R``
    to round-off even where ``rx`` and ``rz`` are not separable (gimbal lock).
    """
    R = np.asarray(R, dtype=float)
    ry = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    rz = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    cz, sz, cy, sy = np.cos(rz), np.sin(rz), np.cos(ry), np.sin(ry)
    # M = Ry(ry)^T Rz(rz)^T R = Rx(rx): rx from M[2, 1] and M[1, 1]
    a01 = cz * R[..., 0, 1] + sz * R[..., 1, 1]
    a11 = cz * R[..., 1, 1] - sz * R[..., 0, 1]
    rx = np.arctan2(sy * a01 + cy * R[..., 2, 1], a11)
    return np.stack([rx, ry, rz], axis=-1)


def project_to_rotation(M: ArrayLike) -> Array:
    """Nearest proper rotation (Frobenius norm) to each ``(..., 3, 3)`` matrix, by SVD."""
    M = np.asarray(M, dtype=float)
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones(M.shape[:-2] + (3,))
    D[..., 2] = d
    return (U * D[..., None, :]) @ Vt


# --------------------------------------------------------------------------- transforms
def transform_from(R: ArrayLike, t: ArrayLike) -> Array:
    """Transforms ``(..., 4, 4)`` from rotations ``(..., 3, 3)`` and translations ``(..., 3)``."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    shape = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert_transform(T: ArrayLike) -> Array:
    """Inverse of rigid transforms ``(..., 4, 4)``: ``b2a`` from ``a2b``."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return transform_from(Rt, -(Rt @ T[..., :3, 3:4])[..., 0])


def transform_from_pq(pq: ArrayLike) -> Array:
    """Transforms ``(..., 4, 4)`` from poses ``(..., 7)`` = (x, y, z, qw, qx, qy, qz)."""
    pq = np.asarray(pq, dtype=float)
    return transform_from(matrix_from_quaternion(pq[..., 3:]), pq[..., :3])


def pq_from_transform(T: ArrayLike) -> Array:
    """Poses ``(..., 7)`` = (x, y, z, qw, qx, qy, qz), ``qw >= 0``, from ``(..., 4, 4)``."""
    T = np.asarray(T, dtype=float)
    return np.concatenate([T[..., :3, 3], quaternion_from_matrix(T[..., :3, :3])], axis=-1)


def transform_from_xyz_rpy(v: ArrayLike) -> Array:
    """Transforms ``(..., 4, 4)`` from ``(..., 6)`` = (x, y, z, rx, ry, rz), R = Rz Ry Rx."""
    v = np.asarray(v, dtype=float)
    return transform_from(matrix_from_rpy(v[..., 3:]), v[..., :3])


def xyz_rpy_from_transform(T: ArrayLike) -> Array:
    """Inverse of `transform_from_xyz_rpy`: ``(..., 4, 4)`` -> ``(..., 6)``."""
    T = np.asarray(T, dtype=float)
    return np.concatenate([T[..., :3, 3], rpy_from_matrix(T[..., :3, :3])], axis=-1)


def pose_errors(T_est: ArrayLike, T_ref: ArrayLike) -> tuple[Array, Array]:
    """Rotation and translation errors between transform stacks ``(..., 4, 4)``.

    Returns
    -------
    rotation : ndarray, shape (...)
        Geodesic angle of ``R_ref^T R_est`` in radians.
    translation : ndarray, shape (...)
        Euclidean distance between the translations (length unit of the inputs).
    """
    T_est = np.asarray(T_est, dtype=float)
    T_ref = np.asarray(T_ref, dtype=float)
    dR = np.swapaxes(T_ref[..., :3, :3], -1, -2) @ T_est[..., :3, :3]
    return rotation_angle(dR), np.linalg.norm(T_est[..., :3, 3] - T_ref[..., :3, 3], axis=-1)
