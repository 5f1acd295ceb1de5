"""Plausibility checks of joint readings and measured positions against a serial model.

Codes: ``joint-limits``, ``joint-units``, ``scale-mismatch``, ``mirrored-frame``,
``initial-error`` (docs/diagnostics.md). The frame comparisons are made after the best
rigid motion between the model's and the measured points, so that an instrument's frame
anywhere never looks like a unit or sign problem.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.diagnostics._common import (
    JOINT_RESOLUTION,
    plural,
    rigid_rms,
    similarity_fit,
    unit_factor_name,
)
from kinecal.data import Measurements
from kinecal.diagnostics import warn
from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "EXPLAINS_BETTER",
    "REACH_FRACTION",
    "TOLERANCE_FACTOR",
    "check_frame_and_units",
    "check_joint_limits",
    "check_joint_units",
]

Array = NDArray[np.float64]

#: an alternative reading of the data (other units, a mirrored axis) must explain it this
#: many times better than the data as given before a check names it
EXPLAINS_BETTER = 5.0
#: a pose set's initial error beyond this fraction of the reach is no calibration problem
REACH_FRACTION = 0.1
#: ... unless the model's tolerances allow it: 3x the RMS effect of errors uniform within them
TOLERANCE_FACTOR = 3.0


# ----------------------------------------------------------------- joint values
def _joint_text(model: SerialModel, j: int, values: Array) -> str:
    s = 1.0 / model.joint_scale()[j]
    unit = model.length_unit if model.is_prismatic()[j] else model.angle_unit
    return f"[{values[0] * s:.4g}, {values[1] * s:.4g}] {unit}"


def check_joint_limits(model: SerialModel, q: Array, what: str = "poses") -> None:
    """``joint-limits``: joint readings outside the model's joint limits."""
    q = np.asarray(q, dtype=float)
    lim = np.asarray(model.joint_limits, dtype=float)
    margin = JOINT_RESOLUTION + 1e-9 * np.abs(lim).max(axis=1)
    out = (q < lim[:, 0] - margin) | (q > lim[:, 1] + margin)
    if not out.any():
        return
    joints = np.flatnonzero(out.any(axis=0))
    j = int(joints[0])
    seen = q[out[:, j], j]
    warn("joint-limits",
         f"{plural(int(out.any(axis=1).sum()), 'row')} of the {what} have joint readings "
         f"outside the model's joint limits (joint{'s' if joints.size > 1 else ''} "
         f"{', '.join(f'q{k + 1}' for k in joints)}; q{j + 1} reads "
         f"{_joint_text(model, j, [seen.min(), seen.max()])}, limits "
         f"{_joint_text(model, j, lim[j])}): check the joint order, units and zero offsets, "
         "or the model's joint_limits")


def _other_angle_unit(model: SerialModel, q: Array) -> Array:
    """The joint values as they would be if the file's revolute columns were in the other
    angle unit than the model says."""
    rev = ~model.is_prismatic()
    f = 180.0 / np.pi if model.angle_unit == "deg" else np.pi / 180.0
    out = np.array(q, dtype=float, copy=True)
    out[:, rev] *= f
    return out


def check_joint_units(model: SerialModel, q: Array, what: str = "poses",
                      min_rows: int = 2) -> bool:
    """``joint-units``: revolute readings of a degree model that all stay within +-2 pi.

    Readings in degrees that never leave +-6.3 deg on any joint, in a model whose limits
    allow four times more, are radians read as degrees (no calibration pose set moves an
    arm that little). Judged from `min_rows` rows on (a robot program's single row of
    radians is as telling as a pose set's). Returns True when it warned.
    """
    if model.angle_unit != "deg":
        return False
    rev = ~model.is_prismatic()
    q = np.asarray(q, dtype=float)
    if not rev.any() or q.shape[0] < min_rows:
        return False
    span = np.abs(q[:, rev]).max()
    small = 2.0 * np.pi * np.pi / 180.0  # 2 pi read as degrees, in rad
    lim = np.asarray(model.joint_limits, dtype=float)[rev]
    if span <= small * 1.01 and (lim[:, 1] - lim[:, 0]).min() > 4.0 * small and span > 0:
        warn("joint-units",
             f"every revolute joint reading of the {what} is within +-{np.degrees(span):.3g} "
             "deg: they look like radians in a model whose angle_unit is deg; convert the "
             "joint columns to degrees (or set angle_unit: rad)")
        return True
    return False


