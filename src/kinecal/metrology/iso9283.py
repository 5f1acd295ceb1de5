"""ISO 9283:1998 pose and distance characteristics of repeated pose measurements.

A test commands P poses in n cycles and measures each pose once per cycle. For one pose,
with (x_j, y_j, z_j) its measured position in cycle j = 1..n, (x_c, y_c, z_c) the commanded
position, and the barycentre x̄ = (1/n) Σ_j x_j (likewise ȳ, z̄):

Pose accuracy, clause 7.2.1::

    AP_P = sqrt((x̄ - x_c)² + (ȳ - y_c)² + (z̄ - z_c)²)
    AP_x = x̄ - x_c,   AP_y = ȳ - y_c,   AP_z = z̄ - z_c
    AP_a = ā - a_c,   AP_b = b̄ - b_c,   AP_c = c̄ - c_c      (orientation)

Pose repeatability, clause 7.2.2::

    l_j = sqrt((x_j - x̄)² + (y_j - ȳ)² + (z_j - z̄)²),   l̄ = (1/n) Σ_j l_j
    S_l = sqrt(Σ_j (l_j - l̄)² / (n - 1)),               RP_l = l̄ + 3 S_l
    RP_a = ±3 S_a,   S_a = sqrt(Σ_j (a_j - ā)² / (n - 1))  (likewise b, c)

Distance accuracy and repeatability between two poses P1, P2 measured in the same
cycles, clause 7.3 (7.3.2 and 7.3.3)::

    D_j = |P1_j - P2_j|,   D̄ = (1/n) Σ_j D_j,   D_c = |P1_c - P2_c|
    AD_P = D̄ - D_c,        RD_P = ±3 sqrt(Σ_j (D_j - D̄)² / (n - 1))
    AD_x = D̄_x - D_cx,     D_xj = |x1_j - x2_j|,   D_cx = |x1_c - x2_c|   (likewise y, z)
    RD_x = ±3 sqrt(Σ_j (D_xj - D̄_x)² / (n - 1))                       (likewise y, z)
    AD_a, RD_a ... from D_aj = |a1_j - a2_j| and D_ca = |a1_c - a2_c|    (orientation)

Conventions of this module:

- a, b, c are the rotations about the x, y and z axes of the measurement (base) frame,
  applied in that order: ``R = Rz(c) Ry(b) Rx(a)`` (roll, pitch, yaw;
  `kinecal.spatial.rpy_from_matrix`). Every difference of angles is wrapped into
  [-pi, pi), so that a pose near c = ±180 deg is not split into two clusters 360 deg apart;
  ā - a_c is computed as the mean of the wrapped a_j - a_c (equal to ā - a_c whenever no
  wrap occurs). Without a commanded orientation, the orientation repeatability is taken
  about the first cycle's angles (RP does not depend on that reference).
- The standard writes the repeatabilities as ±3 S; they are returned as the positive 3 S.
- Lengths are in the unit of the data; angles are radians here (`Iso9283Result.to_dict`
  gives degrees).

Entry points: `iso9283` (every figure of a `kinecal.data.RepeatedPoses` test) and the
per-clause
functions `pose_accuracy`, `pose_repeatability`, `orientation_accuracy`,
`orientation_repeatability` and `distance_figures`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.data import RepeatedPoses
from kinecal.errors import InputError
from kinecal.spatial import rpy_from_matrix

__all__ = [
    "MAX_DEFAULT_PAIRS",
    "MAX_PAIRS",
    "POSE_KEYS",
    "Iso9283Result",
    "default_pairs",
    "distance_figures",
    "iso9283",
    "orientation_accuracy",
    "orientation_angles",
    "orientation_repeatability",
    "pose_accuracy",
    "pose_repeatability",
]

Array = NDArray[np.float64]

#: the number of cycles ISO 9283 prescribes for the AP, RP, AD and RD tests
STANDARD_CYCLES = 30
#: distance pairs of the default "every pair" (45 poses); more poses: consecutive pairs
MAX_DEFAULT_PAIRS = 1000
#: most distance pairs one test may name (beyond the consecutive pairs of its poses)
MAX_PAIRS = 10_000
#: per-pose figures, in the order of the tables (angles: the orientation ones)
POSE_KEYS = ("AP", "APx", "APy", "APz", "RP")
ORIENTATION_KEYS = ("APa", "APb", "APc", "RPa", "RPb", "RPc")
DISTANCE_KEYS = ("AD", "ADx", "ADy", "ADz", "RD", "RDx", "RDy", "RDz")
ORIENTATION_DISTANCE_KEYS = ("ADa", "ADb", "ADc", "RDa", "RDb", "RDc")


def orientation_angles(R: Array) -> Array:
    """ISO 9283's orientation angles (a, b, c) ``(..., 3)`` [rad] of rotations
    ``(..., 3, 3)``: ``R = Rz(c) Ry(b) Rx(a)``."""
    return rpy_from_matrix(R)


def _wrap(angle: Array) -> Array:
    """Angles wrapped into [-pi, pi)."""
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def pose_accuracy(measured: Array, commanded: Array) -> dict[str, Array]:
    """Position accuracy of clause 7.2.1.

    Parameters
    ----------
    measured : ndarray, shape (P, n, 3)
        Measured positions of P poses in n cycles (length unit).
    commanded : ndarray, shape (P, 3)
        Commanded positions.

    Returns
    -------
    dict of str to ndarray, shape (P,)
        ``AP`` (AP_P), ``APx``, ``APy``, ``APz`` (length unit).
    """
    d = np.asarray(measured, float).mean(axis=1) - np.asarray(commanded, float)
    return {"AP": np.sqrt((d * d).sum(axis=1)), "APx": d[:, 0], "APy": d[:, 1],
            "APz": d[:, 2]}


def pose_repeatability(measured: Array) -> dict[str, Array]:
    """Position repeatability of clause 7.2.2.

    Parameters
    ----------
    measured : ndarray, shape (P, n, 3)
        Measured positions of P poses in n >= 2 cycles (length unit).

    Returns
    -------
    dict of str to ndarray, shape (P,)
        ``RP`` (= l̄ + 3 S_l), ``l_mean`` (l̄) and ``S_l`` (length unit).
    """
    m = np.asarray(measured, float)
    r = m - m.mean(axis=1, keepdims=True)
    lj = np.sqrt((r * r).sum(axis=2))
    l_mean, s_l = lj.mean(axis=1), lj.std(axis=1, ddof=1)
    return {"RP": l_mean + 3.0 * s_l, "l_mean": l_mean, "S_l": s_l}


def orientation_accuracy(measured: Array, commanded: Array) -> dict[str, Array]:
    """Orientation accuracy of clause 7.2.1: ``APa``, ``APb``, ``APc`` ``(P,)`` [rad] from
    measured rotations ``(P, n, 3, 3)`` and commanded ones ``(P, 3, 3)``."""
    dev = _wrap(orientation_angles(measured) - orientation_angles(commanded)[:, None, :])
    ap = dev.mean(axis=1)
    return {"APa": ap[:, 0], "APb": ap[:, 1], "APc": ap[:, 2]}


def orientation_repeatability(measured: Array, commanded: Array | None = None
                              ) -> dict[str, Array]:
    """Orientation repeatability of clause 7.2.2: ``RPa``, ``RPb``, ``RPc`` ``(P,)`` [rad]
    (3 S_a ...) of measured rotations ``(P, n, 3, 3)``; the angles are wrapped about the
    commanded ones ``(P, 3, 3)`` when given, else about the first cycle's."""
    ang = orientation_angles(measured)
    ref = ang[:, :1, :] if commanded is None else orientation_angles(commanded)[:, None, :]
    rp = 3.0 * _wrap(ang - ref).std(axis=1, ddof=1)
    return {"RPa": rp[:, 0], "RPb": rp[:, 1], "RPc": rp[:, 2]}


