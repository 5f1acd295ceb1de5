"""In-memory measurement data: joint readings with measured tool-point positions
(`Measurements`), and repeated measurements of commanded poses (`RepeatedPoses`, the ISO
9283 tests of `kinecal.metrology.iso9283`).

Readers and writers of the files live in `kinecal.io.measurements`; the type sits below
both the file layer and the calibration layer, so that neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import check_rotation

__all__ = ["Measurements", "RepeatedPoses"]


@dataclass(frozen=True)
class Measurements:
    """Joint readings with measured tool-point positions (and optionally orientations).

    Attributes
    ----------
    q : ndarray, shape (N, n_joints)
        Joint angles (rad).
    xyz : ndarray, shape (N, 3)
        Measured tool-point positions in the measurement frame (model length unit).
    weights : ndarray, shape (N,) or None
        Optional per-pose weights (relative, > 0).
    source : str
        Where the data came from (file path or description).
    rotations : ndarray, shape (N, 3, 3) or None
        Measured tool-frame orientations in the measurement frame (6-DoF trackers, camera
        poses); None for position-only measurements.
    marker : ndarray of int, shape (N,) or None
        Which marker each pose measured (several tool points on one flange): an index into
        `marker_names`; None when the arm carries one tool point.
    marker_names : tuple of str
        Names of the markers `marker` indexes (the model's markers, in its order).
    """

    q: NDArray[np.float64]
    xyz: NDArray[np.float64]
    weights: NDArray[np.float64] | None = None
    source: str = ""
    rotations: NDArray[np.float64] | None = None
    marker: NDArray[np.intp] | None = None
    marker_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        q = np.asarray(self.q, dtype=float)
        xyz = np.asarray(self.xyz, dtype=float)
        if q.ndim != 2 or xyz.shape != (q.shape[0], 3):
            raise InputError(
                f"measurements: expected q (N, n) and xyz (N, 3), got {q.shape} and {xyz.shape}"
            )
        if not (np.isfinite(q).all() and np.isfinite(xyz).all()):
            raise InputError("measurements contain NaN or infinite values")
        if self.weights is not None:
            w = np.asarray(self.weights, dtype=float)
            if w.shape != (q.shape[0],) or not (w > 0).all():
                raise InputError("weights: expected one positive value per pose")
        if self.rotations is not None:
            R = np.asarray(self.rotations, dtype=float)
            if R.shape != (q.shape[0], 3, 3):
                raise InputError(f"rotations: expected shape ({q.shape[0]}, 3, 3), got {R.shape}")
            check_rotation(R, tol=1e-6, name="measured rotation")
        if self.marker is not None:
            m = np.asarray(self.marker)
            if m.shape != (q.shape[0],) or not np.issubdtype(m.dtype, np.integer):
                raise InputError(f"marker: expected {q.shape[0]} integer indices, got {m.shape}")
            if m.size and (m.min() < 0 or m.max() >= len(self.marker_names)):
                raise InputError(f"marker: indices must lie in 0..{len(self.marker_names) - 1} "
                                 f"(marker_names {list(self.marker_names)})")
        elif self.marker_names:
            raise InputError("marker_names without marker indices")

    def __len__(self) -> int:
        return int(np.shape(self.q)[0])

    def subset(self, index: NDArray[np.intp]) -> Measurements:
        """The poses selected by `index`."""
        w = None if self.weights is None else np.asarray(self.weights)[index]
        R = None if self.rotations is None else np.asarray(self.rotations)[index]
        m = None if self.marker is None else np.asarray(self.marker)[index]
        return Measurements(np.asarray(self.q)[index], np.asarray(self.xyz)[index], w,
                            f"{self.source}[subset]", R, m, self.marker_names)


@dataclass(frozen=True)
class RepeatedPoses:
    """Measurements of P commanded poses, each measured once in each of n cycles.

    Attributes
    ----------
    labels : tuple of str, length P
        Pose names, in the order of the test.
    cycles : ndarray of int, shape (n,)
        Cycle numbers (increasing).
    measured : ndarray, shape (P, n, 3)
        Measured positions (length unit), ``measured[i, j]`` pose i in cycle j.
    commanded : ndarray, shape (P, 3)
        Commanded positions (length unit).
    measured_rotations : ndarray, shape (P, n, 3, 3), optional
        Measured orientations (rotation matrices), None for position-only instruments.
    commanded_rotations : ndarray, shape (P, 3, 3), optional
        Commanded orientations.
    joints : ndarray, shape (P, n_joints), optional
        Commanded joint values (rad; prismatic: length unit) when the commanded poses come
        from a model's forward kinematics.
    length_unit : str
        Unit of the positions (a label).
    source : str
        Where the data came from.
    """

    labels: tuple[str, ...]
    cycles: NDArray[np.int64]
    measured: NDArray[np.float64]
    commanded: NDArray[np.float64]
    measured_rotations: NDArray[np.float64] | None = None
    commanded_rotations: NDArray[np.float64] | None = None
    joints: NDArray[np.float64] | None = None
    length_unit: str = "mm"
    source: str = ""

    def __post_init__(self) -> None:
        m = np.asarray(self.measured, dtype=float)
        p = len(self.labels)
        if m.ndim != 3 or m.shape[0] != p or m.shape[2] != 3:
            raise InputError(f"measured positions: expected shape ({p}, n, 3), got {m.shape}")
        n = m.shape[1]
        shapes = {"cycles": (np.shape(self.cycles), (n,)),
                  "commanded positions": (np.shape(self.commanded), (p, 3))}
        if self.measured_rotations is not None:
            shapes["measured orientations"] = (np.shape(self.measured_rotations), (p, n, 3, 3))
        if self.commanded_rotations is not None:
            shapes["commanded orientations"] = (np.shape(self.commanded_rotations), (p, 3, 3))
        for what, (got, want) in shapes.items():
            if got != want:
                raise InputError(f"{what}: expected shape {want}, got {got}")
        if len(set(self.labels)) != p:
            raise InputError("pose labels repeat: expected one label per pose")
        if not (np.isfinite(m).all() and np.isfinite(self.commanded).all()):
            raise InputError("positions contain NaN or infinite values")

    @property
    def n_cycles(self) -> int:
        """Number of cycles n."""
        return int(np.shape(self.measured)[1])
