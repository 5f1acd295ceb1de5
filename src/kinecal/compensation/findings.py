"""Per-row findings of a compensation, counted over a whole program.

A long program is compensated a block of rows at a time (``kinecal compensate`` streams a
million-line program); the warnings about its rows (joints outside the limits, rows that
did not converge, targets the nominal model does not reach, near-singular rows) must
count every row and name the first one in the whole program, once. `RowFindings` gathers
them block by block and issues them at the end, with the same codes and messages a
single call of `kinecal.compensation.api.compensate` gives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.compensation.moves import JOINT_MOVE_GAIN

__all__ = ["RowFindings", "outside_limits_message"]


def outside_limits_message(count: int, first: int, what: str) -> str:
    """The ``joints-outside-limits`` message: `count` rows of `what`, the first (1-based)."""
    return (f"{count} row(s) of {what} (first: row {first}) lie outside the model's joint "
            "limits; the compensated joints are kept within them")


@dataclass
class RowFindings:
    """Row-level findings gathered over the blocks of one program.

    Attributes
    ----------
    offset : int
        Rows of the program before the block being compensated (set by the caller).
    rows : int
        Rows compensated so far.
    """

    offset: int = 0
    rows: int = 0
    _found: dict[tuple[str, str], list] = field(default_factory=dict)
    _beyond: list = field(default_factory=list)

    def add_beyond(self, d: NDArray[np.float64], envelope, model) -> None:
        """Count the rows of the current block that lie beyond the calibrated joint range:
        `d` ``(rows, n_joints)`` from
        `kinecal.calibration.diagnostics.envelope.beyond_calibrated_range`."""
        from kinecal.calibration.diagnostics.envelope import extremes, significant

        d = significant(d, envelope)
        out = (d != 0).any(axis=1)
        if not out.any():
            return
        rows = self.offset + np.flatnonzero(out) + 1
        if not self._beyond:
            self._beyond[:] = [0, np.zeros(0, dtype=int), np.zeros(d.shape[1]),
                               np.zeros(d.shape[1], dtype=int), envelope, model]
        entry = self._beyond
        entry[0] += int(out.sum())
        if entry[1].size < 5:
            entry[1] = np.r_[entry[1], rows][:5]
        ext = extremes(d)
        entry[2] = np.where(np.abs(ext) > np.abs(entry[2]), ext, entry[2])
        entry[3] += (d != 0).sum(axis=0)

    def add(self, code: str, mask: NDArray[np.bool_], what: str = "",
            first_status: NDArray[np.str_] | None = None) -> None:
        """Count the rows of `mask` (the current block's) under `code`; keep the first
        row (1-based, in the program) and, with `first_status`, its status."""
        idx = np.flatnonzero(mask)
        if not idx.size:
            return
        entry = self._found.setdefault((code, what), [0, None, None])
        entry[0] += idx.size
        if entry[1] is None:
            entry[1] = self.offset + int(idx[0]) + 1
            if first_status is not None:
                entry[2] = str(first_status[idx[0]])

    def warn(self, warn: Callable[[str, str], None] = diagnostics.warn) -> None:
        """Issue every finding once, over all rows (`messages`)."""
        for code, text in self.messages():
            warn(code, text)

    def messages(self) -> list[tuple[str, str]]:
        """``(code, message)`` of every finding, in the order of `compensate`'s warnings."""
        n, out = self.rows, []
        for (code, what), (count, first, _) in self._found.items():
            if code == "joints-outside-limits":
                out.append((code, outside_limits_message(count, first, what)))
        order = ("compensation-not-converged", "nominal-ik-not-converged", "near-singular")
        for code in order:
            if (code, "") not in self._found:
                continue
            count, first, status = self._found[(code, "")]
            if code == "compensation-not-converged":
                text = (f"{count} of {n} rows did not converge (first: row {first}, "
                        f"{status}): the calibrated arm does not reach them from the program's "
                        "configuration (near a singularity, a joint limit or out of reach); "
                        "they are kept with converged=false")
            elif code == "nominal-ik-not-converged":
                text = (f"{count} of {n} targets are out of reach of the nominal model: check "
                        "the targets' frame and units")
            else:
                text = (f"{count} of {n} rows are close to a singularity (condition number "
                        f"above 1e3, or joints moving over {JOINT_MOVE_GAIN:.0f} times what the "
                        "correction needs): their joint corrections are large and sensitive "
                        "to the calibration; move such points away from it if you can")
            out.append((code, text))
        if self._beyond:
            from kinecal.calibration.diagnostics.envelope import outside_message

            total, rows, extreme, counts, envelope, model = self._beyond
            out.append(("outside-calibrated-range",
                        outside_message("compensated joints", total, rows, n, extreme, counts,
                                        envelope, model)))
        return out
