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
        self.envelope = envelope
        self.a = q.copy()
        self.b = q.copy()
        self.t = np.zeros_like(q)
        self.dt = np.zeros_like(q)
        self.slope = np.ones_like(q)
        if envelope is None:
            return
        lo, hi, gap = envelope._arcs()
        rev = np.asarray(envelope.revolute)
        full = envelope.full_turn()
        for j in range(q.shape[1]):
            x = q[:, j]
            if rev[j] and not full[j]:
                up = np.mod(x - hi[j], TURN)  # past high, going up around the circle
                out = up < gap[j]
                t, dts = smoothstep(up / gap[j])
                self.a[:, j] = np.where(out, hi[j], hi[j] + up - TURN)
                self.b[:, j] = np.where(out, lo[j], self.a[:, j])
                self.t[:, j] = np.where(out, t, 0.0)
                self.dt[:, j] = np.where(out, dts / gap[j], 0.0)
            elif not rev[j]:
                self.a[:, j] = self.b[:, j] = np.clip(x, lo[j], hi[j])
                self.slope[:, j] = (x >= lo[j]) & (x <= hi[j])

    def one_joint(self, j: int, f, df, periodic: bool) -> tuple[Array, Array]:
        """A term ``f`` of joint `j` alone (``df`` its derivative): values ``(N,)`` and
        ``d / d q_j`` ``(N,)``; `periodic` terms (harmonics) see a full-turn envelope as
        no limit, the others (scale) are clipped to it."""
        env = self.envelope
        if env is not None and not periodic and env.full_turn()[j]:
            x = self.q[:, j]
            lo, hi = env.low[j], env.high[j]
            return f(np.clip(x, lo, hi)), df(np.clip(x, lo, hi)) * ((x >= lo) & (x <= hi))
        a, b, t = self.a[:, j], self.b[:, j], self.t[:, j]
        fa = f(a)
        if not t.any():
            return fa, df(a) * self.slope[:, j]
        fb = f(b)
        gap = t > 0
        value = np.where(gap, (1.0 - t) * fa + t * fb, fa)
        deriv = np.where(gap, (fb - fa) * self.dt[:, j], df(a) * self.slope[:, j])
        return value, deriv

    def blended(self, fn, derivatives: bool) -> tuple[Array, Array | None]:
        """A function of the whole configuration, ``fn(Q, derivatives) -> (F (N, k),
        dF (N, k, n_joints) or None)``, blended over the corners of every gap a reading
        lies in (multilinear in the weights ``t``): values ``(N, k)`` and derivatives with
        respect to the raw readings ``(N, k, n_joints)``."""
        gap = self.t > 0
        if not gap.any():
            F, dF = fn(self.a, derivatives)
            return F, None if dF is None else dF * self.slope[:, None, :]
        N, n = self.q.shape
        patterns, which = np.unique(gap, axis=0, return_inverse=True)
        F = dF = None
        for p, pattern in enumerate(patterns):
            rows = np.flatnonzero(which.ravel() == p)
            joints = np.flatnonzero(pattern)
            for corner in range(1 << joints.size):
                bits = [(corner >> i) & 1 for i in range(joints.size)]
                Q = self.a[rows].copy()
                w = np.ones(rows.size)
                dw = np.zeros((rows.size, n))
                for i, (j, bit) in enumerate(zip(joints, bits, strict=True)):
                    t = self.t[rows, j]
                    if bit:
                        Q[:, j] = self.b[rows, j]
                    others = np.prod([self.t[rows, jj] if bb else 1.0 - self.t[rows, jj]
                                      for ii, (jj, bb) in enumerate(zip(joints, bits,
                                                                        strict=True))
                                      if ii != i], axis=0) if joints.size > 1 else 1.0
                    w = w * (t if bit else 1.0 - t)
                    dw[:, j] = (1.0 if bit else -1.0) * others * self.dt[rows, j]
                Fc, dFc = fn(Q, derivatives)
                if F is None:
                    F = np.zeros((N, Fc.shape[1]))
                    dF = np.zeros((N, Fc.shape[1], n)) if derivatives else None
                F[rows] += w[:, None] * Fc
                if derivatives:
                    free = self.slope[rows] * ~pattern  # joints not in a gap
                    dF[rows] += (w[:, None, None] * dFc * free[:, None, :]
                                 + Fc[:, :, None] * dw[:, None, :])
        return F, dF
