"""Synthetic measurements of each gauge kind from a (perturbed) arm.

Each kind's rows are joint readings that put the *true* arm's tool point where the gauge
holds it, found by inverse kinematics (`kinecal.kinematics.serial.ik.solve_ik`, position
targets) from random seeds within the joint limits, so that a point is touched in many
arm configurations:

* ``ballbar``: the tool point on the sphere of radius ``L`` about each pivot (random
  directions); the file's distance is the true one plus Gaussian noise ``noise``;
* ``pair``: a bar of length ``L`` placed at random in the workspace, touched at both
  ends; the second end is off by ``noise`` along the bar (the file states ``L``);
* ``point``: each fixed point touched with a 3-D Gaussian error ``noise`` per coordinate;
* ``plane``: each plane touched at random points within ``radius`` of its centre, off the
  plane by ``noise`` along its normal.

Without a stated geometry the pivots, points and planes are placed at reachable points of
the workspace (`default_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.simulate import random_configurations
from kinecal.data import GAUGE_KINDS, GaugeMeasurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["MAX_SIMULATED_ROWS", "KindSimulation", "default_geometry", "reach", "simulate_kind"]

Array = NDArray[np.float64]

#: candidate targets per row wanted (unreachable ones are dropped)
OVERSAMPLE = 3
#: most rows one simulation makes: each is an inverse kinematics solve (about 0.3 ms;
#: ``--groups 1000000`` ran for hours)
MAX_SIMULATED_ROWS = 20_000


@dataclass(frozen=True)
class KindSimulation:
    """Synthetic gauge measurements with their truth.

    Attributes
    ----------
    data : GaugeMeasurements
    true_params : ndarray, shape (n_params,)
    geometry : dict
        The gauge's true geometry: ``centres`` ``(G, 3)`` (pivots, points), ``planes``
        ``(G, 6)`` (a point and the unit normal), ``length``, ``noise``.
    """

    data: GaugeMeasurements
    true_params: Array
    geometry: dict = field(default_factory=dict)


def reach(model: SerialModel, params: Array | None = None, n: int = 400) -> tuple[float, Array]:
    """The largest distance of the tool point from the base origin over random
    configurations (seed 0), and those tool points ``(n, 3)``."""
    q = random_configurations(model, n, np.random.default_rng(0))
    P = model.positions(q, params)
    p = model.nominal if params is None else params
    origin = p[model.index(["base.x", "base.y", "base.z"])]
    return float(np.linalg.norm(P - origin, axis=1).max()), P


def default_geometry(model: SerialModel, kind: str, count: int,
                     rng: np.random.Generator) -> dict:
    """Reachable pivots / points (``centres``) or planes for `kind`, and a bar length.

    Centres are tool points of random configurations whose distance from the base origin
    is 40-70 % of the reach; planes alternate horizontal and vertical through such points.
    """
    R, P = reach(model)
    p = model.nominal
    origin = p[model.index(["base.x", "base.y", "base.z"])]
    d = np.linalg.norm(P - origin, axis=1)
    pool = P[(d > 0.4 * R) & (d < 0.7 * R)]
    if len(pool) < count:
        pool = P
    centres = pool[rng.choice(len(pool), size=count, replace=len(pool) < count)]
    out = {"centres": centres, "length": round(float(0.25 * R), 1 if R < 100 else -1)}
    if kind == "plane":
        normals = np.array([[0.0, 0.0, 1.0] if g % 2 == 0 else
                            [np.cos(g), np.sin(g), 0.0] for g in range(count)])
        out["planes"] = np.column_stack([centres, normals])
        out["radius"] = 0.2 * R
    return out


def _reach_targets(model: SerialModel, params: Array, makers: list, want: int,
                   gen: np.random.Generator) -> list[Array]:
    """Joint readings ``(want, n_joints)`` per group: ``makers[g](m)`` draws ``m`` targets
    ``(m, 3)`` of group ``g``; the first `want` the arm reaches from random seeds are kept
    (one batch for all groups; groups short of reachable targets draw `OVERSAMPLE` times
    more, twice, before an InputError)."""
    out: list[Array | None] = [None] * len(makers)
    m = OVERSAMPLE * want
    for _ in range(3):
        todo = [g for g, q in enumerate(out) if q is None]
        if not todo:
            break
        targets = [makers[g](m) for g in todo]
        T = np.concatenate(targets)
        ik = solve_ik(model, T, random_configurations(model, len(T), gen), params=params,
                      restarts=2, rng=gen)
        ok = ik.status == "converged"
        start = 0
        for g, t in zip(todo, targets, strict=True):
            hit = np.flatnonzero(ok[start:start + len(t)])
            if hit.size >= want:
                out[g] = ik.q[start + hit[:want]]
            start += len(t)
        m *= OVERSAMPLE
    if any(q is None for q in out):
        raise InputError(f"a simulated gauge has fewer than {want} targets within reach of "
                         "the arm: move it closer or make it smaller")
    return out


def _unit_vectors(gen: np.random.Generator, n: int) -> Array:
    u = gen.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1)[:, None]


def simulate_kind(model: SerialModel, kind: str, n: int, *, true_params: Array | None = None,
                  noise: float = 0.0, rng: int | np.random.Generator | None = None,
                  centres: Array | None = None, planes: Array | None = None,
                  length: float | None = None, radius: float | None = None,
                  groups: int | None = None, option: str = "--poses") -> KindSimulation:
    """Simulated rows of one gauge kind (module docstring).

    Parameters
    ----------
    model : SerialModel
        Nominal model.
    kind : {"ballbar", "pair", "point", "plane"}
    n : int
        Rows per pivot (ballbar), pairs (pair), touches per point or per plane.
    true_params : ndarray, shape (n_params,), optional
        The true arm (default nominal).
    noise : float
        Gaussian noise (length unit; the kind's meaning, module docstring).
    rng : int or Generator, optional
    centres : ndarray, shape (G, 3), optional
        Pivots (ballbar) or points (point).
    planes : ndarray, shape (G, 6), optional
        A point on each plane and its normal.
    length : float, optional
        Ballbar or bar length (default a quarter of the reach).
    radius : float, optional
        Planes: touches within this distance of the plane's point (default 1/5 reach).
    groups : int, optional
        Number of pivots / points / planes when not given (default 2 / 4 / 2).
    option : str
        What `n` was given as (named when the rows exceed `MAX_SIMULATED_ROWS`).
    """
    if kind not in GAUGE_KINDS:
        raise InputError(f"kind: expected one of {', '.join(GAUGE_KINDS)}, got {kind!r}",
                         option="--kind")
    if n < 1:
        raise InputError(f"expected at least 1 row per gauge, got {n}", option="--poses")
    if not noise >= 0:
        raise InputError(f"noise: expected >= 0, got {noise}", option="--noise")
    gen = np.random.default_rng(rng)
    p = model.nominal if true_params is None else np.asarray(true_params, dtype=float)
    from kinecal.calibration.diagnostics import sizes  # noise and errors within the machine

    sizes.check_length_noise(noise, sizes.serial_size(model), "--noise", model.length_unit)
    sizes.check_deviations(model, p - model.nominal)
    count = groups or {"ballbar": 2, "point": 4, "plane": 2, "pair": 1}[kind]
    given = planes if planes is not None else centres
    rows = 2 * n if kind == "pair" else n * (count if given is None else len(np.atleast_2d(given)))
    if rows > MAX_SIMULATED_ROWS:
        how = f"{n} pairs x 2" if kind == "pair" else f"{n} per gauge x {rows // n} gauges"
        raise InputError(f"{rows} {kind} rows asked for ({how}): expected at "
                         f"most {MAX_SIMULATED_ROWS} (each row is an inverse kinematics "
                         "solve; a gauge test has tens to hundreds of rows)", option=option)
    geo = default_geometry(model, kind, count, gen)
    if centres is not None:
        geo["centres"] = np.atleast_2d(np.asarray(centres, dtype=float))
    if planes is not None:
        pl = np.atleast_2d(np.asarray(planes, dtype=float))
        pl[:, 3:] /= np.linalg.norm(pl[:, 3:], axis=1)[:, None]
        geo["planes"], geo["centres"] = pl, pl[:, :3]
    if length is not None:
        geo["length"] = float(length)
    if radius is not None:
        geo["radius"] = float(radius)
    geo["noise"] = float(noise)
    rows = _KINDS[kind](model, p, n, noise, gen, geo)
    q, group, distance = rows
    prefix = {"ballbar": "P", "pair": "", "point": "S", "plane": "F"}[kind]
    names = tuple(f"{prefix}{g + 1}" for g in range(int(group.max()) + 1))
    data = GaugeMeasurements(kind, q, group.astype(np.intp), names, distance,
                             source=f"simulated {kind} of {model.name}")
    return KindSimulation(data, p, geo)


def _ballbar(model, p, n, noise, gen, geo):
    C = geo["centres"]
    makers = [lambda m, c=c: c + geo["length"] * _unit_vectors(gen, m) for c in C]
    q = np.concatenate(_reach_targets(model, p, makers, n, gen))
    group = np.repeat(np.arange(len(C)), n)
    d = np.linalg.norm(model.positions(q, p) - C[group], axis=1)
    return q, group, (d + gen.normal(0.0, noise, len(d)) if noise > 0 else d)


def _point(model, p, n, noise, gen, geo):
    C = geo["centres"]
    makers = [lambda m, c=c: c + (gen.normal(0.0, noise, (m, 3)) if noise > 0
                                  else np.zeros((m, 3))) for c in C]
    return (np.concatenate(_reach_targets(model, p, makers, n, gen)),
            np.repeat(np.arange(len(C)), n), None)


def _plane_maker(row, radius, noise, gen):
    c, nrm = row[:3], row[3:]
    t1 = np.cross(nrm, np.eye(3)[int(np.argmin(np.abs(nrm)))])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(nrm, t1)

    def make(m):
        rad = radius * np.sqrt(gen.uniform(size=m))
        ang = gen.uniform(0, 2 * np.pi, m)
        off = gen.normal(0.0, noise, m) if noise > 0 else np.zeros(m)
        return (c + (rad * np.cos(ang))[:, None] * t1 + (rad * np.sin(ang))[:, None] * t2
                + off[:, None] * nrm)

    return make


def _plane(model, p, n, noise, gen, geo):
    makers = [_plane_maker(row, geo["radius"], noise, gen) for row in geo["planes"]]
    return (np.concatenate(_reach_targets(model, p, makers, n, gen)),
            np.repeat(np.arange(len(geo["planes"])), n), None)


def _pair(model, p, n, noise, gen, geo):
    L = geo["length"]
    m = OVERSAMPLE * n
    qa = random_configurations(model, m, gen)
    A = model.positions(qa, p)
    u = _unit_vectors(gen, m)
    off = gen.normal(0.0, noise, m) if noise > 0 else np.zeros(m)
    seeds = random_configurations(model, m, gen)
    ik = solve_ik(model, A + (L + off)[:, None] * u, seeds, params=p, restarts=2, rng=gen)
    ok = np.flatnonzero(ik.status == "converged")
    if ok.size < n:
        raise InputError(f"only {ok.size} of {m} simulated bar placements are within reach "
                         f"(wanted {n}): make the bar shorter")
    ok = ok[:n]
    q = np.empty((2 * n, model.n_joints))
    q[0::2], q[1::2] = qa[ok], ik.q[ok]
    return q, np.repeat(np.arange(n), 2), np.full(2 * n, float(L))


_KINDS = {"ballbar": _ballbar, "point": _point, "plane": _plane, "pair": _pair}
