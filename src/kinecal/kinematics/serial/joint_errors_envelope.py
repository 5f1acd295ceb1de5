"""The joint envelope of a calibration, and joint-error terms held at its edges.

A calibration sees the joints over the ranges its poses span: the *envelope*, per joint
the lowest and highest reading (`JointEnvelope`). Inside it the joint-error terms of
`kinecal.kinematics.serial.joint_errors` are fitted to data; outside, a harmonic series
over a partial turn or a scale term ``s q`` grows or swings freely (a fit over 200 deg of a
joint predicts nothing about the other 160 deg). So a model that carries its envelope
evaluates every term on the readings *retracted* onto it:

* **periodic terms** (harmonics; gravity forces of revolute joints): a revolute joint's
  reading counts modulo a turn. An envelope that spans a full turn leaves them as they
  are. Otherwise the covered arc ``[low, high]`` leaves a gap of width
  ``g = 2 pi - (high - low)``; a reading in the gap, a fraction ``t`` of the way from
  ``high`` to ``low + 2 pi``, gets the terms' values at the two edges blended linearly,
  ``(1 - t) f(high) + t f(low)`` (`bridge`): the correction is held at each edge and
  crosses the gap along a straight line, continuous all round the turn, never beyond the
  values it takes at the edges.
* **scale terms** ``s q`` (not periodic: an encoder gain): the reading clipped to
  ``[low, high]`` (`clip`): held at the edge.
* **gravity forces** depend on the whole configuration: each joint outside is moved to its
  nearest edge (`nearest`), the forces are those of that configuration.

``docs/error-models.md`` gives the reasons and the numbers behind this choice (held-out
series of the UR10 set, synthetic arms calibrated over half a joint's range).

`JointEnvelope.beyond` says by how much rows lie outside, the figure of the
``outside-calibrated-range`` warning (`kinecal.calibration.diagnostics.envelope`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = ["TURN", "JointEnvelope", "Retraction", "envelope_entry", "envelope_from_entry",
           "reading_scale", "smoothstep"]

Array = NDArray[np.float64]
#: one turn (rad)
TURN = 2.0 * np.pi


@dataclass(frozen=True)
class JointEnvelope:
    """Per joint, the lowest and highest reading a calibration saw.

    Attributes
    ----------
    low, high : tuple of float, length n_joints
        Raw readings (rad for revolute joints, length unit for prismatic ones), ``low <=
        high``.
    revolute : tuple of bool, length n_joints
        Revolute joints (their readings also count modulo a turn).
    """

    low: tuple[float, ...]
    high: tuple[float, ...]
    revolute: tuple[bool, ...]

    def __post_init__(self) -> None:
        lo = np.asarray(self.low, dtype=float)
        hi = np.asarray(self.high, dtype=float)
        n = len(self.revolute)
        if lo.shape != (n,) or hi.shape != (n,) or not (np.isfinite(lo).all()
                                                        and np.isfinite(hi).all()):
            raise InputError(f"joint envelope: expected {n} finite [low, high] pairs")
        if (lo > hi).any():
            j = int(np.argmax(lo > hi)) + 1
            raise InputError(f"joint envelope: joint {j} has low > high")
        object.__setattr__(self, "low", tuple(float(v) for v in lo))
        object.__setattr__(self, "high", tuple(float(v) for v in hi))
        object.__setattr__(self, "revolute", tuple(bool(v) for v in self.revolute))

    @classmethod
    def of(cls, q: ArrayLike, revolute: Sequence[bool]) -> JointEnvelope:
        """The envelope of joint readings `q` ``(N, n_joints)`` (N >= 1)."""
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[0] == 0 or q.shape[1] != len(revolute):
            raise InputError(f"joint envelope: expected readings (N >= 1, {len(revolute)}), "
                             f"got {q.shape}")
        return cls(tuple(q.min(axis=0)), tuple(q.max(axis=0)), tuple(revolute))

    @property
    def n_joints(self) -> int:
        return len(self.revolute)

    def full_turn(self) -> NDArray[np.bool_]:
        """``(n_joints,)``: revolute joints whose envelope spans a whole turn."""
        span = np.asarray(self.high) - np.asarray(self.low)
        return np.asarray(self.revolute) & (span >= TURN)

    def _arcs(self) -> tuple[Array, Array, Array]:
        lo, hi = np.asarray(self.low), np.asarray(self.high)
        return lo, hi, np.maximum(TURN - (hi - lo), 0.0)

    def beyond(self, q: ArrayLike, periodic: ArrayLike | None = None) -> Array:
        """Signed distance ``(N, n_joints)`` of each reading outside the envelope: ``> 0``
        above ``high``, ``< 0`` below ``low``, 0 inside.

        `periodic` ``(n_joints,)`` marks the joints compared modulo a turn (default: the
        revolute ones): a reading counts by its nearest edge around the circle, and a joint
        whose envelope spans a turn is never outside. Other joints compare raw readings.
        """
        q = np.asarray(q, dtype=float)
        lo, hi, gap = self._arcs()
        per = (np.asarray(self.revolute) if periodic is None
               else np.asarray(periodic, dtype=bool) & np.asarray(self.revolute))
        out = np.where(q > hi, q - hi, np.where(q < lo, q - lo, 0.0))
        if per.any():
            up = np.mod(q - hi, TURN)  # how far past high, going up around the circle
            inside = up >= gap  # (a reading in [low, high] modulo a turn)
            wrapped = np.where(inside, 0.0, np.where(up <= gap - up, up, up - gap))
            wrapped = np.where(gap > 0, wrapped, 0.0)
            out = np.where(per, wrapped, out)
        return out

    # ------------------------------------------------------------------ retractions
    def clip(self, q: Array) -> Array:
        """Readings clipped to ``[low, high]`` ``(N, n_joints)``: non-periodic terms."""
        return np.clip(q, np.asarray(self.low), np.asarray(self.high))

    def nearest(self, q: Array) -> Array:
        """Readings moved to their nearest edge ``(N, n_joints)``: revolute joints around
        the circle (a reading inside modulo a turn is kept), prismatic ones clipped."""
        d = self.beyond(q)
        return np.where(d != 0, np.where(d > 0, np.asarray(self.high), np.asarray(self.low)),
                        q)

    # ------------------------------------------------------------------ files
    def to_dict(self, scale: Sequence[float]) -> dict:
        """``{"low": [...], "high": [...]}``, readings times `scale` (rad -> file unit)."""
        s = np.asarray(scale, dtype=float)
        return {"low": (np.asarray(self.low) * s).tolist(),
                "high": (np.asarray(self.high) * s).tolist()}

    @classmethod
    def from_dict(cls, raw: object, scale: Sequence[float], revolute: Sequence[bool],
                  where: str = "envelope") -> JointEnvelope:
        """The inverse of `to_dict` (the same `scale`, rad -> file unit: the file's readings
        are divided by it); InputError naming `where`."""
        n = len(revolute)
        if not isinstance(raw, dict) or set(raw) != {"low", "high"}:
            raise InputError(f"{where}: expected {{low: [{n} values], high: [{n} values]}}")
        try:
            lo = np.asarray(raw["low"], dtype=float)
            hi = np.asarray(raw["high"], dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected numbers in low and high") from None
        if lo.shape != (n,) or hi.shape != (n,):
            raise InputError(f"{where}: expected {n} values in low and in high, got "
                             f"{lo.size} and {hi.size}")
        s = np.asarray(scale, dtype=float)
        try:
            return cls(tuple(lo / s), tuple(hi / s), tuple(revolute))
        except InputError as exc:
            raise InputError(f"{where}: {exc.message}") from None


def reading_scale(model: SerialModel) -> list[float]:
    """Per joint, rad to the model's unit of a reading (revolute) or 1 (prismatic)."""
    f = 180.0 / np.pi if model.angle_unit == "deg" else 1.0
    return [f if k != "prismatic" else 1.0 for k in model.joint_kinds]


