"""What the gauge kinds share: rows grouped by an id (a pivot, a bar, a socket, a plane),
each group with its own unknowns, at least as many rows as the group needs, a stated noise
per row from the file's ``sigma`` column, and the per-group spread test after the fit."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import ResidualBlock, group_rows
from kinecal.calibration.diagnostics._common import repeat_groups
from kinecal.calibration.diagnostics.kinds import check_group_spread
from kinecal.calibration.diagnostics.observations import pose_groups
from kinecal.data import GaugeMeasurements
from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["GaugeBlock"]

Array = NDArray[np.float64]

#: residuals below this fraction of the machine's size are round-off, not a finding
ROUND_OFF = 1e-9


def _rows_text(rows: NDArray[np.intp]) -> str:
    shown = ", ".join(str(int(r) + 1) for r in rows[:6])
    return ("row " if rows.size == 1 else "rows ") + shown + (", ..." if rows.size > 6 else "")


#: a known distance this many times the median of its file (or less than its inverse) is
#: a typing or unit slip of that row, not a measurement: it is refused, naming the row
DISTANCE_RATIO = 100.0


def check_distance_rows(block: ResidualBlock, distance: Array, what: str) -> None:
    """Refuse the first row whose known distance is `DISTANCE_RATIO` times the median of
    the file's distances or less than its inverse (``1e11`` among readings of 260 mm): a
    fit through it could not determine the gauge's unknowns, and would not say why."""
    L = np.asarray(distance, dtype=float)
    if not L.size:
        return
    median = float(np.median(L))
    if not median > 0:
        return
    bad = np.flatnonzero((L > DISTANCE_RATIO * median) | (L < median / DISTANCE_RATIO))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{block.name}: {what} {L[i]:.6g} is {L[i] / median:.3g} times the "
                         f"file's median {median:.6g} ({bad.size} such "
                         f"{'row' if bad.size == 1 else 'rows'}): expected readings of the "
                         "same gauge, in the model's length unit", file=block.source,
                         row=i + 1)


