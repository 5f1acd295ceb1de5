"""``outside-calibrated-range``: joint readings beyond the envelope a calibration saw.

A calibration is fitted on its poses' joint readings (`kinecal.kinematics.serial.
joint_errors_envelope.JointEnvelope`, stored in every result). Beyond them the geometry is
extrapolated and the joint-error terms are held at the edge: the model was never checked
there. `fk --params`, `compensate` and ``--validate`` name the rows that lie beyond, which
joint and by how much; `beyond_calibrated_range` gives the figures to a caller that judges
them itself (a registry check of a few poses).

A revolute joint's reading counts modulo a turn (the geometry, harmonics and gravity
forces repeat every turn) unless the model has a scale term on that joint (an encoder
gain error keeps growing with the raw reading): `periodic_joints`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.diagnostics import warn
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.motions import PRISMATIC

__all__ = ["EDGE_MARGIN", "beyond_calibrated_range", "check_calibrated_range", "extremes",
           "outside_message", "periodic_joints", "significant"]

Array = NDArray[np.float64]
#: rows are named when they lie beyond the range by more than this fraction of the joint's
#: calibrated span: a sample of poses never reaches quite to the edges of the range it was
#: drawn from (50 random poses leave 1/51 of it out at each end on average, and more than a
#: fifth with probability 0.8^50 = 1.4e-5; the bundled examples' validation poses reach up
#: to 16 % beyond their calibration poses); beyond that, rows extrapolate farther than the
#: gaps of a random sample
EDGE_MARGIN = 0.25
#: and by more than this (rad; prismatic joints: length unit): a joint held still reads
#: within its resolution
_MARGIN_FLOOR = 1e-3
#: rows listed by number in the message
_ROWS_SHOWN = 5


def periodic_joints(model: SerialModel) -> NDArray[np.bool_]:
    """``(n_joints,)``: joints whose readings count modulo a turn for `model` (revolute,
    without a joint-error scale term)."""
    scaled = set() if model.joint_errors is None else set(model.joint_errors.scale)
    return np.array([k != PRISMATIC and j + 1 not in scaled
                     for j, k in enumerate(model.joint_kinds)], dtype=bool)


def beyond_calibrated_range(q: Array, envelope: JointEnvelope, model: SerialModel) -> Array:
    """Signed distance ``(N, n_joints)`` of each reading beyond `envelope` (rad or length
    unit; > 0 above, < 0 below, 0 inside), revolute joints modulo a turn where the model
    repeats every turn (`periodic_joints`)."""
    return envelope.beyond(np.asarray(q, dtype=float), periodic_joints(model))


def significant(d: Array, envelope: JointEnvelope) -> Array:
    """`d` ``(N, n_joints)`` of `beyond_calibrated_range` with the distances within the
    edge margin (`EDGE_MARGIN`, a quarter of each joint's calibrated span, at least 1e-3)
    set to 0."""
    span = np.asarray(envelope.high) - np.asarray(envelope.low)
    margin = np.maximum(EDGE_MARGIN * span, _MARGIN_FLOOR)
    return np.where(np.abs(d) > margin, d, 0.0)


def check_calibrated_range(q: Array, envelope: JointEnvelope | None, model: SerialModel,
                           what: str = "joint readings", warn=warn) -> Array | None:
    """Warn ``outside-calibrated-range`` when rows of `q` ``(N, n_joints)`` (rad; prismatic:
    length unit) lie beyond the calibrated `envelope` by more than its edge margin
    (`significant`; None: nothing to check).

    The message (`outside_message`) names how many rows, the first row numbers (1-based)
    and per joint how far beyond the range they go, in the model's units. `warn` issues
    it (default `kinecal.diagnostics.warn`). Returns `beyond_calibrated_range` (None
    without an envelope).
    """
    if envelope is None or len(q) == 0:
        return None
    d = beyond_calibrated_range(q, envelope, model)
    far = significant(d, envelope)
    rows = np.flatnonzero((far != 0).any(axis=1)) + 1
    if rows.size:
        warn("outside-calibrated-range",
             outside_message(what, rows.size, rows, len(q), extremes(far),
                             (far != 0).sum(axis=0), envelope, model))
    return d


def extremes(d: Array) -> Array:
    """Per joint the signed distance of largest magnitude ``(n_joints,)`` in `d`."""
    return d[np.argmax(np.abs(d), axis=0), np.arange(d.shape[1])]


def outside_message(what: str, total: int, rows: NDArray[np.intp], n: int, extreme: Array,
                    counts: NDArray[np.intp], envelope: JointEnvelope,
                    model: SerialModel) -> str:
    """The ``outside-calibrated-range`` message: `total` rows of `n` beyond, `rows` the
    first of their 1-based numbers, per joint the row count `counts` and the `extreme`
    signed distance."""
    deg = model.angle_unit == "deg"
    parts = []
    for j in np.flatnonzero(counts):
        revolute = model.joint_kinds[j] != PRISMATIC
        f = (180.0 / np.pi if deg else 1.0) if revolute else 1.0
        unit = model.angle_unit if revolute else model.length_unit
        side, edge = (("above", envelope.high[j]) if extreme[j] > 0
                      else ("below", envelope.low[j]))
        parts.append(f"q{j + 1} in {int(counts[j])} rows, up to {abs(extreme[j]) * f:.3g} "
                     f"{unit} {side} {edge * f:.4g} (calibrated {envelope.low[j] * f:.4g} .. "
                     f"{envelope.high[j] * f:.4g} {unit})")
    shown = ", ".join(map(str, rows[:_ROWS_SHOWN])) + (", ..." if total > _ROWS_SHOWN
                                                       else "")
    return (f"{what}: {total} of {n} rows (rows {shown}) lie beyond the joint range the "
            f"calibration saw: {'; '.join(parts)}. The calibration was not fitted there (the "
            "geometry extrapolates, joint-error terms are held at the edge): measure poses "
            "there to trust it")
