"""Prior files of ``kinecal calibrate --prior FILE``: one parameter per row.

CSV with the header ``name,sigma`` or ``name,sigma,mean``:

``name``
    A parameter of the model (``theta2``, ``a3``, ``tool.x``, ``base.rz``, ...).
``sigma``
    The prior's 1-sigma of the parameter's deviation, in the model file's units (the length
    unit, and degrees for a ``deg`` model); ``none`` (or an empty cell) for no prior on it.
``mean``
    The parameter's prior value (model file units); empty or absent: the nominal value,
    or the value of the ``--prior-from`` result.

The prior itself (how it enters the fit) is `kinecal.calibration.serial.prior`; this
module only reads and checks the file.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from kinecal._files import read_text
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["MAX_PRIOR_ROWS", "PriorRow", "read_prior_file"]

#: most rows a prior file may have (a model has tens to hundreds of parameters)
MAX_PRIOR_ROWS = 100_000
_NONE = ("", "none", "inf")


@dataclass(frozen=True)
class PriorRow:
    """One row of a prior file (model file units).

    Attributes
    ----------
    name : str
    sigma : float or None
        None: no prior on this parameter.
    mean : float or None
        None: the nominal value (or the ``--prior-from`` result's).
    row : int
        1-based data row (for messages).
    """

    name: str
    sigma: float | None
    mean: float | None
    row: int


def _number(cell: str, what: str, path: Path, row: int, allow_none: bool) -> float | None:
    text = cell.strip()
    if text.lower() in _NONE:
        if allow_none:
            return None
        raise InputError(f"{what}: expected a number, got {cell!r}", file=path, row=row)
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{what}: expected a number, got {cell!r}", file=path,
                         row=row) from None
    if not math.isfinite(value):
        raise InputError(f"{what}: expected a finite number, got {cell!r}", file=path, row=row)
    return value


def read_prior_file(path: str | Path, model: SerialModel) -> list[PriorRow]:
    """The rows of a prior file (module docstring), names checked against `model`.

    Raises
    ------
    InputError
        With the file and row: no or another header, a name the model does not have or
        given twice, a sigma that is not a positive number (or ``none``), a mean that is
        not a finite number.
    """
    path = Path(path)
    text = read_text(path, max_bytes=16_000_000)
    lines = list(csv.reader(text.splitlines()))
    lines = [ln for ln in lines if any(c.strip() for c in ln)]
    header = [c.strip().lower() for c in lines[0]] if lines else []
    if header not in (["name", "sigma"], ["name", "sigma", "mean"]):
        raise InputError(f"expected the header name,sigma or name,sigma,mean, got "
                         f"{','.join(header) or 'an empty file'}", file=path)
    if len(lines) - 1 > MAX_PRIOR_ROWS:
        raise InputError(f"{len(lines) - 1} rows: expected at most {MAX_PRIOR_ROWS} (one per "
                         "parameter)", file=path)
    known = set(model.parameter_names)
    out: list[PriorRow] = []
    seen: dict[str, int] = {}
    for row, cells in enumerate(lines[1:], start=1):
        if len(cells) != len(header):
            raise InputError(f"expected {len(header)} cells ({','.join(header)}), got "
                             f"{len(cells)}", file=path, row=row)
        name = cells[0].strip()
        if name not in known:
            raise InputError(f"unknown parameter {name!r}: model {model.name!r} has "
                             f"{', '.join(model.parameter_names[:6])}, ...", file=path, row=row)
        if name in seen:
            raise InputError(f"parameter {name!r} is given twice (rows {seen[name]} and {row})",
                             file=path, row=row)
        seen[name] = row
        sigma = _number(cells[1], "sigma", path, row, allow_none=True)
        if sigma is not None and not sigma > 0:
            raise InputError(f"sigma: expected a positive number (or none for no prior), got "
                             f"{cells[1].strip()}", file=path, row=row)
        mean = _number(cells[2], "mean", path, row, allow_none=True) if len(cells) > 2 else None
        out.append(PriorRow(name, sigma, mean, row))
    return out
