"""The UR controller's ``calibration.conf``: factory deltas to the nominal D-H table.

The controller keeps its factory calibration in an INI-style file (``[mounting]`` section)
whose keys ``delta_theta``, ``delta_a``, ``delta_d`` and ``delta_alpha`` each hold a list
of six numbers, one per joint (radians and metres), added to the nominal D-H parameters of
the arm type (`kinecal.io.ur.robots`). Other keys and sections (checksums, status) are
read past; ``#`` and ``;`` start comments.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_text
from kinecal.errors import InputError

__all__ = ["DELTA_KEYS", "check_calibration", "read_calibration_conf"]

#: the keys read, in the column order of the returned table (theta, a, d, alpha)
DELTA_KEYS = ("delta_theta", "delta_a", "delta_d", "delta_alpha")
_SECTION = "mounting"
_ANGLES = ("delta_theta", "delta_alpha")
#: beyond these magnitudes (rad, m) a double keeps no 1e-12 rad / 1e-10 m of a value: no
#: calibration writes them (real files: up to 7.2 rad and 450 m)
MAX_ANGLE = 4096.0
MAX_LENGTH = 1e6
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")


def _strip_comment(line: str) -> str:
    for mark in ("#", ";"):
        k = line.find(mark)
        if k >= 0:
            line = line[:k]
    return line.strip()


def _values(key: str, text: str, path: Path, row: int) -> list[float]:
    body = text.strip()
    if not (body.startswith("[") and body.endswith("]")):
        raise InputError(f"line {row}: {key}: expected a list [v1, ..., v6], got {body[:40]!r}",
                         file=path)
    cells = [c for c in re.split(r"[,\s]+", body[1:-1].strip()) if c]
    if len(cells) != 6:
        raise InputError(f"line {row}: {key}: expected 6 values (one per joint), got {len(cells)}",
                         file=path)
    out = []
    for c in cells:
        if not _NUMBER.match(c) or not math.isfinite(float(c)):
            raise InputError(f"line {row}: {key}: {c!r} is not a finite number", file=path)
        out.append(float(c))
    return out


def read_calibration_conf(path: str | Path) -> NDArray[np.float64]:
    """The factory deltas of a UR controller's ``calibration.conf``.

    Parameters
    ----------
    path : str or Path
        The file (copied from the controller, ``/root/.urcontrol/calibration.conf``).

    Returns
    -------
    ndarray, shape (6, 4)
        One row per joint: delta theta (rad), delta a (m), delta d (m), delta alpha (rad).

    Raises
    ------
    InputError
        No ``[mounting]`` section, a missing or repeated key, a list without exactly six
        finite numbers, a value too large to carry any precision (file and line named).
        The geometry the deltas give is judged by `check_calibration`.
    """
    path = Path(path)
    text = read_text(path)
    section, found, rows = None, {}, {}
    for row, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw)
        if not line:
            continue
        if line.startswith("[") and line.endswith("]") and "=" not in line:
            section = line[1:-1].strip().lower()
            continue
        key, eq, value = line.partition("=")
        key = key.strip().lower()
        if section != _SECTION or not eq or key not in DELTA_KEYS:
            continue
        if key in found:
            raise InputError(f"line {row}: {key} given twice (also line {rows[key]})", file=path)
        found[key], rows[key] = _values(key, value, path, row), row
    missing = [k for k in DELTA_KEYS if k not in found]
    if missing:
        where = "its [mounting] section" if rows else "a [mounting] section"
        raise InputError(f"not a UR calibration.conf: expected {where} with "
                         f"{', '.join(DELTA_KEYS)} (missing {', '.join(missing)})", file=path)
    deltas = np.array([found[k] for k in DELTA_KEYS]).T
    _check_ranges(deltas, path, rows)
    return deltas


def _check_ranges(deltas: NDArray[np.float64], path: Path, rows: dict[str, int]) -> None:
    """Refuse values whose size leaves no precision (`MAX_ANGLE`, `MAX_LENGTH`). Large
    deltas as such are no fault: real files have ``delta_d`` of hundreds of metres on the
    parallel joints and ``delta_theta`` beyond a turn; their geometry is judged by
    `check_calibration`."""
    for col, key in enumerate(DELTA_KEYS):
        v = deltas[:, col]
        limit, unit = (MAX_ANGLE, "rad") if key in _ANGLES else (MAX_LENGTH, "m")
        if np.abs(v).max() > limit:
            raise InputError(f"line {rows[key]}: {key}: {v[np.abs(v).argmax()]:.6g} is beyond "
                             f"{limit:g} {unit}, where a double keeps no useful precision: "
                             "expected radians and metres", file=path)


def check_calibration(deltas: NDArray[np.float64], robot: str, path: str | Path) -> float:
    """Judge a file's deltas by the arm they give (`kinecal.io.ur.geometry`).

    Parameters
    ----------
    deltas : ndarray, shape (6, 4)
        `read_calibration_conf`'s table.
    robot : str
        The UR type the file is said to be of.
    path : str or Path
        For messages.

    Returns
    -------
    float
        The largest distance (m) of the calibrated flange from the nominal `robot`'s over
        the joint range.

    Raises
    ------
    InputError
        The flange moves by more than the arm's reach: no calibration of this type (deltas
        in mm or degrees?).

    Warns ``ur-conf-implausible`` beyond what a factory calibration gives
    (`kinecal.io.ur.geometry.FACTORY_FRACTION` of the reach), naming the type the deltas
    fit when there is one.
    """
    from kinecal.io.ur.geometry import fitting_types, reach, within_factory

    robot = robot.strip().lower()
    fits = dict(fitting_types(deltas))
    dev, arm = fits[robot], reach(robot)
    others = [f"{t} ({e * 1000:.3g} mm)" for t, e in fits.items()
              if t != robot and within_factory(t, e)]
    hint = (f"; they fit a {' or '.join(others[:3])}: give that --robot?" if others else
            ": deltas in another unit (mm, degrees), or not a controller's file?")
    if dev > arm:
        raise InputError(f"the deltas move the {robot}'s flange by up to "
                         f"{_mm(dev)} over the joint range, more than the arm's reach "
                         f"({arm * 1000:.0f} mm): no calibration of a {robot}{hint}", file=path)
    if not within_factory(robot, dev):
        from kinecal.diagnostics import warn
        from kinecal.io.ur.geometry import FACTORY_FRACTION

        warn("ur-conf-implausible", f"{path}: the deltas move the {robot}'s flange by up to "
             f"{_mm(dev)} over the joint range, more than a factory calibration does (at most "
             f"{FACTORY_FRACTION:.0%} of the reach, {FACTORY_FRACTION * arm * 1000:.3g} mm)"
             f"{hint}")
    return dev


def _mm(metres: float) -> str:
    return f"{metres * 1000:.4g} mm" if np.isfinite(metres) else "an undefined distance"
