"""Non-geometric errors as joint-angle corrections ``q_j -> q_j + dq_j(q, c)``.

A geometric model says where the tool is for perfect joints; real joints bend under
gravity and their transmissions (gears, encoders) add errors periodic in the joint angle.
Industrial calibration packages model both on top of the geometry. kinecal adds them as
corrections of the joint readings before the chain is composed, so the chain and its
analytic Jacobian stay as they are and every term enters through the chain rule:

* **gravity compliance** (family ``compliance``): ``dq_j = sum_m c_jm tau_jm(q) / R``,
  the generalised gravity force of a point mass ``m`` on joint ``j``
  (`kinecal.kinematics.serial.gravity`), computed on the nominal kinematics, per lever ``R`` (the
  sum of the chain's translations, a bound of its reach; `JointErrorTerms.lever`). With
  a mass model (link masses and centres of mass, a payload) there is one coefficient per
  joint, ``dq_j = c_j sum_m mass_m tau_jm / R``, named ``dq{j}.compliance``; without one,
  a generic basis of unit point masses at the link frames (end of each joint's entry) and
  the tool point, one coefficient per (joint, mass): ``dq{j}.compliance.link{k}``,
  ``dq{j}.compliance.tool``. A revolute joint's coefficient is an angle: its deflection
  under a unit mass (mass model: its masses) at lever ``R``, i.e. ``c = g R / k`` for a
  joint stiffness ``k``. A prismatic joint's is a length per unit mass.
* **harmonic transmission errors** (family ``harmonic``, revolute joints): ``dq_j = sum_h
  a_jh sin(h q_j) + b_jh cos(h q_j)`` for ``h = 1..H``, named ``dq{j}.sin{h}``,
  ``dq{j}.cos{h}`` (angles).
* **joint scale** (family ``scale``, encoder gain or screw-pitch error): ``dq_j = s_j q_j``,
  named ``dq{j}.scale`` (dimensionless).

Joints are numbered from 1 in names and files. Every term is linear in its coefficient:
``dq_j = sum_k c_k w_k(q)`` over the coefficients ``k`` of joint ``j``, with the basis
``w_k(q)`` (`JointErrorTerms.basis`) independent of the geometric parameters; so
``d dq / d c`` is the basis, and ``d dq / d q`` (for inverse kinematics) follows from the
derivatives of the sines, cosines and gravity forces.

The coefficients are extra named parameters appended to the model's parameter vector
(`kinecal.kinematics.serial.model.SerialModel`, field ``joint_errors``); a model without joint
errors is unchanged.

A model whose terms carry the joint envelope they were fitted on (``JointErrors.envelope``,
every calibrated model) evaluates them on readings retracted onto it: held at its edges
beyond it (`kinecal.kinematics.serial.joint_errors_envelope`); and a joint's own terms
(harmonics, scale) are taken relative to their value at the middle of its range, so that
they vanish there and the joint offset alone carries the constant.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.gravity import LoadPoint, chain_frames, gravity_forces
from kinecal.kinematics.serial.joint_error_spec import (
    FAMILIES,
    JointErrors,
    PointMass,
    joint_errors_for,
)
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope, Retraction
from kinecal.kinematics.serial.motions import PRISMATIC, TRANSLATION

if TYPE_CHECKING:
    from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "FAMILIES",
    "JointErrorTerms",
    "JointErrors",
    "PointMass",
    "joint_errors_for",
]

Array = NDArray[np.float64]

#: joint readings whose bases are cached per model (repeated evaluations at the same poses)
_CACHE_ENTRIES = 4
#: largest basis (poses x coefficients) that is cached
_CACHE_ELEMENTS = 4_000_000


@dataclass(frozen=True)
class _Term:
    name: str
    family: str
    joint: int  # 0-based
    order: int = 0  # harmonics: h; sin (order > 0) or cos (order < 0)
    pair: int = -1  # compliance: column of the gravity-force table


def _identity(x: Array) -> Array:
    return x


class JointErrorTerms:
    """`JointErrors` bound to a model's chain: names, basis, corrections, derivatives.

    Parameters
    ----------
    model : SerialModel
        The model (its chain, joint kinds and geometric nominal values; built before its
        parameter vector is extended).
    spec : JointErrors

    Attributes
    ----------
    names : tuple of str
        Coefficient names, in parameter-vector order.
    nominal : ndarray, shape (n,)
        Coefficient values of `spec` (0 where absent).
    """

    def __init__(self, model: SerialModel, spec: JointErrors) -> None:
        self.spec = spec
        n = model.n_joints
        self.n_joints = n
        self.kinds = tuple(model.joint_kinds)
        self._motions = model.motions
        self._owners = model._chain.owners
        self._motion_index = model._motion_index
        geo_names = model._chain.names
        ref = dict(zip(geo_names, model._nominal[: len(geo_names)].tolist(), strict=True))
        if spec.reference is not None:
            unknown = set(spec.reference) - set(geo_names)
            if unknown:
                raise InputError(f"joint_errors.reference: unknown parameter(s) "
                                 f"{sorted(unknown)}")
            ref.update({k: float(v) for k, v in spec.reference.items()})
        self.reference = ref
        self._ref_vector = np.array([ref[k] for k in geo_names])
        # lever of the gravity forces: the chain's translations summed (a bound of the reach)
        lever = sum(abs(ref[m.name]) for m, owner in zip(model.motions, self._owners,
                                                          strict=True)
                    if owner != "base" and m.kind == TRANSLATION and m.joint is None)
        self.lever = float(lever) if lever > 0 else 1.0
        self._check_joints(spec)
        self._groups: list[tuple[int, int]] = []  # mass model: pairs summed per term
        self._loads, self._pairs, terms = self._gravity_terms(spec)
        for j in spec.harmonic_joints:
            for h in range(1, spec.harmonics + 1):
                terms.append(_Term(f"dq{j}.sin{h}", "harmonic", j - 1, h))
                terms.append(_Term(f"dq{j}.cos{h}", "harmonic", j - 1, -h))
        terms += [_Term(f"dq{j}.scale", "scale", j - 1) for j in spec.scale]
        self._terms = tuple(terms)
        self.names = tuple(t.name for t in terms)
        index = {nm: k for k, nm in enumerate(self.names)}
        unknown = [k for k in spec.values if k not in index]
        if unknown:
            raise InputError(f"joint_errors.values: {unknown[0]!r} is not a term of this model "
                             f"(terms: {', '.join(self.names) or 'none'})")
        self.nominal = np.zeros(len(terms))
        for k, v in spec.values.items():
            self.nominal[index[k]] = float(v)
        self.joint_of = np.array([t.joint for t in terms], dtype=np.intp)
        env = spec.envelope
        #: where a joint's own terms vanish (the middle of its calibrated range)
        self._anchor = (None if env is None else
                        0.5 * (np.asarray(env.low) + np.asarray(env.high)))
        self.families = tuple(t.family for t in terms)
        self._cache: OrderedDict = OrderedDict()

    # ------------------------------------------------------------------ set-up
    def _check_joints(self, spec: JointErrors) -> None:
        n = self.n_joints
        for key in ("compliance", "harmonic_joints", "scale"):
            joints = getattr(spec, key)
            bad = [j for j in joints if not 1 <= j <= n]
            if bad or len(set(joints)) != len(joints):
                raise InputError(f"joint_errors.{key}: expected distinct joints 1..{n}, "
                                 f"got {list(joints)}")
        env = spec.envelope
        if env is not None and env.revolute != tuple(k != PRISMATIC for k in self.kinds):
            raise InputError(f"joint_errors.envelope: expected {n} joints of kinds "
                             f"{', '.join(self.kinds)}, got {env.n_joints}")
        prismatic = [j for j in spec.harmonic_joints if self.kinds[j - 1] == PRISMATIC]
        if prismatic:
            raise InputError(f"joint_errors: harmonic terms need revolute joints; joint(s) "
                             f"{prismatic} are prismatic")
        for mass in (spec.masses or ()):
            if not 1 <= mass.joint <= n:
                raise InputError(f"joint_errors.masses: joint {mass.joint}: expected 1..{n}")
            if not (np.isfinite(mass.mass) and mass.mass >= 0):
                raise InputError(f"joint_errors.masses: mass {mass.mass!r}: expected >= 0")

    def _gravity_terms(self, spec: JointErrors) -> tuple[list, list, list[_Term]]:
        """Point masses ``(link, kind, com, mass)`` and (joint, mass) pairs of compliance."""
        n = self.n_joints
        if spec.masses is None:  # generic basis: unit masses at link frames and the tool
            loads = [(k, "link", (0.0, 0.0, 0.0), 1.0) for k in range(n)]
            loads.append((n - 1, "tool", None, 1.0))
        else:
            loads = [(m.joint - 1, "link", m.com, float(m.mass)) for m in spec.masses]
            if spec.payload is not None:
                loads.append((n - 1, "payload", spec.payload.com, float(spec.payload.mass)))
        pairs: list[tuple[int, int]] = []
        terms: list[_Term] = []
        for j in spec.compliance:
            jj = j - 1
            if spec.masses is None:
                for m, (link, kind, _, _) in enumerate(loads):
                    if link >= jj:
                        label = "tool" if kind == "tool" else f"link{link + 1}"
                        terms.append(_Term(f"dq{j}.compliance.{label}", "compliance", jj,
                                           pair=len(pairs)))
                        pairs.append((jj, m))
            else:
                terms.append(_Term(f"dq{j}.compliance", "compliance", jj, pair=len(terms)))
                start = len(pairs)
                pairs += [(jj, m) for m, ld in enumerate(loads) if ld[0] >= jj]
                self._groups.append((start, len(pairs)))
        return loads, pairs, terms

    @property
    def n(self) -> int:
        """Number of coefficients."""
        return len(self._terms)

    def is_angle(self) -> NDArray[np.bool_]:
        """Mask ``(n,)``: angle-valued coefficients (harmonics; compliance of revolute
        joints, an angle per unit load)."""
        return np.array([t.family == "harmonic" or
                         (t.family == "compliance" and self.kinds[t.joint] != PRISMATIC)
                         for t in self._terms], dtype=bool)

    # ------------------------------------------------------------------ gravity
    def _forces(self, q: Array, derivatives: bool) -> tuple[Array, Array | None]:
        """Compliance basis ``(N, n_compliance)`` (one column per compliance coefficient, in
        order) and its q-derivative ``(N, n_compliance, n_joints)``."""
        if not self._pairs:
            k = sum(t.family == "compliance" for t in self._terms)
            return np.zeros((q.shape[0], k)), (np.zeros((q.shape[0], k, self.n_joints))
                                               if derivatives else None)
        fr = chain_frames(self._motions, self._owners, self._motion_index, self.n_joints,
                          self._ref_vector, q)
        points = []
        for link, kind, com, mass in self._loads:
            if kind == "tool" or com is None:
                pos = fr.tool
            else:
                axes, origin = fr.flange if kind == "payload" else fr.links[link]
                pos = origin + com[0] * axes[0] + com[1] * axes[1] + com[2] * axes[2]
            points.append(LoadPoint(link, pos, mass))
        g = np.asarray(self.spec.gravity)
        raw_pairs = [(j, points[m]) for j, m in self._pairs]
        tau, dtau = gravity_forces(fr, self.kinds, g, raw_pairs, derivatives)
        # torques per lever (revolute joints): compliance coefficients are then angles
        per = np.array([1.0 if self.kinds[j] == PRISMATIC else 1.0 / self.lever
                        for j, _ in self._pairs])
        tau = tau * per
        dtau = None if dtau is None else dtau * per[:, None]
        if self.spec.masses is None:
            return tau, dtau
        # mass model: one column per joint, the sum over the masses that load it
        T = np.stack([tau[:, a:b].sum(axis=1) for a, b in self._groups], axis=1)
        D = None
        if dtau is not None:
            D = np.stack([dtau[:, a:b].sum(axis=1) for a, b in self._groups], axis=1)
        return T, D

    # ------------------------------------------------------------------ basis
    def basis(self, q: Array) -> Array:
        """``d dq_j / d c_k`` ``(N, n)``: coefficient ``k`` acts on joint `joint_of` [k]."""
        q = np.asarray(q, dtype=float)
        key = None
        if q.size * max(self.n, 1) <= _CACHE_ELEMENTS:
            key = (q.shape, hashlib.blake2b(np.ascontiguousarray(q).tobytes(),
                                            digest_size=16).digest())
            hit = self._cache.get(key)
            if hit is not None:
                self._cache.move_to_end(key)
                return hit
        W = self.basis_within(q, self.spec.envelope)
        if key is not None:
            W.flags.writeable = False
            self._cache[key] = W
            if len(self._cache) > _CACHE_ENTRIES:
                self._cache.popitem(last=False)
        return W

    def basis_within(self, q: Array, envelope: JointEnvelope | None) -> Array:
        """`basis` with the terms held at the edges of another `envelope` (None: nowhere),
        as a fit on part of the poses would evaluate the others (cross-validation)."""
        return self._evaluate(Retraction(envelope, q), derivatives=False)[0]

    def basis_rows(self, q: Array, low: Array, high: Array) -> Array:
        """`basis_within` with an envelope per row, `low` and `high` ``(N, n_joints)``."""
        revolute = [k != PRISMATIC for k in self.kinds]
        return self._evaluate(Retraction.rows(q, low, high, revolute), derivatives=False)[0]

    def _evaluate(self, r: Retraction, derivatives: bool) -> tuple[Array, Array | None]:
        """Basis ``(N, n)`` at the retracted readings `r` and, with `derivatives`, its
        derivative with respect to the raw readings ``(N, n, n_joints)``."""
        N = r.q.shape[0]
        W = np.empty((N, self.n))
        dW = np.zeros((N, self.n, self.n_joints)) if derivatives else None
        tau, dtau = r.blended(self._forces, derivatives)
        anchor = self._anchor
        for k, t in enumerate(self._terms):
            j = t.joint
            if t.family == "compliance":
                W[:, k] = tau[:, t.pair]
                if derivatives:
                    dW[:, k] = dtau[:, t.pair]
                continue
            if t.family == "harmonic":
                h = abs(t.order)
                f, df = ((lambda x, h=h: np.sin(h * x), lambda x, h=h: h * np.cos(h * x))
                         if t.order > 0 else
                         (lambda x, h=h: np.cos(h * x), lambda x, h=h: -h * np.sin(h * x)))
                value, slope = r.one_joint(j, f, df, periodic=True)
            else:
                f = _identity
                value, slope = r.one_joint(j, f, np.ones_like, periodic=False)
            # with an envelope, a joint's own terms vanish at the middle of its range: the
            # joint offset (or what stands in for it) alone carries the constant
            W[:, k] = value if anchor is None else value - f(anchor[j:j + 1])[0]
            if derivatives:
                dW[:, k, j] = slope
        return W, dW

    def dq(self, q: Array, c: Array) -> Array:
        """Joint corrections ``(N, n_joints)``, or ``(P, N, n_joints)`` for ``c`` ``(P, n)``."""
        W = self.basis(q)
        c = np.asarray(c, dtype=float)
        out = np.zeros(c.shape[:-1] + (q.shape[0], self.n_joints))
        for j in range(self.n_joints):
            sel = np.flatnonzero(self.joint_of == j)
            if sel.size:
                out[..., j] = np.einsum("nk,...k->...n", W[:, sel], c[..., sel])
        return out

    def dq_dq(self, q: Array, c: Array) -> Array:
        """``d dq_j / d q_i`` ``(N, n_joints, n_joints)`` at one coefficient vector ``c``."""
        q = np.asarray(q, dtype=float)
        c = np.asarray(c, dtype=float)
        _, dW = self._evaluate(Retraction(self.spec.envelope, q), derivatives=True)
        D = np.zeros((q.shape[0], self.n_joints, self.n_joints))
        for j in range(self.n_joints):
            sel = np.flatnonzero(self.joint_of == j)
            if sel.size:
                D[:, j, :] = np.einsum("nki,k->ni", dW[:, sel], c[sel])
        return D

    def through_corrections(self, Jt: Array, q: Array, c: Array) -> Array:
        """Joint Jacobian ``(n_joints, rows, N)`` of the corrected chain with respect to the
        raw readings: ``J(q + dq) (I + d dq / dq)``, from the chain's Jacobian `Jt` at the
        corrected readings (joint-major)."""
        D = self.dq_dq(q, c)
        idx = np.arange(self.n_joints)
        D[:, idx, idx] += 1.0
        return np.einsum("jrn,nji->irn", Jt, D)

    def chain_rule_t(self, Jq_t: Array, q: Array, columns: Sequence[int]) -> Array:
        """Rows ``(len(columns), rows, N)`` of the identification Jacobian of coefficients.

        Parameters
        ----------
        Jq_t : ndarray, shape (n_joints, rows, N)
            Joint Jacobian of the chain at the corrected readings (joint-major).
        q : ndarray, shape (N, n_joints)
            Raw joint readings.
        columns : sequence of int
            Coefficient indices (0-based within the joint-error terms).
        """
        W = self.basis(q)
        cols = np.asarray(columns, dtype=np.intp)
        return Jq_t[self.joint_of[cols]] * W[:, cols].T[:, None, :]

    def effect_scale(self, q: Array, length: float) -> Array:
        """Column factors ``(n,)`` that make coefficients comparable with geometry.

        A coefficient ``c_k`` turns joint ``j`` by ``c_k w_k(q)``: ``1 / (L rms(w_k))``
        (revolute joints; ``L`` the workspace's characteristic length) or ``1 / rms(w_k)``
        (prismatic joints) is the value that moves the tool by about one length unit, the
        unit of the geometric length parameters (`kinecal.calibration.serial.problem.column_scale`).
        """
        rms = np.sqrt(np.mean(np.square(self.basis(q)), axis=0)) if len(q) else np.ones(self.n)
        # a basis that is zero but for round-off (a mass on its joint's axis) must stay
        # negligible: no rms below 1e-6 of its family's largest
        fam = np.array(self.families)
        for f in set(self.families):
            top = rms[fam == f].max()
            rms[fam == f] = np.maximum(rms[fam == f], 1e-6 * top if top > 0 else 1.0)
        revolute = np.array([self.kinds[j] != PRISMATIC for j in self.joint_of], dtype=bool)
        return np.where(revolute, 1.0 / length, 1.0) / rms