class GaugeBlock(ResidualBlock):
    """A `GaugeMeasurements` file as a residual block; subclasses set the kind's numbers.

    Parameters
    ----------
    data : GaugeMeasurements
    sigma : float, optional
        Stated noise of every row (overrides the file's ``sigma`` column).
    """

    #: the group column's name and what a group is, in words
    group_word: ClassVar[str] = ""
    #: unknowns per group, and the fewest rows a group needs (and why)
    per_group: ClassVar[int] = 0
    min_rows: ClassVar[int] = 1
    min_reason: ClassVar[str] = ""
    #: fewest rows of a known group (a fixture: every touch informs the arm)
    min_rows_known: ClassVar[int] = 1
    shares_tool_points = True
    #: code of the per-group spread check after the fit (docs/diagnostics.md)
    spread_code: ClassVar[str] = ""
    spread_advice: ClassVar[str] = ""

    def __init__(self, data: GaugeMeasurements, sigma: float | None = None) -> None:
        if data.kind != self.kind:
            raise InputError(f"{data.source}: {data.kind} measurements given to the "
                             f"{self.kind} block")
        self.data = data
        self.groups = group_rows(np.asarray(data.group), len(data.group_names))
        #: groups whose geometry is known (fixtures, `kinecal.io.fixtures`) ``(G,)``
        self.known_mask = data.known_groups
        self.known = None if data.known is None else np.asarray(data.known, dtype=float)
        super().__init__(data.source, data.q, data.marker, sigma,
                         obs_sigma=None if sigma is not None else self._obs_sigma(data))
        self._check_groups()

    @property
    def n_obs(self) -> int:
        """One observation per file row."""
        return len(self.data)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        """The row of every residual (`obs_dof` residuals per row)."""
        return np.repeat(np.arange(len(self.data), dtype=np.intp), self.obs_dof)

    def observation_poses(self) -> tuple[NDArray[np.intp], int]:
        """Rows of one arm configuration at several markers are one pose."""
        if self.marker is None:
            return np.arange(self.n_obs, dtype=np.intp), self.n_obs
        return pose_groups(self.q, self.marker)

    def _obs_sigma(self, data: GaugeMeasurements) -> Array | None:
        return None if data.sigma is None else np.asarray(data.sigma, dtype=float)

    def _check_groups(self) -> None:
        """Refuse a group with fewer distinct arm configurations than it needs (a row
        repeated 1000 times is one touch); warn ``duplicate-poses`` on repeated rows."""
        key = np.asarray(self.q, dtype=float)
        if self.marker is not None:
            key = np.column_stack([key, self.marker])
        group = np.asarray(self.data.group, dtype=np.intp)
        # rows equal in their joints and their group, all groups at once (a loop over
        # 500 000 pairs took 45 s)
        same, n_same = repeat_groups(key, group[:, None].astype(float))
        first = np.unique(same, return_index=True)[1]
        n_groups = len(self.data.group_names)
        distinct = np.bincount(group[first], minlength=n_groups)
        repeats = len(key) - n_same
        least = np.where(np.asarray(self.known_mask, dtype=bool), self.min_rows_known,
                         self.min_rows)
        short = np.flatnonzero((distinct > 0) & (distinct < least))
        if short.size:
            g = int(short[0])
            name, rows, n_distinct = self.data.group_names[g], self.groups[g], int(distinct[g])
            where = "" if rows.size == 1 else f" ({_rows_text(rows)})"
            raise InputError(
                f"{self.name}: {self.group_word} {name!r} has {rows.size} "
                f"{'row' if rows.size == 1 else 'rows'}{where}"
                + (f" in {n_distinct} distinct arm configuration"
                   f"{'' if n_distinct == 1 else 's'} (the others repeat their joint "
                   "readings)" if n_distinct < rows.size else "")
                + f": expected at least {int(least[g])} distinct ({self.min_reason})",
                file=self.source, row=int(rows[0]) + 1)
        if repeats:
            warn("duplicate-poses",
                 f"{self.name}: {repeats} of {len(key)} rows repeat the joint readings of "
                 f"another row of their {self.group_word}: repeated rows add no geometry, "
                 f"and the noise and standard errors assume independent readings; measure "
                 f"distinct configurations")

    @property
    def live_groups(self) -> list[int]:
        """Groups with rows (ids listed by a file's writer may be unused)."""
        return [g for g, rows in enumerate(self.groups) if rows.size]

    @property
    def solved_groups(self) -> list[int]:
        """Groups with rows whose geometry is solved with the arm (not known)."""
        return [g for g in self.live_groups if not self.known_mask[g]]

    @property
    def nuisance_names(self) -> list[str]:
        names = self.data.group_names
        return [f"{self.group_word}.{names[g]}.{c}" for g in self.solved_groups
                for c in self.nuisance_components]

    nuisance_components: ClassVar[tuple[str, ...]] = ()

    def group_residual_rows(self, g: int) -> NDArray[np.intp]:
        """Residual rows of group `g` (default: one residual row per file row)."""
        return self.groups[g]

    def check_fit(self, model: SerialModel, params: Array, nuisance: Array, r: Array,
                  sigma: Array) -> None:
        if not self.spread_code or not len(self.q):
            return
        size = float(np.abs(model.positions(self.q[:16], params, None if self.marker is None
                                            else self.marker[:16])).max())
        if np.abs(r).max(initial=0.0) <= ROUND_OFF * max(size, 1.0):
            return  # residuals at round-off (noise-free data): nothing to judge
        w = np.asarray(r) / sigma[self.obs_index]
        live = self.live_groups
        rss = np.array([float(np.sum(w[self.group_residual_rows(g)] ** 2)) for g in live])
        dof = np.array([self.group_residual_rows(g).size
                        - (0 if self.known_mask[g] else self.per_group) for g in live])
        check_group_spread(self.spread_code, self.name, self.group_word,
                           [self.data.group_names[g] for g in live], rss, dof,
                           stated=self.stated_sigma() is not None,
                           advice=self.spread_advice)
