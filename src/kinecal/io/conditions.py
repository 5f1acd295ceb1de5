"""The conditions of a measurement row: the ``temperature`` and ``time`` columns.

``temperature``: deg C, a number per row. ``time``: seconds (any origin) or an ISO 8601
date and time (``2020-07-14T16:39:04``, ``2020-07-14 16:39:04.5+02:00``; without a zone
it is taken as UTC), turned into seconds since 1970-01-01 UTC. Both are optional; the
calibration report plots the residual against them, and time-ordered poses are also
cross-validated in blocks of time (`kinecal.calibration.serial.cross_validation_folds`).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.csvtable import read_column

__all__ = ["CONDITION_COLUMNS", "read_conditions", "seconds_of"]

#: the optional condition columns of a measurement file
CONDITION_COLUMNS = ("temperature", "time")
#: a temperature (deg C) outside this range is not an ambient or machine temperature
_TEMPERATURE_RANGE = (-90.0, 200.0)


def seconds_of(cell: str) -> float | None:
    """A ``time`` cell in seconds: a number as it is, an ISO 8601 date and time as seconds
    since 1970-01-01 UTC (UTC when it names no zone); None when it is neither."""
    try:
        value = float(cell)
    except ValueError:
        pass
    else:
        return value if np.isfinite(value) else None
    try:
        stamp = datetime.fromisoformat(cell)
    except ValueError:
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=UTC)
    return stamp.timestamp()


def read_conditions(path: str | Path) -> dict[str, NDArray[np.float64] | None]:
    """``{"temperature": (N,) or None, "time": (N,) or None}`` of a measurement file.

    Raises
    ------
    InputError
        A cell that is not a number (temperature) or neither seconds nor an ISO 8601 date
        (time), or a temperature outside -90 .. 200 deg C, with its row.
    """
    out: dict[str, NDArray[np.float64] | None] = {}
    for name in CONDITION_COLUMNS:
        cells = read_column(path, name)
        if cells is None:
            out[name] = None
            continue
        values = np.empty(len(cells))
        for r, cell in enumerate(cells, start=1):
            v = seconds_of(cell) if name == "time" else _number(cell)
            if v is None:
                what = ("seconds or an ISO 8601 date and time (2020-07-14T16:39:04)"
                        if name == "time" else "a number (deg C)")
                raise InputError(f"column {name}: {cell!r}, expected {what}", file=path, row=r)
            if name == "temperature" and not _TEMPERATURE_RANGE[0] <= v <= _TEMPERATURE_RANGE[1]:
                raise InputError(f"column temperature: {v:g}, expected deg C within "
                                 f"{_TEMPERATURE_RANGE[0]:g} .. {_TEMPERATURE_RANGE[1]:g}",
                                 file=path, row=r)
            values[r - 1] = v
        out[name] = values
    return out


def _number(cell: str) -> float | None:
    try:
        v = float(cell)
    except ValueError:
        return None
    return v if np.isfinite(v) else None
