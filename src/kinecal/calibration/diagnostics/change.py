"""Did the calibration change the arm more than a calibration can? (``implausible-change``)

A calibration moves an arm's tool poses by millimetres and tenths of a degree. When a fit
moves them by a sizeable part of the arm (a joint offset turned by 142 deg, the tool moved
by 152 mm: 30 plane touches of a 3-joint arm that pin too little), the result is not the
same arm any more, and ``fk --params``, ``export``, ``compensate`` and `kinecal.load_result`
refuse it. The calibration says so itself, with the same rule
(`kinecal.kinematics.serial.same_arm.compare_arms`, one function for both): a result
that passes here is never refused later, and one that is refused later was warned about.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.diagnostics import warn
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.same_arm import ArmComparison, compare_arms

__all__ = ["check_change"]

Array = NDArray[np.float64]


def _moves(model: SerialModel, params: Array, std: Array, names: Sequence[str],
           prior_decided: Sequence[str]) -> str:
    """The free parameters that moved most (in tolerances), with their standard errors."""
    if not names:
        return ""
    idx = model.index(list(names))
    angle = model.is_angle()[idx]
    tol = np.where(angle, model.tolerances["angle"], model.tolerances["length"])
    delta = np.asarray(params, float)[idx] - model.nominal[idx]
    order = np.argsort(-np.abs(delta) / tol)[:3]
    deg = model.angle_unit == "deg"
    out = []
    for i in order:
        if delta[i] == 0:
            continue
        f = np.degrees(1.0) if angle[i] and deg else 1.0
        unit = model.angle_unit if angle[i] else model.length_unit
        s = std[idx[i]]
        sd = f"sigma {s * f:.3g} {unit}" if np.isfinite(s) else "no standard error"
        who = ", decided by the prior" if names[i] in prior_decided else ""
        out.append(f"{names[i]} {delta[i] * f:+.4g} {unit} ({sd}{who})")
    return "; ".join(out)


def check_change(nominal: SerialModel, params: Array, std: Array, free: Sequence[str], *,
                 prior_decided: Sequence[str] = (), prior: str | None = None,
                 kinds: Sequence[str] = ()) -> ArmComparison | None:
    """``implausible-change``: the calibrated model is not a calibration of the same arm
    by the rule the commands that read results refuse it with.

    Parameters
    ----------
    nominal : SerialModel
        The model calibrated (with its markers).
    params : ndarray, shape (n_params,)
        Identified parameters (length unit, rad).
    std : ndarray, shape (n_params,)
        Their standard errors (``inf`` where not identifiable).
    free : sequence of str
        The free parameters (those named in the message).
    prior_decided : sequence of str
        Free parameters a prior decided rather than the data (named so in the message).
    prior : {None, "used", "declined"}
        No prior was asked for; one was used (the advice then is a tighter one); ``auto``
        found none the data support (the advice then is to state one).
    kinds : sequence of str
        Measurement kinds of the data (``point`` / ``plane``: known fixture coordinates
        are advised too).

    Returns
    -------
    ArmComparison or None
        The rule's verdict (its ``same`` is False when warned); None when the values
        make no chain of this arm at all (warned too).
    """
    try:
        calibrated = nominal.with_params(np.asarray(params, float),
                                         name=f"{nominal.name}-calibrated")
        found = compare_arms(nominal, calibrated)
    except InputError as exc:  # values no chain of this arm accepts: refused later too
        found = None
        finding = exc.message
    else:
        if found.same:
            return found
        finding = found.finding
    moves = _moves(nominal, params, np.asarray(std, float), list(free), prior_decided)
    if prior == "used":
        todo = ("a prior on more of the free parameters, or a tighter one (smaller --prior "
                "sigmas)")
    elif prior == "declined":
        todo = ("a prior of stated sigmas (--prior lengths=S,angles=S, e.g. the model's "
                "tolerances: cross-validation found no strength these data support)")
    else:
        todo = "a prior on the parameters (--prior auto, or --prior lengths=S,angles=S)"
    fixtures = (", known fixture coordinates for the points and planes"
                if {"point", "plane"} & set(kinds) else ", fixtures of known geometry")
    warn("implausible-change",
         f"the calibration changed the arm more than a calibration can: {finding}"
         + (f"; largest changes: {moves}" if moves else "")
         + ". fk --params, export and compensate will refuse this result. Check the "
         "data first (units, frame, joint order, another robot's file: the other "
         f"warnings); if they are right, use {todo}, more and better spread "
         f"poses{fixtures}, or fewer free parameters (--free)")
    return found