def envelope_entry(model: SerialModel, envelope: JointEnvelope) -> dict:
    """The ``envelope`` entry of a result JSON: ``{"joints": ["q1", ...], "low": [...],
    "high": [...]}`` in the model's units (its angle unit, length unit for prismatic
    joints)."""
    return {"joints": [f"q{j + 1}" for j in range(envelope.n_joints)],
            **envelope.to_dict(reading_scale(model))}


def envelope_from_entry(model: SerialModel, entry: object, where: str = "envelope"
                        ) -> JointEnvelope:
    """The inverse of `envelope_entry` for `model` (InputError naming `where`)."""
    raw = {k: v for k, v in entry.items() if k != "joints"} if isinstance(entry, dict) else entry
    return JointEnvelope.from_dict(raw, reading_scale(model),
                                   [k != "prismatic" for k in model.joint_kinds], where)


def smoothstep(s: Array) -> tuple[Array, Array]:
    """``3 s^2 - 2 s^3`` on ``[0, 1]`` and its derivative: 0 and 1 at the ends, flat there."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s)


class Retraction:
    """Where joint-error terms are evaluated for readings `q` ``(N, n_joints)``.

    Per joint, two readings ``a``, ``b`` and a weight ``t``: a term ``f`` of the joint
    takes ``(1 - t) f(a) + t f(b)``.

    * Revolute joint, envelope less than a turn: a reading inside the arc modulo a turn is
      evaluated at its equivalent inside ``[low, high]`` (``a = b``, ``t = 0``); a reading
      in the gap at both edges, ``a = high``, ``b = low``, with ``t`` the smoothstep of
      its position ``s`` across the gap (from ``high``): held at each edge (zero slope
      there), crossing the gap continuously. Every term of the joint (harmonics and scale
      alike) is evaluated at the same points, so that terms which cancel inside the
      envelope keep cancelling beyond it.
    * Revolute joint, envelope of a turn or more: periodic terms as they are; the scale
      term at the reading clipped to ``[low, high]``.
    * Prismatic joint: every term at the reading clipped to ``[low, high]``.

    Attributes
    ----------
    a, b, t : ndarray, shape (N, n_joints)
        Evaluation readings and weights of the joints' own (periodic) terms.
    dt : ndarray, shape (N, n_joints)
        ``d t / d q`` (0 outside gaps).
    slope : ndarray, shape (N, n_joints)
        ``d a / d q`` where ``t = 0``: 1 inside, 0 where a reading is held at an edge.
    """

    def __init__(self, envelope: JointEnvelope | None, q: Array) -> None:
        q = np.asarray(q, dtype=float)
        self.q = q
        self.a = q.copy()
        self.b = q.copy()
        self.t = np.zeros_like(q)
        self.dt = np.zeros_like(q)
        self.slope = np.ones_like(q)
        self.low = self.high = None
        if envelope is not None:
            self._setup(np.broadcast_to(np.asarray(envelope.low), q.shape),
                        np.broadcast_to(np.asarray(envelope.high), q.shape),
                        np.asarray(envelope.revolute))

    @classmethod
    def rows(cls, q: Array, low: Array, high: Array, revolute) -> Retraction:
        """Readings `q` ``(N, n_joints)``, each row against its own envelope `low`, `high`
        ``(N, n_joints)`` (cross-validation: each fold's training poses)."""
        out = cls(None, q)
        out._setup(np.asarray(low, dtype=float), np.asarray(high, dtype=float),
                   np.asarray(revolute, dtype=bool))
        return out

    def _setup(self, lo: Array, hi: Array, rev: NDArray[np.bool_]) -> None:
        q = self.q
        self.low, self.high = lo, hi
        span = hi - lo
        gap = np.maximum(TURN - span, 0.0)
        self.full = rev & (span >= TURN)
        partial = rev & ~self.full
        up = np.mod(q - hi, TURN)  # past high, going up around the circle
        out = partial & (up < gap)
        t, dts = smoothstep(np.where(out, up / np.where(gap > 0, gap, 1.0), 0.0))
        self.a = np.where(partial, np.where(out, hi, hi + up - TURN), q)
        self.b = np.where(out, lo, self.a)
        self.t = np.where(out, t, 0.0)
        self.dt = np.where(out, dts / np.where(gap > 0, gap, 1.0), 0.0)
        clip = np.clip(q, lo, hi)
        self.a = np.where(rev, self.a, clip)
        self.b = np.where(rev, self.b, clip)
        self.slope = np.where(rev, 1.0, (q >= lo) & (q <= hi)).astype(float)

    def one_joint(self, j: int, f, df, periodic: bool) -> tuple[Array, Array]:
        """A term ``f`` of joint `j` alone (``df`` its derivative): values ``(N,)`` and
        ``d / d q_j`` ``(N,)``; `periodic` terms (harmonics) see a full-turn envelope as
        no limit, the others (scale) are clipped to it."""
        a, b, t = self.a[:, j], self.b[:, j], self.t[:, j]
        slope = self.slope[:, j]
        if self.low is not None and not periodic and self.full[:, j].any():
            x, lo, hi = self.q[:, j], self.low[:, j], self.high[:, j]
            full = self.full[:, j]
            a = np.where(full, np.clip(x, lo, hi), a)
            b = np.where(full, a, b)
            slope = np.where(full, (x >= lo) & (x <= hi), slope)
        fa = f(a)
        if not t.any():
            return fa, df(a) * slope
        fb = f(b)
        gap = t > 0
        value = np.where(gap, (1.0 - t) * fa + t * fb, fa)
        deriv = np.where(gap, (fb - fa) * self.dt[:, j], df(a) * slope)
        return value, deriv

    def blended(self, fn, derivatives: bool) -> tuple[Array, Array | None]:
        """A function of the whole configuration, ``fn(Q, derivatives) -> (F (N, k),
        dF (N, k, n_joints) or None)``, blended over the corners of every gap a reading
        lies in (multilinear in the weights ``t``): values ``(N, k)`` and derivatives with
        respect to the raw readings ``(N, k, n_joints)``.

        Two calls of `fn`: the readings in no gap, and every (reading, corner) pair of the
        others stacked (a reading in gaps of ``g`` joints has ``2^g`` corners)."""
        gap = self.t > 0
        if not gap.any():
            F, dF = fn(self.a, derivatives)
            return F, None if dF is None else dF * self.slope[:, None, :]
        rows = np.flatnonzero(gap.any(axis=1))
        plain = np.flatnonzero(~gap.any(axis=1))
        g = gap[rows]
        counts = 1 << g.sum(axis=1)
        row_of = np.repeat(np.arange(rows.size), counts)
        corner = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        G = g[row_of]
        order = np.maximum(np.cumsum(g, axis=1) - 1, 0)[row_of]  # a joint's bit in the corner
        at_b = G & (((corner[:, None] >> order) & 1) == 1)
        src = rows[row_of]
        Q = np.where(at_b, self.b[src], self.a[src])
        t = self.t[src]
        wj = np.where(G, np.where(at_b, t, 1.0 - t), 1.0)  # per joint, in (0, 1]
        w = np.prod(wj, axis=1)
        Fc, dFc = fn(Q, derivatives)
        N, n = self.q.shape
        F = np.zeros((N, Fc.shape[1]))
        dF = np.zeros((N, Fc.shape[1], n)) if derivatives else None
        if plain.size:
            Fp, dFp = fn(self.a[plain], derivatives)
            F[plain] = Fp
            if derivatives:
                dF[plain] = dFp * self.slope[plain][:, None, :]
        out = np.zeros((rows.size, Fc.shape[1]))
        np.add.at(out, row_of, w[:, None] * Fc)
        F[rows] = out
        if derivatives:
            # d w / d q_j for a joint in a gap: +-(product of the others' weights) dt_j/dq_j
            dw = np.where(G, np.where(at_b, 1.0, -1.0) * w[:, None] / wj * self.dt[src], 0.0)
            free = self.slope[src] * ~G  # joints in no gap move the corners themselves
            dout = np.zeros((rows.size, Fc.shape[1], self.q.shape[1]))
            np.add.at(dout, row_of, w[:, None, None] * dFc * free[:, None, :]
                      + Fc[:, :, None] * dw[:, None, :])
            dF[rows] = dout
        return F, dF
