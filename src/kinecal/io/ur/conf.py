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

__all__ = ["DELTA_KEYS", "read_calibration_conf"]

#: the keys read, in the column order of the returned table (theta, a, d, alpha)
DELTA_KEYS = ("delta_theta", "delta_a", "delta_d", "delta_alpha")
_SECTION = "mounting"
_ANGLES = ("delta_theta", "delta_alpha")
#: keys whose joints 2-4 are judged by their sum (the parallel axes)
_PARALLEL = ("delta_theta", "delta_d")
#: a length delta beyond this (m) is no calibration: refused
MAX_LENGTH = 100.0
#: the largest delta a factory calibration gives (m, rad), beyond which a warning is given
PLAUSIBLE = {"delta_theta": 0.05, "delta_a": 0.01, "delta_d": 0.01, "delta_alpha": 0.05}
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
        finite numbers (file and line named).
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
    """Refuse deltas no calibration has (an angle beyond a turn, a length beyond
    `MAX_LENGTH`: another unit); warn (``ur-conf-implausible``) beyond what a factory
    calibration gives: `PLAUSIBLE` per key, for joints 2-4 (parallel axes, whose theta
    and d deltas may be large and opposite) on their sum."""
    for col, key in enumerate(DELTA_KEYS):
        v = deltas[:, col]
        limit, unit, word = ((2 * math.pi, "rad", "radians") if key in _ANGLES else
                             (MAX_LENGTH, "m", "metres"))
        if np.abs(v).max() > limit:
            raise InputError(f"line {rows[key]}: {key}: {v[np.abs(v).argmax()]:.6g} is beyond "
                             f"{limit:.4g} {unit}: expected {word} (a factory calibration's "
                             "deltas are small)", file=path)
    found = []
    for col, key in enumerate(DELTA_KEYS):
        v = deltas[:, col]
        parts = [v[0], v[1:4].sum(), v[4], v[5]] if key in _PARALLEL else list(v)
        worst = float(np.abs(parts).max())
        if worst > PLAUSIBLE[key]:
            found.append(f"{key} {worst:.4g}" + (" (joints 2-4 summed)" if key in _PARALLEL
                                                  and worst == abs(parts[1]) else ""))
    if found:
        from kinecal.diagnostics import warn

        warn("ur-conf-implausible", f"{path}: factory deltas larger than a UR calibration "
             f"gives: {', '.join(found)} (expected at most {PLAUSIBLE['delta_a']:g} m and "
             f"{PLAUSIBLE['delta_alpha']:g} rad): another unit (mm, degrees) or another "
             "robot's file?")
