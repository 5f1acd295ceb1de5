"""The poses of a check (``kinecal plan-check``): the few that best reveal the changes robots
usually suffer: a joint's offset (its zero slipped), the base frame (the robot moved on
its mount) and a bent link (a crash: each link's twist, the directions a bend turns the
next axis).

The poses are chosen D-optimally for those directions alone (the greedy build-up and
Fedorov exchanges of `kinecal.calibration.serial.pose_selection.d_optimal`, on their
identification Jacobian with unit-RMS columns), from random candidates within the joint
limits. For each direction the plan says how large a change makes the limit's error over
the workspace (its RMS effect over the candidates: ``at_limit``) and, with the
instrument's noise, the change of that direction alone that the chosen poses see as one
standard error of the noise (``std``: the noise over the root of the sum of its squared
effects): a change at the limit stands ``at_limit / std`` standard errors out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["CheckPlan", "bend_directions", "plan_check"]

Array = NDArray[np.float64]

#: poses a plan may have
MIN_PLAN, MAX_PLAN = 3, 200


def bend_directions(model: SerialModel) -> list[str]:
    """Each link's bend: its twist (D-H family ``alpha``, Hayati's ``beta``) or, for a
    URDF origin, the local rotations about x and y (``wx``, ``wy``)."""
    names = model.parameter_names
    if model.convention == "urdf":
        found = []
        for entry in model.joints:
            if "frame" in entry or not entry.get("name"):
                continue
            found += [f"{entry['name']}.{c}" for c in ("wx", "wy")
                      if f"{entry['name']}.{c}" in names]
        return found
    return [n for n in names if n.startswith(("alpha", "beta")) and n[-1].isdigit()]


@dataclass
class CheckPlan:
    """A check's poses (`plan_check`).

    Attributes
    ----------
    q : ndarray, shape (count, n_joints)
        Joint values in plan order (rad; prismatic joints in the length unit).
    directions : dict
        ``{name: {"at_limit", "std", "unit", "kind"}}`` (model file units).
    observability : dict
        O1..O5 of the directions at the chosen poses.
    """

    q: Array
    directions: dict[str, dict[str, Any]] = field(default_factory=dict)
    observability: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"poses": len(self.q), "directions": self.directions,
                "observability": self.observability}


def _jacobian(model: SerialModel, q: Array, cols: NDArray[np.intp]) -> Array:
    """Per-configuration blocks ``(N, 3 M, k)`` (every marker of each configuration)."""
    from kinecal.calibration.serial.pose_selection import marker_rows

    rows, marker = marker_rows(model, q)
    J = model.identification_jacobian(rows, marker=marker)[:, :, cols]
    return J.reshape(len(q), -1, len(cols))


def plan_check(model: SerialModel, count: int, *, candidates: int = 2000, seed: int = 0,
               sigma: float | None = None, limit: float | None = None) -> CheckPlan:
    """Choose `count` check poses (module docstring)."""
    from kinecal.calibration.identifiability import observability_indices
    from kinecal.calibration.serial.pose_selection import d_optimal
    from kinecal.calibration.serial.simulate import random_configurations
    from kinecal.registry.check import drift_directions

    if not MIN_PLAN <= count <= MAX_PLAN:
        raise InputError(f"expected {MIN_PLAN} to {MAX_PLAN} poses, got {count}",
                         option="--poses")
    if candidates < count:
        raise InputError(f"{candidates} candidates for {count} poses", option="--candidates")
    names = list(dict.fromkeys(drift_directions(model) + bend_directions(model)))
    kinds = {n: ("base" if n.startswith("base.") else "bend" if n in bend_directions(model)
                 else "offset") for n in names}
    cols = model.index(names)
    q = random_configurations(model, candidates, np.random.default_rng(seed))
    B = _jacobian(model, q, cols)
    rms = np.sqrt((B ** 2).sum(axis=(0, 1)) / (B.shape[0] * B.shape[1] / 3))
    live = rms > 1e-12 * max(rms.max(), 1e-300)
    names = [n for n, ok in zip(names, live, strict=True) if ok]
    B, rms = B[:, :, live], rms[live]
    idx = d_optimal(B / rms, count)
    chosen = B[idx].reshape(-1, B.shape[2])
    sv = np.linalg.svd(chosen / rms, compute_uv=False)
    obs = observability_indices(sv, chosen.shape[0])
    seen = np.sqrt((chosen ** 2).sum(axis=0))  # a change of one unit, alone: its effect
    table = {}
    deg = model.angle_unit == "deg"
    for k, n in enumerate(names):
        angle = bool(model.is_angle()[model.index([n])[0]])
        f = (180.0 / np.pi if deg else 1.0) if angle else 1.0
        entry: dict[str, Any] = {"kind": kinds[n],
                                 "unit": model.angle_unit if angle else model.length_unit,
                                 "at_limit": None if limit is None else float(limit / rms[k] * f),
                                 "std": None}
        if sigma is not None:
            entry["std"] = float(sigma / seen[k] * f) if seen[k] > 0 else None
        table[n] = entry
    return CheckPlan(q[np.asarray(idx)], table, {k: float(v) for k, v in obs.items()})
