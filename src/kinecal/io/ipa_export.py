"""The measurement export of the IPA UR10 accuracy data set, read into kinecal's CSV.

Landgraf, Ernst, Schleth, Fabritius, Huber (2021), "A Hybrid Neural Network Approach for
Increasing the Absolute Accuracy of Industrial Robots", IEEE CASE 2021, pp. 468-474; data
at github.com/christianlandgraf/ipa-robot-accuracy (MIT). A Universal Robots UR10 carries a
Leica T-Mac, whose pose a Leica laser tracker measures (``docs/datasets.md``).

The upstream files are ``;``-separated with decimal commas (a German spreadsheet export):
``Timestamp`` (``YYYYmmddHHMMSS``; in series B-D the spreadsheet rounded it to
``2,02011E+13``, so only the row order is left), ``Goal x..yaw`` (the planned T-Mac pose in
the robot base, m and rad), the six joint readings ``shoulder_pan_joint .. wrist_3_joint``
(rad), ``measurement_temperature`` (deg C), the measured T-Mac pose in the tracker frame
``measurement_x, _y, _z`` (mm) and ``measurement_rx, _ry, _rz`` (deg, intrinsic X-Y-Z Euler
angles: ``R = Rx(rx) Ry(ry) Rz(rz)``), and in series B-D each value's standard deviation
``measurement_std_*``.

`convert_ipa_export` writes kinecal's measurement CSV: ``q1..q6`` (deg, 12 significant
digits), ``x, y, z`` (mm), ``sx, sy, sz`` (mm) where the export has them, ``temperature``
(deg C) and ``time`` (ISO 8601, the lab's local time, where the export kept it); with
`orientation` also ``a, b, c`` (deg, the T-Mac's orientation in the same convention, read
with ``--orientation-format intrinsic-xyz:deg``) and ``srx, sry, srz`` (deg). ``kinecal
import SERIES.csv --out FILE.csv [--orientation]`` runs it.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import atomic_open
from kinecal.errors import InputError

__all__ = ["IPA_JOINTS", "ORIENTATION", "convert_ipa_export", "is_ipa_export",
           "read_ipa_export"]

#: the joint columns of the export, base to flange (UR's joint names)
IPA_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
              "wrist_2_joint", "wrist_3_joint")
#: upstream column -> kinecal column (all optional but the joints and positions)
_COLUMNS = {"measurement_x": "x", "measurement_y": "y", "measurement_z": "z",
            "measurement_rx": "a", "measurement_ry": "b", "measurement_rz": "c",
            "measurement_std_x": "sx", "measurement_std_y": "sy", "measurement_std_z": "sz",
            "measurement_std_rx": "srx", "measurement_std_ry": "sry",
            "measurement_std_rz": "srz", "measurement_temperature": "temperature"}
#: the orientation columns (kinecal's names), written with ``orientation`` only
ORIENTATION = ("a", "b", "c", "srx", "sry", "srz")
_REQUIRED = (*IPA_JOINTS, "measurement_x", "measurement_y", "measurement_z")
#: at most this many rows (the largest upstream series has 11910)
_MAX_ROWS = 1_000_000


def _header(path: Path) -> list[str]:
    try:
        with open(path, encoding="utf-8-sig") as fh:
            return [h.strip() for h in fh.readline().split(";")]
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read: {exc}", file=path) from None


def is_ipa_export(path: str | Path) -> bool:
    """Whether `path` is an IPA UR10 export (``;``-separated, joints and T-Mac columns)."""
    path = Path(path)
    if not path.is_file():
        return False
    header = _header(path)
    return all(c in header for c in _REQUIRED)


def read_ipa_export(path: str | Path) -> dict[str, NDArray]:
    """The columns of an IPA export in kinecal's names and units (module docstring):
    ``q1..q6`` (deg) and the float columns of `_COLUMNS` present (orientation as ``a, b,
    c``); ``time`` (ISO 8601 strings) when the timestamps are whole.

    Raises
    ------
    InputError
        A missing column, a row with another number of fields, or a cell that is not a
        number (with its row).
    """
    path = Path(path)
    header = _header(path)
    missing = [c for c in _REQUIRED if c not in header]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}: expected the IPA UR10 "
                         f"export ({'; '.join(_REQUIRED)})", file=path)
    rows: list[list[str]] = []
    with open(path, encoding="utf-8-sig") as fh:
        next(fh)
        for r, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            cells = [c.strip() for c in line.rstrip("\n").split(";")]
            if len(cells) != len(header):
                raise InputError(f"{len(cells)} fields, expected {len(header)} as in the "
                                 "header", file=path, row=r)
            rows.append(cells)
            if len(rows) > _MAX_ROWS:
                raise InputError(f"more than {_MAX_ROWS} rows", file=path)
    if not rows:
        raise InputError("no data rows", file=path)

    def numbers(name: str) -> NDArray[np.float64]:
        k = header.index(name)
        out = np.empty(len(rows))
        for r, row in enumerate(rows, start=1):
            try:
                out[r - 1] = float(row[k].replace(",", "."))
            except ValueError:
                raise InputError(f"column {name}: {row[k]!r}, expected a number", file=path,
                                 row=r) from None
            if not np.isfinite(out[r - 1]):
                raise InputError(f"column {name}: expected a finite number", file=path, row=r)
        return out

    # degrees to 12 significant digits (the export gives the radians to 6)
    cols: dict[str, NDArray] = {f"q{i + 1}": np.array([float(f"{v:.12g}") for v in
                                                       np.degrees(numbers(j))])
                                for i, j in enumerate(IPA_JOINTS)}
    cols.update({mine: numbers(theirs) for theirs, mine in _COLUMNS.items() if theirs in header})
    if "Timestamp" in header:
        stamps = _stamps([row[header.index("Timestamp")] for row in rows])
        if stamps is not None:
            cols["time"] = stamps
    return cols


def _stamps(cells: list[str]) -> NDArray | None:
    """``YYYYmmddHHMMSS`` cells as ISO 8601 strings; None when any is not one (series B-D,
    whose timestamps a spreadsheet rounded)."""
    out = []
    for cell in cells:
        try:
            out.append(datetime.strptime(cell, "%Y%m%d%H%M%S").isoformat())
        except ValueError:
            return None
    return np.array(out)


def convert_ipa_export(source: str | Path, out: str | Path, orientation: bool = False) -> int:
    """Write an IPA export `source` as kinecal's measurement CSV `out` (module docstring):
    positions, or with `orientation` the T-Mac's poses; returns the number of rows. Numbers
    keep their shortest round-trip digits."""
    cols = read_ipa_export(source)
    names = [c for c in cols if orientation or c not in ORIENTATION]
    n = len(cols["q1"])
    text = [[repr(float(v)) for v in cols[c]] if c != "time" else list(cols[c])
            for c in names]
    with atomic_open(Path(out), "w") as fh:
        fh.write(",".join(names) + "\n")
        for r in range(n):
            fh.write(",".join(col[r] for col in text) + "\n")
    return n
