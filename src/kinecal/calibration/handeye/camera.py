"""Pinhole camera with OpenCV's lens distortion, in numpy, with analytic Jacobians.

The model is OpenCV's (``cv2.projectPoints``) with up to 8 distortion coefficients
``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``: for a point ``P = (X, Y, Z)`` in the camera frame,
``x = X/Z, y = Y/Z, r^2 = x^2 + y^2``,

    f  = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
    x' = x f + 2 p1 x y + p2 (r^2 + 2 x^2)
    y' = y f + p1 (r^2 + 2 y^2) + 2 p2 x y
    u  = fx x' + s y' + cx,   v = fy y' + cy          (s: skew, K[0, 1]; usually 0)

Pixel coordinates follow OpenCV: integer values are pixel centres. The intrinsic
parameter vector used by the refinements is ``(fx, fy, cx, cy, k1, k2, p1, p2, k3)`` and,
for the rational model (8 coefficients), ``k4, k5, k6`` after it. OpenCV's thin-prism and
tilted models (12 and 14 coefficients) are not supported.

Kept free of OpenCV so that the hand-eye refinement runs on the core install; the tests
check it against ``cv2.projectPoints`` and finite differences.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = [
    "INTRINSIC_NAMES",
    "check_camera",
    "check_intrinsics_determined",
    "intrinsic_vector",
    "project",
    "project_jacobian",
    "with_intrinsics",
]

#: names of the intrinsic parameter vector (first 9; the rational model adds k4, k5, k6)
INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


def check_camera(K: ArrayLike, dist: ArrayLike | None) -> tuple[Array, Array]:
    """Validate a camera matrix ``(3, 3)`` and distortion coefficients; return ``(K, d8)``.

    ``d8`` is the distortion padded with zeros to 8 coefficients
    ``(k1, k2, p1, p2, k3, k4, k5, k6)``.

    Raises
    ------
    InputError
        K not upper triangular with positive focal lengths and ``K[2] = (0, 0, 1)``, NaN
        values, or more than 8 (non-zero) distortion coefficients.
    """
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3) or not np.isfinite(K).all():
        raise InputError(f"camera matrix: expected a finite 3x3 matrix, got shape {K.shape}")
    if K[0, 0] <= 0 or K[1, 1] <= 0 or abs(K[1, 0]) + abs(K[2, 0]) + abs(K[2, 1]) > 0 \
            or abs(K[2, 2] - 1.0) > 1e-9:
        raise InputError("camera matrix: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                         "with fx, fy > 0")
    d = np.zeros(0) if dist is None else np.asarray(dist, dtype=float).ravel()
    if not np.isfinite(d).all():
        raise InputError("distortion coefficients contain NaN or infinite values")
    if d.size > 8:
        if np.any(d[8:] != 0):
            raise InputError(f"{d.size} distortion coefficients with non-zero thin-prism or "
                             "tilt terms: only OpenCV's 4, 5 or 8 coefficient models are "
                             "supported")
        d = d[:8]
    d8 = np.zeros(8)
    d8[: d.size] = d
    return K, d8


def intrinsic_vector(K: Array, dist8: Array, rational: bool = False) -> Array:
    """``(fx, fy, cx, cy, k1, k2, p1, p2, k3[, k4, k5, k6])`` from K and 8 coefficients."""
    v = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], *dist8[:5]])
    return np.concatenate([v, dist8[5:8]]) if rational else v


def with_intrinsics(K: Array, dist8: Array, p: Array) -> tuple[Array, Array]:
    """``(K, dist8)`` with the intrinsic vector `p` (9 or 12 values) put in; skew kept."""
    K = K.copy()
    K[0, 0], K[1, 1], K[0, 2], K[1, 2] = p[:4]
    d = dist8.copy()
    d[: len(p) - 4] = p[4:]
    return K, d


def _distort(x: Array, y: Array, d: Array) -> tuple[Array, ...]:
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    r2 = x * x + y * y
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    f = num / den
    xd = x * f + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * f + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd, r2, num, den, f


def project(K: ArrayLike, dist: ArrayLike | None, P: ArrayLike) -> Array:
    """Pixel coordinates ``(..., 2)`` of camera-frame points ``(..., 3)`` (length unit any).

    Points at or behind the camera (Z <= 0) give NaN.
    """
    K, d = check_camera(K, dist)
    P = np.asarray(P, dtype=float)
    Z = P[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(Z > 0, P[..., 0] / Z, np.nan)
        y = np.where(Z > 0, P[..., 1] / Z, np.nan)
    xd, yd = _distort(x, y, d)[:2]
    return np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1)


def project_jacobian(
    K: Array, dist8: Array, P: Array, rational: bool = False, jacobians: bool = True,
    intrinsics: bool = True,
) -> tuple[Array, Array | None, Array | None]:
    """Projection of points ``(N, 3)`` and its Jacobians.

    Parameters
    ----------
    K : ndarray, shape (3, 3)
    dist8 : ndarray, shape (8,)
        ``(k1, k2, p1, p2, k3, k4, k5, k6)`` (see `check_camera`).
    P : ndarray, shape (N, 3)
        Camera-frame points, Z > 0.
    rational : bool
        Include ``k4, k5, k6`` in the intrinsic Jacobian (12 columns instead of 9).
    jacobians : bool
        False: the pixels only (both Jacobians None).
    intrinsics : bool
        False: no intrinsic Jacobian (None; callers with the intrinsics held).

    Returns
    -------
    uv : ndarray, shape (N, 2)
        Pixels.
    J_point : ndarray, shape (N, 2, 3)
        ``d uv / d P`` (pixel per length unit).
    J_intrinsics : ndarray, shape (N, 2, 9) or (N, 2, 12)
        ``d uv / d (fx, fy, cx, cy, k1, k2, p1, p2, k3[, k4, k5, k6])``.
    """
    k1, k2, p1, p2, k3, k4, k5, k6 = dist8
    fx, s, fy = K[0, 0], K[0, 1], K[1, 1]
    Z = P[:, 2]
    x, y = P[:, 0] / Z, P[:, 1] / Z
    xd, yd, r2, num, den, f = _distort(x, y, dist8)
    uv = np.stack([fx * xd + s * yd + K[0, 2], fy * yd + K[1, 2]], axis=-1)
    if not jacobians:
        return uv, None, None
    # d f / d r2
    dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
    dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
    fr = (dnum * den - num * dden) / (den * den)
    dxd_dx = f + 2.0 * x * x * fr + 2.0 * p1 * y + 6.0 * p2 * x
    dxd_dy = 2.0 * x * y * fr + 2.0 * p1 * x + 2.0 * p2 * y
    dyd_dx = dxd_dy
    dyd_dy = f + 2.0 * y * y * fr + 6.0 * p1 * y + 2.0 * p2 * x
    # d uv / dP = Juv (2x2) . Jd (2x2) . d(x, y)/dP (2x3), written out elementwise
    iz = 1.0 / Z
    a00 = fx * dxd_dx + s * dyd_dx  # d u / d x
    a01 = fx * dxd_dy + s * dyd_dy  # d u / d y
    a10 = fy * dyd_dx
    a11 = fy * dyd_dy
    n = len(P)
    J_point = np.empty((n, 2, 3))
    J_point[:, 0, 0] = a00 * iz
    J_point[:, 0, 1] = a01 * iz
    J_point[:, 0, 2] = -(a00 * x + a01 * y) * iz
    J_point[:, 1, 0] = a10 * iz
    J_point[:, 1, 1] = a11 * iz
    J_point[:, 1, 2] = -(a10 * x + a11 * y) * iz
    if not intrinsics:
        return uv, J_point, None
    # intrinsics: d(xd, yd) / d coefficient, then through Juv
    r4, r6 = r2 * r2, r2 * r2 * r2
    cols = [
        (x * r2 / den, y * r2 / den),  # k1
        (x * r4 / den, y * r4 / den),  # k2
        (2.0 * x * y, r2 + 2.0 * y * y),  # p1
        (r2 + 2.0 * x * x, 2.0 * x * y),  # p2
        (x * r6 / den, y * r6 / den),  # k3
    ]
    if rational:
        g = -num / (den * den)
        cols += [(x * g * r2, y * g * r2), (x * g * r4, y * g * r4), (x * g * r6, y * g * r6)]
    nk = 4 + len(cols)
    J_int = np.zeros((n, 2, nk))
    J_int[:, 0, 0] = xd
    J_int[:, 1, 1] = yd
    J_int[:, 0, 2] = 1.0
    J_int[:, 1, 3] = 1.0
    for k, (ax, ay) in enumerate(cols):
        J_int[:, 0, 4 + k] = fx * ax + s * ay
        J_int[:, 1, 4 + k] = fy * ay
    return uv, J_point, J_int


#: ``intrinsics-weak`` beyond these 1-sigma uncertainties of intrinsics estimated from the
#: views: the focal length relative to itself, the principal point relative to the image
#: width (a good camera calibration: 0.1-0.3 % and 1-3 px on a 640 px image)
WEAK_FOCAL = 0.005
WEAK_CENTRE = 0.005


def check_intrinsics_determined(cov: Array, names: list[str], K: Array,
                                size: tuple[int, int] | None) -> bool:
    """``intrinsics-weak``: intrinsics estimated from views that leave the focal length or
    the principal point poorly determined (`WEAK_FOCAL`, `WEAK_CENTRE`; nearly face-on
    views confound the focal length with the distance, and X's translation with both).
    `cov` ``(p, p)`` is the covariance of the unknowns `names` (``fx`` ... among them).
    Returns True when it warned."""
    from kinecal import diagnostics

    if "fx" not in names:
        return False
    k = names.index("fx")
    sd = np.sqrt(np.clip(np.diag(cov)[k:k + 4], 0.0, None))
    width = float(size[0]) if size else 2.0 * float(K[0, 2])
    f = float(np.sqrt(K[0, 0] * K[1, 1]))
    rel_f = float(max(sd[0] / K[0, 0], sd[1] / K[1, 1]))
    c = float(max(sd[2], sd[3]))
    if not (rel_f > WEAK_FOCAL or c > WEAK_CENTRE * width):
        return False
    # X's translation sigma with the intrinsics' uncertainty and without it (conditional)
    idx = np.arange(k, len(names))
    C = cov[np.ix_(idx, idx)]
    Xk = cov[3:6][:, idx]
    try:
        cond = cov[3:6, 3:6] - Xk @ np.linalg.solve(C, Xk.T)
    except np.linalg.LinAlgError:
        cond = cov[3:6, 3:6]
    full = float(np.sqrt(np.trace(cov[3:6, 3:6])))
    own = float(np.sqrt(max(np.trace(cond), 0.0)))
    diagnostics.warn("intrinsics-weak",
                     f"the views leave the intrinsics estimated from them poorly determined "
                     f"(1 sigma: focal length {max(sd[0], sd[1]):.3g} px = {100 * rel_f:.2g} % "
                     f"of {f:.4g} px, principal point {c:.3g} px): X moves with them, its "
                     f"translation sigma {full:.3g} instead of {own:.3g} with the intrinsics "
                     "known; add views tilted 30-45 deg about both board axes and at several "
                     "distances, or give --intrinsics from a camera calibration")
    return True
