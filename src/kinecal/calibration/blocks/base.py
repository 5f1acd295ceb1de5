"""`ResidualBlock`: the residuals of one measurement set over the arm and its own unknowns.

A calibration problem is a stack of residual blocks over shared parameter blocks
(`kinecal.calibration.blocks.stack`): the arm's free parameters, which every block sees,
and each block's *nuisance* parameters, which only that block sees (a ballbar's pivot, a
socket's point, a plane; for a camera: its mount, the board pose, the intrinsics). A new
measurement kind is a new subclass of `ResidualBlock`; the solver, the identifiability
analysis, the covariance and the reports are the stack's and need no change.

What a block provides (each method's docstring has the shapes and units):

========================  =================================================================
``kind``                  the kind's name (``tracker``, ``ballbar``, ... ``camera``)
``unit``                  what a residual row is in: ``length`` (model length unit) or
                          another unit (``px``); the weights ``1 / sigma`` make rows unitless
``blind_to``              the motions of the whole arm the residuals cannot see
                          (``translation``, ``rotation``, ``scale``)
``blind_constraints()``   the same as linear conditions on a motion ``(t, w, s)`` (known
                          geometry sees some combinations: a known point stays put)
``obs_dof``               residual rows per observation (for outlier tests), e.g. 3 for a
                          touched point, 1 for a distance
``n_obs``, ``obs_index``  observations (file rows, pairs, images) and the observation of
                          each residual row
``nuisance_names``        names of the block's own unknowns (reported, in the JSON)
``start(model, p)``       nuisance start values from the data at arm parameters ``p`` (a
                          sphere fit for a pivot, a centroid for a point, an SVD plane fit);
                          a block with rotations keeps a reference here and parametrises
                          small rotations about it
``evaluate(...)``         residuals and the analytic Jacobian for the arm columns asked
                          for and for the nuisance (`BlockRows`); the arm part through
                          `SerialModel`'s identification Jacobian (`tool_points`; a block
                          that sets ``shares_tool_points`` gets them from the stack, one
                          sweep for all such blocks)
``arm_normal(...)``       optional, blocks without unknowns of their own: their share of
                          the normal equations accumulated chunk by chunk and chain by
                          chain, never the dense rows (default: None, the stack forms the
                          rows from ``evaluate``)
``observation_errors(r)`` per-observation error sizes from the residual (before / after
                          statistics, outliers)
``normal_parts(...)``     optional: the block's share of the normal equations without its
                          dense rows (a block-sparse nuisance Jacobian)
``observation_poses()``   the pose of each observation (rows of one configuration at
                          several markers: one pose of the outlier test)
``check_data``, ``check_fit``  plausibility hooks (`kinecal.diagnostics.warn` with a stable
                          code) before the fit at the start values, and after it
``nuisance_report``       the solved nuisance in words and numbers (JSON, report)
========================  =================================================================

Noise: ``sigma`` (a float for the whole block) or ``obs_sigma`` (one per observation,
e.g. a file's ``sigma`` column), in the block's unit, is the *stated* 1-sigma noise of one
residual component; ``relative`` (one per observation, default 1) scales an estimated
noise (a tracker row's ``weight`` w gives ``1 / sqrt(w)``). Without a stated noise the
stack estimates one per block (`kinecal.calibration.blocks.weights`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "MOTION_WORDS",
    "BlockRows",
    "ResidualBlock",
    "group_rows",
    "plane_constraint",
    "point_constraint",
    "tool_points",
]

Array = NDArray[np.float64]

#: poses per forward-kinematics sweep of `tool_points` (one sweep keeps every frame)
SWEEP_POSES = 4096
#: the similarity motions of the measurement frame, ``delta x = t + w x x + s x``, as
#: coordinates ``(t_x, t_y, t_z, w_x, w_y, w_z, s)``: the word of each coordinate
MOTION_WORDS = ("translation",) * 3 + ("rotation",) * 3 + ("scale",)


def _cross(v: Array) -> Array:
    """``[v]_x`` ``(3, 3)``: ``[v]_x w = v x w``."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def point_constraint(c: Array) -> Array:
    """Rows ``(3, 7)`` on a motion ``(t, w, s)`` that leave the known point `c` in place:
    ``t + w x c + s c = 0``."""
    c = np.asarray(c, dtype=float)[:3]
    return np.hstack([np.eye(3), -_cross(c), c[:, None]])


def plane_constraint(p: Array, n: Array) -> Array:
    """Rows ``(4, 7)`` on a motion that maps the known plane through `p` with unit normal
    `n` onto itself: the rotation about `n` only (``n x w = 0``) and ``n . t + s (n . p)
    = 0``."""
    n = np.asarray(n, dtype=float)
    rot = np.hstack([np.zeros((3, 3)), _cross(n), np.zeros((3, 1))])
    off = np.r_[n, np.zeros(3), float(n @ np.asarray(p, dtype=float))][None, :]
    return np.vstack([rot, off])


