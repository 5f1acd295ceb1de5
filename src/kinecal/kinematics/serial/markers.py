"""Several markers on one flange: a tool point per marker, all identified together.

A laser tracker often measures two or three reflectors (SMRs) on the flange, or a camera
sees several targets; every measurement row says which marker it saw. The model then has,
instead of one tool point ``tool.x, tool.y, tool.z``, one per marker ``tool.NAME.x,
tool.NAME.y, tool.NAME.z`` (flange frame, length unit), in the order the markers are
declared.

One mechanism carries it through the kinematics: the chain's three tool translations
``Tx Ty Tz`` take a *per-pose* value, the coordinates of the marker each pose saw
(`MarkerSet.pose_values`, handed to the FK kernels like a joint reading), and their
identification-Jacobian columns are masked by marker (`MarkerSet.fill_jacobian`: the
column of ``tool.A.x`` is the flange's x axis on poses that saw A and zero elsewhere).
Everything above the kinematics passes a per-pose marker index array ``(N,)`` (0-based,
into `SerialModel.marker_names`) next to the joint readings; None means every pose saw
the first marker.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["MarkerSet", "check_marker", "check_markers", "marker_parameter_names",
           "marker_points", "model_for_markers", "remap_markers", "with_markers"]

Array = NDArray[np.float64]


def marker_parameter_names(name: str) -> tuple[str, str, str]:
    """``tool.NAME.x, tool.NAME.y, tool.NAME.z``: the tool point of marker `name`."""
    return (f"tool.{name}.x", f"tool.{name}.y", f"tool.{name}.z")


def check_markers(markers: Mapping) -> dict[str, Array]:
    """Validated ``{name: (3,) point}`` in declaration order.

    Raises
    ------
    InputError
        No markers, a bad name (empty, spaces, commas, quotes) or a point that is not three
        finite numbers.
    """
    if not isinstance(markers, Mapping) or not markers:
        raise InputError("markers: expected a mapping of marker names to [x, y, z]")
    out: dict[str, Array] = {}
    for name, point in markers.items():
        if not isinstance(name, str | int) or isinstance(name, bool):
            raise InputError(f"markers: name {name!r}: expected a name or a number")
        name = str(name)
        if not name or any(c in name for c in ", \t\n\"'"):
            raise InputError(f"markers: name {name!r}: expected a non-empty name without "
                             "spaces, commas or quotes")
        try:
            p = np.asarray(point, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise InputError(f"markers: {name}: expected [x, y, z], got {point!r}") from None
        if not np.isfinite(p).all():
            raise InputError(f"markers: {name}: expected finite numbers, got {p.tolist()}")
        if name in out:
            raise InputError(f"markers: {name} is declared twice")
        out[name] = p
    return out


@dataclass(frozen=True)
class MarkerSet:
    """The markers of a model and where they sit in its parameter vector and motions.

    Attributes
    ----------
    names : tuple of str
        Marker names, in declaration order (marker index = position).
    params : ndarray, shape (M, 3)
        Parameter index of ``tool.NAME.x, .y, .z`` per marker.
    motions : tuple of 3 int
        Positions of the tool translations ``Tx, Ty, Tz`` in the model's motions.
    """

    names: tuple[str, ...]
    params: NDArray[np.intp]
    motions: tuple[int, int, int]

    def indices(self, marker: ArrayLike | None, n: int) -> NDArray[np.intp]:
        """Per-pose marker indices ``(n,)`` (None: the first marker everywhere)."""
        if marker is None:
            return np.zeros(n, dtype=np.intp)
        m = np.asarray(marker)
        if m.shape != (n,) or not np.issubdtype(m.dtype, np.integer):
            raise InputError(f"marker: expected {n} integer marker indices (one per pose), "
                             f"got shape {m.shape} of {m.dtype}")
        if m.size and (m.min() < 0 or m.max() >= len(self.names)):
            raise InputError(f"marker: indices must lie in 0..{len(self.names) - 1} "
                             f"({', '.join(self.names)}), got {m.min()}..{m.max()}")
        return m.astype(np.intp, copy=False)

    def pose_values(self, marker: NDArray[np.intp], p: Array) -> dict[int, Array]:
        """Per-pose values of the tool translations: motion position -> ``(*batch, N)``."""
        return {i: p[..., self.params[marker, c]] for c, i in enumerate(self.motions)}

    def fill_jacobian(self, Jt: Array, frames: list, row_of: NDArray[np.intp],
                      marker: NDArray[np.intp]) -> None:
        """Write the masked marker columns into `Jt` ``(k, rows, n)`` in place.

        `row_of` maps a parameter index to its row of `Jt` (-1: not wanted); `frames` are the
        sweep's (axis, origin) per motion; a tool translation moves the point of the poses
        that saw its marker along the flange axis, and nothing else.
        """
        for c, i in enumerate(self.motions):
            u = frames[i][0]
            for m in range(len(self.names)):
                r = row_of[self.params[m, c]]
                if r < 0:
                    continue
                mask = marker == m
                for k in range(3):
                    Jt[r, k] = u[k] * mask
                Jt[r, 3:] = 0.0


def marker_points(markers: Sequence[str], values: Mapping[str, float]) -> dict[str, list]:
    """``{name: [x, y, z]}`` of `markers` from parameter `values` (by name)."""
    return {n: [float(values[p]) for p in marker_parameter_names(n)] for n in markers}


def check_marker(model: SerialModel, marker: ArrayLike | None, n: int
                 ) -> NDArray[np.intp] | None:
    """Checked per-pose marker indices ``(n,)`` for `model` (None: one tool point)."""
    if model._marker_set is None:
        if marker is not None:
            raise InputError(f"marker: model {model.name!r} has one tool point, no markers "
                             "(declare them: markers: {NAME: [x, y, z], ...})")
        return None
    return model._marker_set.indices(marker, n)


def with_markers(model: SerialModel, markers: Mapping | Sequence[str]) -> SerialModel:
    """`model` with several markers instead of one tool point.

    `markers` is ``{name: [x, y, z]}``, or names, each then starting at the model's tool
    point (the flange origin without one). A tool frame (6 values) cannot take markers.
    """
    tool = np.zeros(3) if model.tool is None else np.asarray(model.tool, dtype=float)
    if tool.size == 6:
        raise InputError(f"model {model.name!r} has a tool frame (6 values): markers are "
                         "tool points")
    if not isinstance(markers, Mapping):
        markers = {str(n): tool.tolist() for n in markers}
    return dataclasses.replace(
        model, tool=None, markers=dict(markers), joint_limits=np.array(model.joint_limits),
        tolerances=dict(model.tolerances or {}),
        fixed=tuple(f for f in model.fixed if not f.startswith("tool.")))


def remap_markers(marker: ArrayLike | None, names: Sequence[str], model_names: Sequence[str]
                  ) -> NDArray[np.intp] | None:
    """Marker indices into `names` turned into indices into `model_names` (by name)."""
    if marker is None:
        return None
    lookup = {n: i for i, n in enumerate(model_names)}
    missing = [n for n in names if n not in lookup]
    if missing:
        raise InputError(f"marker {missing[0]!r} is not a marker of the model "
                         f"({', '.join(model_names) or 'none'})")
    table = np.array([lookup[n] for n in names], dtype=np.intp)
    return table[np.asarray(marker, dtype=np.intp)]


def model_for_markers(model: SerialModel, names: Sequence[str]) -> SerialModel:
    """The model that measurements with markers `names` (indices into them) need.

    `model` itself when it has no markers in use or exactly these; a model without
    markers gets one tool point per name (`with_markers`); otherwise `InputError`.
    """
    names = tuple(names)
    if not names or model.marker_names == names:
        return model
    if not model.marker_names:
        return with_markers(model, names)
    raise InputError(f"the measurements' markers {', '.join(names)} are not the markers of "
                     f"model {model.name!r} ({', '.join(model.marker_names)})")