# ------------------------------------------------------------- frame and units
def check_frame_and_units(model: SerialModel, data: Measurements, ref,
                          base_free: bool, what: str = "poses",
                          joint_units_warned: bool = False) -> None:
    """``scale-mismatch``, ``mirrored-frame``, ``joint-units``, ``initial-error``.

    Compares the measured positions with the nominal model's (`ref`, a
    `kinecal.calibration.diagnostics.serial.Reference`, gives the reach and the
    tolerance-sized error). The frame comparisons are made after the best rigid
    motion (the instrument's frame is arbitrary); the initial error is taken as it is when
    the model has no free base frame (the data must then be in the robot's base frame).
    """
    q = np.asarray(data.q, dtype=float)
    xyz = np.asarray(data.xyz, dtype=float)
    marker = getattr(data, "marker", None)
    P0 = model.positions(q, None, marker)
    unit = model.length_unit
    explained = joint_units_warned
    aligned = rigid_rms(P0, xyz)
    s, e_sim = similarity_fit(P0, xyz)
    spread = float(np.sqrt(((P0 - P0.mean(axis=0)) ** 2).sum(axis=1).mean()))
    # e_sim is in the measured unit: / s puts it in the model's, like the spread
    if (np.isfinite(s) and s > 0 and abs(np.log(s)) > np.log(2.0)
            and spread > 3.0 * e_sim / s):
        warn("scale-mismatch",
             f"the measured positions of the {what} span {s:.3g} times what the model "
             f"predicts (looks like {unit_factor_name(s)}): give positions in the model's "
             f"length unit ({unit})")
        explained = True
    if not explained and len(q) >= 4:
        mirrored = rigid_rms(P0, xyz, reflection=True)
        if mirrored * EXPLAINS_BETTER < aligned:
            warn("mirrored-frame",
                 f"the measured positions of the {what} match the model {aligned / mirrored:.0f}"
                 f" times better mirrored ({mirrored:.3g} vs {aligned:.3g} {unit} RMS): an axis "
                 "of the instrument's frame is negated or the frame is left-handed; fix the "
                 "sign of that column")
            explained = True
    if not explained and (~model.is_prismatic()).any():
        other = rigid_rms(model.positions(_other_angle_unit(model, q), None, marker), xyz)
        if other * EXPLAINS_BETTER < aligned:
            file_unit = "rad" if model.angle_unit == "deg" else "deg"
            warn("joint-units",
                 f"the {what} match the model {aligned / other:.0f} times better when the "
                 f"joint columns are read in {file_unit} ({other:.3g} vs {aligned:.3g} {unit} "
                 f"RMS): convert them to the model's angle_unit ({model.angle_unit})")
            explained = True
    if explained:
        return
    e0 = aligned if base_free else float(np.sqrt(((P0 - xyz) ** 2).sum(axis=1).mean()))
    limit = max(REACH_FRACTION * ref.reach, TOLERANCE_FACTOR * ref.tolerance_error)
    if e0 > limit:
        frame = ("" if base_free else "; without a base frame in the model the data must be "
                 "in the robot's base frame (add base: [x, y, z, rx, ry, rz])")
        warn("initial-error",
             f"the {what} are {e0:.4g} {unit} RMS from the nominal model, "
             f"{100 * e0 / ref.reach:.0f} % of its reach ({ref.reach:.4g} {unit}) and beyond "
             f"what its tolerances allow ({limit:.3g} {unit}): probably the wrong model for "
             f"this robot, or wrong joint order or zero offsets{frame}")