@dataclass
class BlockRows:
    """What `ResidualBlock.evaluate` returns.

    Attributes
    ----------
    r : ndarray, shape (m,)
        Unweighted residual rows (block unit), observation-major.
    arm : ndarray, shape (m, k) or None
        ``dr / d(arm parameters)`` for the columns asked for (unit per parameter unit).
    nuisance : ndarray, shape (m, n_b) or None
        ``dr / d(nuisance)``.
    """

    r: Array
    arm: Array | None = None
    nuisance: Array | None = None


def tool_points(model: SerialModel, q: Array, params: Array, marker: NDArray[np.intp] | None,
                columns: NDArray[np.intp] | None) -> tuple[Array, Array | None]:
    """Tool points ``(N, 3)`` and, for `columns`, their identification Jacobian
    ``(k, 3, N)`` (length unit per parameter unit) at the full parameter vector `params`."""
    if columns is None:
        return model.positions(q, params, marker), None
    if len(q) <= SWEEP_POSES:
        s = model.sweep(q, params, marker)
        return s.positions, s.jacobian_t(columns=columns)
    return (model.positions(q, params, marker),
            model.jacobian_t(q, params, "position", columns, marker))


def group_rows(group: NDArray[np.intp], n_groups: int) -> list[NDArray[np.intp]]:
    """The row indices of each group, in group order."""
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(group[order], np.arange(n_groups + 1))
    return [order[bounds[g]:bounds[g + 1]] for g in range(n_groups)]


