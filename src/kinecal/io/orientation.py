"""Named Euler conventions: rotation matrices, and the rates that turn the standard
deviations of three Euler angles into those of the small rotation about fixed axes.

A convention is ``intrinsic-SEQ`` or ``extrinsic-SEQ`` with ``SEQ`` three axes out of
``x, y, z`` (no axis twice in a row: the six Tait-Bryan sequences such as ``xyz`` and the
six proper Euler sequences such as ``zxz``), the angles ``(a, b, c)`` in sequence order:

* ``intrinsic-xyz``: ``R = Rx(a) Ry(b) Rz(c)`` (about the moving frame's axes; Leica's
  T-Mac writes its orientation so, scipy ``Rotation.from_euler("XYZ", ...)``);
* ``extrinsic-xyz``: ``R = Rz(c) Ry(b) Rx(a)`` (about the fixed frame's axes; scipy
  ``"xyz"``; the same matrix as roll-pitch-yaw).

kinecal's older names stay: ``euler-zyx`` is ``intrinsic-zyx`` (KUKA A, B, C) and ``rpy``
is ``extrinsic-xyz`` with the columns ``roll, pitch, yaw`` (`kinecal.io.poses`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.spatial import rot_x, rot_y, rot_z

__all__ = ["EULER_COLUMNS", "EULER_FORMATS", "euler_matrix", "euler_rates", "euler_spec",
           "rotation_sigma"]

Array = NDArray[np.float64]

#: the twelve axis sequences (no axis twice in a row)
SEQUENCES = tuple(a + b + c for a in "xyz" for b in "xyz" for c in "xyz" if a != b != c)
#: every named convention -> (sequence, intrinsic)
EULER_FORMATS: dict[str, tuple[str, bool]] = {
    f"{kind}-{seq}": (seq, kind == "intrinsic")
    for kind in ("intrinsic", "extrinsic") for seq in SEQUENCES}
#: the older names of `kinecal.io.poses` that are Euler conventions
ALIASES = {"euler-zyx": ("zyx", True), "rpy": ("xyz", False)}
#: the angle columns of a named convention, in sequence order
EULER_COLUMNS = ("a", "b", "c")
_ROT = {"x": rot_x, "y": rot_y, "z": rot_z}
_AXIS = {"x": 0, "y": 1, "z": 2}


def euler_spec(name: str) -> tuple[str, bool]:
    """``(sequence, intrinsic)`` of a named convention (or of an older alias)."""
    spec = EULER_FORMATS.get(name) or ALIASES.get(name)
    if spec is None:
        raise InputError(f"Euler convention {name!r}: expected intrinsic-SEQ or extrinsic-SEQ "
                         "with SEQ such as xyz, zyx or zxz")
    return spec


def euler_matrix(angles: ArrayLike, seq: str, intrinsic: bool) -> Array:
    """Rotations ``(..., 3, 3)`` from angles ``(..., 3)`` (rad) of sequence `seq`."""
    a = np.asarray(angles, dtype=float)
    R = [_ROT[ax](a[..., k]) for k, ax in enumerate(seq)]
    return R[0] @ R[1] @ R[2] if intrinsic else R[2] @ R[1] @ R[0]


def euler_rates(angles: ArrayLike, seq: str, intrinsic: bool) -> Array:
    """``E`` ``(..., 3, 3)``: the small rotation about the fixed frame's axes is
    ``E @ (da, db, dc)`` for small changes of the angles (column k: the axis of angle k
    in the fixed frame)."""
    a = np.asarray(angles, dtype=float)
    R = [_ROT[ax](a[..., k]) for k, ax in enumerate(seq)]
    e = [np.eye(3)[_AXIS[ax]] for ax in seq]
    if intrinsic:  # R0 R1 R2: e0, R0 e1, R0 R1 e2
        cols = [np.broadcast_to(e[0], a.shape), R[0] @ e[1], R[0] @ R[1] @ e[2]]
    else:  # R2 R1 R0: R2 R1 e0, R2 e1, e2
        cols = [R[2] @ R[1] @ e[0], R[2] @ e[1], np.broadcast_to(e[2], a.shape)]
    return np.stack(cols, axis=-1)


def rotation_sigma(fmt: str, angles: Array | None, sigma: Array) -> Array:
    """Standard deviations ``(N, 3)`` (rad) of the small rotation about the measurement
    frame's x, y, z axes from those of the file's three orientation values `sigma`
    ``(N, 3)`` (rad).

    Euler formats (`EULER_FORMATS`, ``euler-zyx``, ``rpy``): first-order propagation,
    ``Sigma = E diag(sigma^2) E^T`` (`euler_rates` at the measured `angles` ``(N, 3)``),
    and the square roots of its diagonal (the correlations are not kept). Other formats
    (quaternions): `sigma` is already about the measurement axes.
    """
    if fmt not in EULER_FORMATS and fmt not in ALIASES:
        return np.asarray(sigma, dtype=float)
    E = euler_rates(angles, *euler_spec(fmt))
    var = np.einsum("nij,nj,nij->ni", E, np.square(sigma), E)
    return np.sqrt(var)
