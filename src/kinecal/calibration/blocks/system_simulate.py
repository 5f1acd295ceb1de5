"""Synthetic measurements of a robot system: rows of each chain from one true system.

* ``tracker``: `n` random configurations per tip (its chain's joints uniform within their
  limits), each tool point (and frame) measured in the one tracker frame;
* ``pair``: `n` bars of length ``L`` between two tips (a bar between two hands): the first
  tip at a random configuration, the second brought by inverse kinematics to a point ``L``
  away in a random direction;
* ``point``: `groups` fixed points, each touched `n` times by every tip given (the points
  both tools touch), configurations by inverse kinematics from random seeds;
* carried points (``carrier``): points fixed in a moving link (a workpiece on a
  positioner's table), each touched `n` times by a tip whose chain is not the carrier's:
  the carrier's joints at random, the tip brought onto the point.

Joints off a row's chain (and its carrier's) are set as the system's readers set them
(zero clipped into their limits), so a file written and read back gives the same rows.
Noise: per coordinate (tracker, points), along the bar (pair).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.simulate import random_configurations
from kinecal.data import GaugeMeasurements, Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.kinematics.tree.system import SystemModel

__all__ = ["SystemSimulation", "simulate_system"]

Array = NDArray[np.float64]
#: attempts (times the rows wanted) at reachable inverse-kinematics targets
OVERSAMPLE = 4


@dataclass(frozen=True)
class SystemSimulation:
    """Rows of a system with their truth (`simulate_system`).

    Attributes
    ----------
    data : Measurements or GaugeMeasurements
    true_params : ndarray, shape (n_params,)
    geometry : dict
        The true gauges: ``centres`` (points; in the carrier's frame for carried points),
        ``length`` (bars).
    """

    data: Measurements | GaugeMeasurements
    true_params: Array
    geometry: dict = field(default_factory=dict)


def _fill(system: SystemModel, q: Array, tips: NDArray[np.intp],
          carrier_joints: NDArray[np.intp] | None = None) -> Array:
    """`q` with the joints off each row's chain (and `carrier_joints`) set as the readers
    set blanks."""
    keep = np.zeros(q.shape, dtype=bool)
    for t, name in enumerate(system.tips):
        keep[np.ix_(tips == t, system.chain_joints(name))] = True
    if carrier_joints is not None:
        keep[:, carrier_joints] = True
    lo, hi = system.joint_limits[:, 0], system.joint_limits[:, 1]
    return np.where(keep, q, np.clip(0.0, lo, hi))


def _reach(system: SystemModel, tip: str, p: Array, targets: Array, q_rest: Array,
           gen: np.random.Generator) -> tuple[Array, NDArray[np.bool_]]:
    """System readings putting `tip` on each of `targets` ``(m, 3)`` (its chain's joints by
    inverse kinematics at `p`, the others from `q_rest` ``(m, n_joints)``), and which
    converged."""
    model = system.tip_model(tip, p)
    src = system._chains[system.tip_number(tip)].source
    seeds = random_configurations(model, len(targets), gen)
    ik = solve_ik(model, targets, seeds, restarts=2, rng=gen)
    q = q_rest.copy()
    q[:, src] = ik.q
    return q, ik.status == "converged"


def _tracker(system, p, n, tips, gen, noise, orientation):
    q = random_configurations(system, n * len(tips), gen)
    tip = np.repeat(np.asarray(tips), n)
    q = _fill(system, q, tip)
    T = system.fk(q, p, tip)
    xyz = T[:, :3, 3] + (gen.normal(0.0, noise, (len(q), 3)) if noise > 0 else 0.0)
    R = T[:, :3, :3] if orientation else None
    return Measurements(q, xyz, None, f"simulated tracker of {system.name}", R, tip,
                        system.tips), {}


def _pair(system, p, n, tips, gen, noise, length):
    if len(tips) != 2:
        raise InputError("a bar between two hands: expected two tips", option="--tip")
    a, b = tips
    m = OVERSAMPLE * n
    q = _fill(system, random_configurations(system, m, gen), np.full(m, a))
    A = system.positions(q, p, np.full(m, a))
    u = gen.normal(size=(m, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    off = gen.normal(0.0, noise, m) if noise > 0 else np.zeros(m)
    qb, ok = _reach(system, system.tips[b], p, A + (length + off)[:, None] * u,
                    random_configurations(system, m, gen), gen)
    ok = np.flatnonzero(ok)
    if ok.size < n:
        raise InputError(f"only {ok.size} of {m} simulated bars between the tips are within "
                         f"reach (wanted {n}): make the bar shorter")
    ok = ok[:n]
    tip = np.tile([a, b], n)
    Q = np.empty((2 * n, system.n_joints))
    Q[0::2], Q[1::2] = q[ok], qb[ok]
    Q = _fill(system, Q, tip)
    data = GaugeMeasurements("pair", Q, np.repeat(np.arange(n), 2),
                             tuple(str(k + 1) for k in range(n)), np.full(2 * n, float(length)),
                             None, f"simulated bars of {system.name}", tip, system.tips)
    return data, {"length": float(length)}


def _points(system, p, n, tips, gen, noise, centres, carrier):
    """Touches of `centres` ``(G, 3)`` by each of `tips` (in `carrier`'s frame when
    given, the carrier's joints at random)."""
    cj = None if carrier is None else system.link_joints(carrier)
    qs, groups, tip_rows = [], [], []
    for g, c in enumerate(centres):
        for t in tips:
            m = OVERSAMPLE * n
            rest = random_configurations(system, m, gen)
            target = np.tile(c, (m, 1))
            if carrier is not None:
                if np.intersect1d(cj, system.chain_joints(system.tips[t])).size:
                    raise InputError(f"tip {system.tips[t]} and carrier {carrier} share joints: "
                                     "such touches are not simulated")
                target = system.link_points(rest, carrier, target, p)[0]
            if noise > 0:
                target = target + gen.normal(0.0, noise, target.shape)
            q, ok = _reach(system, system.tips[t], p, target, rest, gen)
            ok = np.flatnonzero(ok)
            if ok.size < n:
                raise InputError(f"point {g + 1}: tip {system.tips[t]} reaches {ok.size} of "
                                 f"{m} tries (wanted {n}): place it within reach")
            qs.append(q[ok[:n]])
            groups += [g] * n
            tip_rows += [t] * n
    tip = np.array(tip_rows, dtype=np.intp)
    Q = _fill(system, np.concatenate(qs), tip, cj)
    carried = None if carrier is None else np.zeros(len(Q), dtype=np.intp)
    data = GaugeMeasurements("point", Q, np.array(groups, dtype=np.intp),
                             tuple(f"S{g + 1}" for g in range(len(centres))), None, None,
                             f"simulated points of {system.name}", tip, system.tips,
                             carrier=carried, carrier_names=() if carrier is None
                             else (carrier,))
    return data, {"centres": np.asarray(centres, dtype=float)}


def simulate_system(system: SystemModel, n: int, *, kind: str = "tracker",
                    tips: Sequence[str] | None = None, true_params: Array | None = None,
                    noise: float = 0.0, rng: int | np.random.Generator | None = None,
                    orientation: bool = False, length: float | None = None,
                    centres: Array | None = None, carrier: str | None = None
                    ) -> SystemSimulation:
    """Rows of `system` (module docstring).

    Parameters
    ----------
    system : SystemModel
    n : int
        Rows per tip (tracker), bars (pair), touches per point and tip (point).
    kind : {"tracker", "pair", "point"}
    tips : sequence of str, optional
        The chains measured (default all; a pair: two).
    true_params : ndarray, shape (n_params,), optional
        The true system (default nominal).
    noise : float
        Gaussian noise (length unit; per coordinate, along the bar for pairs).
    rng : int or Generator, optional
    orientation : bool
        Tracker: also the tool frames' orientation.
    length : float
        Pair: the bar's length.
    centres : ndarray, shape (G, 3)
        Points: where they are (in `carrier`'s frame when given).
    carrier : str, optional
        Points: the link carrying them (a positioner's table).
    """
    gen = np.random.default_rng(rng)
    p = system.nominal if true_params is None else np.asarray(true_params, dtype=float)
    idx = [system.tip_number(t) for t in (tips or system.tips)]
    if n < 1 or not noise >= 0:
        raise InputError(f"expected n >= 1 and noise >= 0, got {n} and {noise}")
    if kind == "tracker":
        data, geo = _tracker(system, p, n, idx, gen, noise, orientation)
    elif kind == "pair":
        if length is None or not length > 0:
            raise InputError("a bar: expected its length > 0", option="--length")
        data, geo = _pair(system, p, n, idx, gen, noise, float(length))
    elif kind == "point":
        if centres is None:
            raise InputError("points: expected their centres", option="--point")
        data, geo = _points(system, p, n, idx, gen, noise, np.atleast_2d(centres), carrier)
    else:
        raise InputError(f"kind: expected tracker, pair or point on a system, got {kind!r}",
                         option="--kind")
    return SystemSimulation(data, p, geo)