class ResidualBlock(ABC):
    """One measurement set (module docstring).

    Parameters
    ----------
    source : str
        File name or description (messages, reports).
    q : ndarray, shape (N, n_joints)
        Joint readings of the block's rows (rad; prismatic: length unit).
    marker : ndarray of int, shape (N,), optional
        Marker (tool point) of each row, an index into the model's markers.
    sigma : float, optional
        Stated noise of the whole block (block unit).
    obs_sigma : ndarray, shape (n_obs,), optional
        Stated noise per observation (overrides `sigma`).
    relative : ndarray, shape (n_obs,), optional
        Relative noise per observation (with an estimated noise).
    """

    kind: ClassVar[str] = ""
    unit: ClassVar[str] = "length"
    obs_dof: ClassVar[int] = 1
    #: what the stated noise is the noise of (docs, messages)
    noise_of: ClassVar[str] = ""
    #: the block's residuals depend on the arm only through its rows' tool points: the stack
    #: then computes them for every such block in one forward-kinematics sweep and passes
    #: them to `evaluate` as ``points``
    shares_tool_points: ClassVar[bool] = False
    #: similarity motions of the whole arm (and the block's unknowns with it) that leave
    #: the residuals unchanged: any of ``translation``, ``rotation``, ``scale``
    #: (`kinecal.calibration.blocks.motions`)
    blind_to: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, source: str, q: Array, marker: NDArray[np.intp] | None = None,
                 sigma: float | None = None, obs_sigma: Array | None = None,
                 relative: Array | None = None) -> None:
        self.source = str(source)
        self.q = np.asarray(q, dtype=float)
        self.marker = None if marker is None else np.asarray(marker, dtype=np.intp)
        if sigma is not None and not (np.isfinite(sigma) and sigma > 0):
            raise InputError(f"{self.name}: sigma: expected a positive number, got {sigma}",
                             option="--sigma")
        self.sigma = None if sigma is None else float(sigma)
        self.obs_sigma = None if obs_sigma is None else np.asarray(obs_sigma, dtype=float)
        self.relative = None if relative is None else np.asarray(relative, dtype=float)

    # ------------------------------------------------------------------ identity
    @property
    def name(self) -> str:
        """``kind (file name)`` for messages."""
        return f"{self.kind} ({Path(self.source).name or self.source})"

    @property
    @abstractmethod
    def n_obs(self) -> int:
        """Number of observations."""

    @property
    @abstractmethod
    def obs_index(self) -> NDArray[np.intp]:
        """Observation of each residual row ``(m,)`` (non-decreasing)."""

    @property
    def n_rows(self) -> int:
        """Number of residual rows ``m``."""
        return int(self.obs_index.size)

    @property
    def nuisance_names(self) -> list[str]:
        """Names of the block's own unknowns (none by default)."""
        return []

    @property
    def n_nuisance(self) -> int:
        """Number of nuisance parameters."""
        return len(self.nuisance_names)

    def nuisance_scale(self, length: float) -> Array:
        """Column factors ``(n_b,)`` making the nuisance columns comparable with lengths
        (1 for a length, ``1 / length`` for an angle; `length`: the workspace's size)."""
        return np.ones(self.n_nuisance)

    def observation_labels(self) -> list[str]:
        """One label per observation (``file:row``) for outlier lists."""
        stem = Path(self.source).name or self.source
        return [f"{stem}:{i + 1}" for i in range(self.n_obs)]

    def blind_constraints(self) -> Array:
        """Linear conditions ``C (r, 7)`` on a motion ``m = (t, w, s)`` of the whole arm
        (`MOTION_WORDS`): the residuals are blind to `m` when ``C m = 0``. Default: the
        coordinates of the motions not in `blind_to` are zero."""
        return np.eye(7)[[i for i, w in enumerate(MOTION_WORDS) if w not in self.blind_to]]

    def observation_poses(self) -> tuple[NDArray[np.intp], int]:
        """The pose of each observation ``(n_obs,)`` and the number of poses: the
        observations one arm configuration made at several markers are one pose of the
        outlier test (`kinecal.calibration.diagnostics.observations`). Default: each
        observation its own pose."""
        return np.arange(self.n_obs, dtype=np.intp), self.n_obs

    def configurations(self) -> tuple[Array, NDArray[np.intp] | None]:
        """Joint readings and markers of the tool points the block measures."""
        return self.q, self.marker

    # ------------------------------------------------------------------ noise
    def stated_sigma(self) -> Array | None:
        """Stated noise per observation ``(n_obs,)`` or None (estimate it)."""
        if self.obs_sigma is not None:
            return self.obs_sigma
        if self.sigma is not None:
            rel = np.ones(self.n_obs) if self.relative is None else self.relative
            return self.sigma * rel
        return None

    def relative_sigma(self) -> Array:
        """Relative noise per observation ``(n_obs,)`` (ones unless weights say otherwise)."""
        return np.ones(self.n_obs) if self.relative is None else self.relative

    # ------------------------------------------------------------------ residuals
    @abstractmethod
    def start(self, model: SerialModel, params: Array) -> Array:
        """Nuisance start values ``(n_b,)`` from the data at arm parameters `params`.

        Raises `InputError` when the data cannot determine them (e.g. a pivot whose rows
        lie on one circle).
        """

    @abstractmethod
    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        """Residuals at arm parameters `params` ``(n_params,)`` and `nuisance` ``(n_b,)``.

        With `jacobian`, also ``dr / d(arm)`` for the parameter indices `columns` and
        ``dr / d(nuisance)``. `points` (blocks with ``shares_tool_points``): the rows' tool
        points ``(N, 3)`` and, with `jacobian`, their Jacobian ``(k, 3, N)`` for `columns`,
        as `tool_points` gives them; None: the block computes them.
        """

    def arm_normal(self, model: SerialModel, params: Array, columns: NDArray[np.intp],
                   weight: Array, groups: list | None = None
                   ) -> tuple[Array, Array, Array] | None:
        """The share of a block without unknowns of its own in the normal equations.

        Parameters
        ----------
        model, params
            As in `evaluate`.
        columns : ndarray of int, shape (k,)
            Parameter indices of the arm's columns.
        weight : ndarray, shape (m,)
            Weight of each residual row (``1 / sigma``; zero: the row is left out).
        groups : list of (ndarray, ndarray), optional
            The residual rows grouped by the chains they reach, with the positions in
            `columns` of those chains' columns (`kinecal.calibration.blocks.tips.
            column_groups`); None: every row reaches every column.

        Returns
        -------
        tuple of (r (m,), J^T J (k, k), J^T r (k,)) or None
            Weighted residual rows and their normal equations; None (the default): the
            stack forms them from `evaluate`'s rows.
        """
        return None

    @abstractmethod
    def observation_errors(self, r: Array) -> Array:
        """Error size per observation ``(n_obs,)`` (block unit) from residuals ``(m,)``."""

    def normal_parts(self, model: SerialModel, params: Array, nuisance: Array,
                     columns: NDArray[np.intp], weights: Array) -> tuple | None:
        """The block's share of the normal equations summed without its dense rows, for a
        block whose nuisance Jacobian is mostly zeros (a camera rig's: each row reaches one
        camera and one board): ``(r_w, A_aa, A_an, A_nn, g_a, g_n)`` with the rows weighted
        by `weights` ``(m,)`` (``r_w`` the weighted residual ``(m,)``; ``A_aa`` ``(k, k)``,
        ``A_an`` ``(k, n_b)``, ``A_nn`` ``(n_b, n_b)``, ``g_a`` ``(k,)``, ``g_n`` ``(n_b,)``
        for the arm `columns`). None (the default): the stack forms them from
        `evaluate`."""
        return None

    # ------------------------------------------------------------------ hooks
    def check_data(self, model: SerialModel, params: Array, nuisance: Array) -> None:
        """Plausibility checks before the fit (at the start values); warn, don't raise."""
        return None

    def check_fit(self, model: SerialModel, params: Array, nuisance: Array, r: Array,
                  sigma: Array) -> None:
        """Plausibility checks after the fit; `sigma` ``(n_obs,)``: the noise used."""
        return None

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict[str, Any]]:
        """The solved nuisance, one entry per object (pivot, point, plane ...)."""
        return []