def distance_figures(data: RepeatedPoses, first: int, second: int,
                     angles: tuple[Array | None, Array | None] | None = None
                     ) -> dict[str, float]:
    """Distance accuracy and repeatability of clause 7.3 between two poses of `data`.

    Parameters
    ----------
    data : RepeatedPoses
        The test.
    first, second : int
        Indices of the two poses (P1 and P2 of the clause).
    angles : (ndarray or None, ndarray or None), optional
        `orientation_angles` of the measured and commanded rotations, when already
        computed (`iso9283` computes them once for every pair).

    Returns
    -------
    dict of str to float
        ``D_commanded`` (D_c), ``D_mean`` (D̄), ``AD``, ``ADx``, ``ADy``, ``ADz``, ``RD``,
        ``RDx``, ``RDy``, ``RDz`` (length unit); with measured orientations also ``RDa``,
        ``RDb``, ``RDc`` and, with commanded ones, ``ADa``, ``ADb``, ``ADc`` [rad].
    """
    m, c = np.asarray(data.measured, float), np.asarray(data.commanded, float)
    diff = m[first] - m[second]
    dj = np.sqrt((diff * diff).sum(axis=1))
    dc_vec = c[first] - c[second]
    dc = float(np.sqrt((dc_vec * dc_vec).sum()))
    comp, comp_c = np.abs(diff), np.abs(dc_vec)
    out = {"D_commanded": dc, "D_mean": float(dj.mean()), "AD": float(dj.mean() - dc)}
    out.update({f"AD{a}": float(comp[:, k].mean() - comp_c[k]) for k, a in enumerate("xyz")})
    out["RD"] = float(3.0 * dj.std(ddof=1))
    out.update({f"RD{a}": float(3.0 * comp[:, k].std(ddof=1)) for k, a in enumerate("xyz")})
    if data.measured_rotations is not None:
        ang, angc = _angles(data) if angles is None else angles
        da = np.abs(_wrap(ang[first] - ang[second]))
        if angc is not None:
            dca = np.abs(_wrap(angc[first] - angc[second]))
            out.update({f"AD{a}": float(da[:, k].mean() - dca[k]) for k, a in enumerate("abc")})
        out.update({f"RD{a}": float(3.0 * da[:, k].std(ddof=1)) for k, a in enumerate("abc")})
    return out


def _angles(data: RepeatedPoses) -> tuple[Array | None, Array | None]:
    """`orientation_angles` of the measured and the commanded rotations (None: none)."""
    mr, cr = data.measured_rotations, data.commanded_rotations
    return (None if mr is None else orientation_angles(np.asarray(mr, float)),
            None if cr is None else orientation_angles(np.asarray(cr, float)))


def default_pairs(p: int) -> list[tuple[int, int]]:
    """The distance pairs of a test of `p` poses when none are named: every pair while
    there are at most `MAX_DEFAULT_PAIRS` (45 poses), else each pose with the next in test
    order (every pair of 2 000 poses is 2 million figures, hours and gigabytes)."""
    if p * (p - 1) // 2 <= MAX_DEFAULT_PAIRS:
        return [(i, k) for i in range(p) for k in range(i + 1, p)]
    return [(i, i + 1) for i in range(p - 1)]


@dataclass(frozen=True, repr=False)
class Iso9283Result:
    """ISO 9283 figures of a test (`iso9283`).

    Attributes
    ----------
    data : RepeatedPoses
        The test.
    poses : dict of str to ndarray, shape (P,)
        Per pose: ``AP, APx, APy, APz, RP, l_mean, S_l`` (length unit) and, with
        orientations, ``APa, APb, APc`` (commanded orientations needed) and ``RPa, RPb,
        RPc`` [rad].
    pairs : list of (int, int)
        The pose pairs of the distance figures (indices into ``data.labels``).
    distances : list of dict
        `distance_figures` of each pair.
    """

    data: RepeatedPoses
    poses: dict[str, Array]
    pairs: list[tuple[int, int]] = field(default_factory=list)
    distances: list[dict[str, float]] = field(default_factory=list)

    def __repr__(self) -> str:
        d = self.data
        return (f"<Iso9283Result {len(d.labels)} poses x {d.n_cycles} cycles: AP max "
                f"{float(np.max(self.poses['AP'])):.4g}, RP max "
                f"{float(np.max(self.poses['RP'])):.4g} {d.length_unit}, "
                f"{len(self.distances)} distance pairs>")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``standard, cycles, length_unit, angle_unit ("deg"), poses:
        [{pose, AP, APx, APy, APz, RP, l_mean, S_l, [APa..RPc], barycentre, commanded}],
        distances: [{poses: [P1, P2], D_commanded, D_mean, AD, ..., RD, ...}]}``."""
        d = self.data
        bary = np.asarray(d.measured, float).mean(axis=1)
        poses = []
        for i, label in enumerate(d.labels):
            entry: dict[str, Any] = {"pose": label}
            for key, values in self.poses.items():
                v = float(values[i])
                entry[key] = math.degrees(v) if key in ORIENTATION_KEYS else v
            entry["barycentre"] = [float(v) for v in bary[i]]
            entry["commanded"] = [float(v) for v in np.asarray(d.commanded)[i]]
            poses.append(entry)
        distances = []
        for (i, k), fig in zip(self.pairs, self.distances, strict=True):
            entry = {"poses": [d.labels[i], d.labels[k]]}
            entry.update({key: math.degrees(v) if key in ORIENTATION_DISTANCE_KEYS else v
                          for key, v in fig.items()})
            distances.append(entry)
        return {"standard": "ISO 9283:1998", "cycles": d.n_cycles,
                "cycle_numbers": [int(c) for c in d.cycles], "length_unit": d.length_unit,
                "angle_unit": "deg", "orientation": _orientation_kind(d),
                "poses": poses, "distances": distances}


def _orientation_kind(data: RepeatedPoses) -> str:
    if data.measured_rotations is None:
        return "none"
    return "accuracy and repeatability" if data.commanded_rotations is not None \
        else "repeatability"


def iso9283(data: RepeatedPoses, pairs: Sequence[tuple[int, int]] | None = None, *,
            check: bool = True) -> Iso9283Result:
    """Every ISO 9283 pose and distance figure of a test.

    Parameters
    ----------
    data : RepeatedPoses
        P poses measured in n >= 2 cycles.
    pairs : sequence of (int, int), optional
        Pose pairs for the distance figures (indices into ``data.labels``); default
        `default_pairs` (every pair ``(i, k)``, ``i < k``, in test order up to 45 poses;
        consecutive poses beyond), at most `MAX_PAIRS`. The standard's distance test uses
        one pair of its test poses; give that pair to report it alone.
    check : bool
        Warn on an implausible test (`kinecal.metrology.iso_checks`: ``scale-mismatch``,
        ``far-from-commanded``, ``cycle-scatter``).

    Returns
    -------
    Iso9283Result

    Raises
    ------
    InputError
        Fewer than 2 cycles, a pair naming an unknown pose or one pose twice, more than
        `MAX_PAIRS` pairs.
    """
    n, p = data.n_cycles, len(data.labels)
    if n < 2:
        raise InputError(f"{n} cycle(s): the repeatabilities need at least 2 (ISO 9283 "
                         f"prescribes {STANDARD_CYCLES})")
    pairs = default_pairs(p) if pairs is None else list(pairs)
    if len(pairs) > max(MAX_PAIRS, p - 1):
        raise InputError(f"{len(pairs):,} pose pairs: expected at most {MAX_PAIRS:,} (the "
                         "standard's distance test uses one pair)", option="--pairs")
    for i, k in pairs:
        if not (0 <= i < p and 0 <= k < p) or i == k:
            raise InputError(f"pose pair ({i}, {k}): expected two different poses of 0..{p - 1}")
    m = np.asarray(data.measured, float)
    figures = {**pose_accuracy(m, data.commanded), **pose_repeatability(m)}
    if data.measured_rotations is not None:
        mr = np.asarray(data.measured_rotations, float)
        cr = None if data.commanded_rotations is None else np.asarray(
            data.commanded_rotations, float)
        if cr is not None:
            figures.update(orientation_accuracy(mr, cr))
        figures.update(orientation_repeatability(mr, cr))
    pairs = [(int(i), int(k)) for i, k in pairs]
    angles = _angles(data)
    res = Iso9283Result(data, figures, pairs, [distance_figures(data, i, k, angles)
                                               for i, k in pairs])
    if check:
        from kinecal.metrology.iso_checks import check_test

        check_test(res)
    return res
