"""The motions of the whole arm a mix of measurement kinds cannot see, found and named.

A ballbar's distances do not change when the whole arm moves rigidly with its pivots;
fixed points and planes neither when the arm moves rigidly or grows uniformly with them.
Each block says which of these *similarity motions* of the measurement frame it is blind
to (``blind_to``: translation, rotation, scale, or as linear conditions
``blind_constraints``); the mix is blind to those every block is blind to
(`blind_motions`). `blind_basis` gives the arm directions that produce them on the tool
points (removed from the factor by `kinecal.calibration.blocks.analysis`, and from the
covariance by `kinecal.calibration.blocks.uncertainty`); `motion_names`, `unseen_words`
and `fixture_words` say them in words.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import MOTION_WORDS
from kinecal.calibration.blocks.stack import StackedProblem

__all__ = ["MOTIONS", "PRODUCIBLE", "blind_basis", "blind_motions", "configurations",
           "fixture_visibility", "fixture_words", "motion_names", "unseen_words"]

Array = NDArray[np.float64]

#: the similarity motions of the measurement frame, by the blind-to words of the blocks
MOTIONS = {"translation": ("translation x", "translation y", "translation z"),
           "rotation": ("rotation x", "rotation y", "rotation z"),
           "scale": ("scale",)}
#: a motion counts as produced by the arm's parameters when their least-squares fit
#: leaves less than this fraction of it on the tool points
PRODUCIBLE = 1e-6

def configurations(problem: StackedProblem) -> tuple[Array, NDArray[np.intp] | None]:
    """Joint readings ``(N, n_joints)`` and markers ``(N,)`` (None without markers) of
    every tool point the blocks measure, in block order."""
    model = problem.model
    qs, ms = [], []
    for b in problem.blocks:
        q, m = b.configurations()
        qs.append(q)
        ms.append(np.zeros(len(q), dtype=np.intp) if m is None else m)
    q = np.concatenate(qs)
    return q, (np.concatenate(ms) if model.marker_names else None)


def blind_motions(blocks, known: bool = True) -> Array:
    """Orthonormal basis ``(7, b)`` of the motions ``(t, w, s)`` every block is blind to
    (the null space of their stacked `ResidualBlock.blind_constraints`); with
    ``known=False``, as if every known fixture were unknown (the blocks' `blind_to`)."""
    rows = [b.blind_constraints() if known else
            np.eye(7)[[i for i, w in enumerate(MOTION_WORDS) if w not in b.blind_to]]
            for b in blocks]
    C = np.concatenate(rows) if rows else np.zeros((0, 7))
    if C.shape[0] == 0:
        return np.eye(7)
    _, s, Vt = np.linalg.svd(C)
    rank = int((s > 1e-9 * max(float(s.max(initial=0.0)), 1e-300)).sum())
    return Vt[rank:].T


def _fields(P: Array) -> Array:
    """The seven unit motions on the tool points ``P (N, 3)``: ``(3N, 7)``."""
    F = np.zeros((P.size, 7))
    for a in range(3):
        t = np.zeros_like(P)
        t[:, a] = 1.0
        F[:, a] = t.ravel()
        F[:, 3 + a] = np.cross(np.eye(3)[a], P).ravel()
    F[:, 6] = P.ravel()
    return F


def _producible(problem: StackedProblem, params: Array, q: Array, P: Array, D: Array,
                known: bool, used: list[bool] | None = None, configs: Array | None = None
                ) -> tuple[Array, Array]:
    """The blind motions the candidate parameters can make on the tool points: the arm
    directions ``(k, p)`` (unscaled least-squares solutions) and the motions ``(7, p)``;
    `used`: the blocks that count (default all), `configs`: the configurations that count
    (a mask, default all)."""
    blocks = [b for i, b in enumerate(problem.blocks) if used is None or used[i]]
    M = blind_motions(blocks, known)
    if M.shape[1] == 0 or problem.k == 0:
        return np.zeros((problem.k, 0)), np.zeros((7, 0))
    _, marker = configurations(problem)
    if configs is not None:
        q, P = q[configs], P[configs]
        marker = None if marker is None else marker[configs]
    J = problem.model.identification_jacobian(q, params, marker=marker)[:, :, problem.index]
    J = J.reshape(-1, problem.k)
    W = _fields(P) @ M  # the blind motions' fields
    _, sw, Vwt = np.linalg.svd(W, full_matrices=False)
    keep = sw > 1e-12 * max(float(sw.max(initial=0.0)), 1e-300)
    C = Vwt[keep].T / sw[keep]  # motion combinations with orthonormal fields
    v, *_ = np.linalg.lstsq(J, W @ C, rcond=None)
    A = J @ v - W @ C  # (3N, p): only its right singular vectors are needed (a full U of
    # 3N x 3N rows was 13 GB for 13406 tracker rows)
    _, sl, Vlt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])
    sl = np.r_[sl, np.zeros(Vlt.shape[0] - sl.size)]
    made = Vlt[sl <= PRODUCIBLE].T  # combinations the parameters produce
    return v @ made, M @ C @ made


def blind_basis(problem: StackedProblem, params: Array, q: Array, P: Array, D: Array,
                known: bool = True, used: list[bool] | None = None,
                configs: Array | None = None) -> tuple[Array, list[str]]:
    """Orthonormal arm directions ``(k, b)`` (columns scaled by `D`) producing the mix's
    blind motions on the tool points `P` ``(N, 3)`` of the configurations `q`, and the
    motions' names (`stack_scale` gives `D`, `q` and `P`; `known`: as `blind_motions`;
    `used`, `configs`: the blocks and configurations that count, as `_producible`).

    The blind motions are those every block is blind to (`blind_motions`); of them, the
    ones the candidate parameters can make on the tool points (least squares on the
    tool-point Jacobian leaves less than `PRODUCIBLE` of the motion's field) are named
    (`motion_names`) and returned.
    """
    v, motions = _producible(problem, params, q, P, D, known, used, configs)
    if v.shape[1] == 0:
        return np.zeros((problem.k, 0)), []
    U, s, _ = np.linalg.svd(v / D[:, None], full_matrices=False)
    rank = int((s > 1e-9 * max(s.max(), 1e-300)).sum())
    return U[:, :rank], motion_names(motions)


def fixture_visibility(problem: StackedProblem, params: Array, q: Array, P: Array,
                       D: Array) -> list[str]:
    """What the blocks' known fixtures make visible, of ``translation``, ``rotation`` and
    ``scale`` of the whole arm: those the mix would not see were the fixtures unknown and
    sees with them. A translation is unseen when some blind motion is a pure translation,
    a rotation or the scale when some blind motion has a rotation or scale component."""
    if not any(getattr(b, "known", None) is not None and b.known_mask.any()
               for b in problem.blocks):
        return []
    unseen = [_unseen_kinds(_producible(problem, params, q, P, D, k)[1]) for k in (False, True)]
    return [w for w in ("translation", "rotation", "scale")
            if w in unseen[0] and w not in unseen[1]]


def _unseen_kinds(motions: Array) -> set[str]:
    """Which of translation, rotation, scale the blind motions ``(7, p)`` hold."""
    if motions.shape[1] == 0:
        return set()
    Q, _ = np.linalg.qr(motions)

    def rank(A: Array) -> int:
        s = np.linalg.svd(A, compute_uv=False)
        return int((s > 1e-9).sum())

    out = set()
    if Q.shape[1] - rank(Q[3:]) > 0:  # a motion with no rotation nor scale part
        out.add("translation")
    if rank(Q[3:6]) > 0:
        out.add("rotation")
    if rank(Q[6:]) > 0:
        out.add("scale")
    return out


def motion_names(M: Array) -> list[str]:
    """Names of the motions spanned by the columns of ``M (7, b)`` (`MOTION_WORDS`
    coordinates): ``translation x`` ... ``rotation z``, ``scale`` when they are spanned by
    those unit motions, else each basis motion in words (``scale about (500, 300, 200)``,
    ``rotation about (0, 0, 1) through (100, 0, 0)``)."""
    if M.shape[1] == 0:
        return []
    Q, _ = np.linalg.qr(M)
    inside = [i for i in range(7) if np.linalg.norm(Q.T[:, i]) > 1.0 - 1e-9]
    if len(inside) == M.shape[1]:
        return [name for i, name in enumerate(_UNIT_NAMES) if i in inside]
    # a canonical basis: scale first, then rotations, then translations as pivots
    order = [6, 3, 4, 5, 0, 1, 2]
    B = _rref(M.T[:, order])[:, np.argsort(order)]
    return [_motion_words(b) for b in B]


_UNIT_NAMES = tuple(n for w in ("translation", "rotation", "scale") for n in MOTIONS[w])


def _rref(A: Array, tol: float = 1e-9) -> Array:
    """Reduced row echelon form of the rows of `A` (a basis of their span)."""
    A = np.array(A, dtype=float)
    r = 0
    for c in range(A.shape[1]):
        if r == A.shape[0]:
            break
        p = r + int(np.argmax(np.abs(A[r:, c])))
        if abs(A[p, c]) <= tol:
            continue
        A[[r, p]] = A[[p, r]]
        A[r] /= A[r, c]
        others = np.arange(A.shape[0]) != r
        A[others] -= np.outer(A[others, c], A[r])
        r += 1
    return A[:r]


def _vector(v: Array) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in np.where(np.abs(v) < 1e-9, 0.0, v)) + ")"


def _motion_words(m: Array) -> str:
    """One motion ``(t, w, s)`` in words: a scale, rotation or translation about a point."""
    t, w, s = m[:3], m[3:6], float(m[6])
    if abs(s) > 1e-12 and np.linalg.norm(w) <= 1e-12:
        return f"scale about {_vector(-t / s)}"
    if np.linalg.norm(w) > 1e-12 and abs(s) <= 1e-12:
        u = w / np.linalg.norm(w)
        c = np.cross(w, t) / float(w @ w)  # the axis point nearest the origin
        axis = next((f"rotation {a}" for a, e in zip("xyz", np.eye(3), strict=True)
                     if abs(abs(u @ e) - 1.0) < 1e-12), f"rotation about {_vector(u)}")
        pitch = float(w @ t) / float(w @ w)
        return (axis + (f" through {_vector(c)}" if np.linalg.norm(c) > 1e-9 else "")
                + (f" with a translation of {pitch:.4g} per rad" if abs(pitch) > 1e-9
                   else ""))
    if np.linalg.norm(w) <= 1e-12 and abs(s) <= 1e-12:
        u = t / np.linalg.norm(t)
        return next((f"translation {a}" for a, e in zip("xyz", np.eye(3), strict=True)
                     if abs(abs(u @ e) - 1.0) < 1e-12), f"translation along {_vector(u)}")
    return f"the motion t = {_vector(t)}, w = {_vector(w)}, s = {s:.4g}"


def unseen_words(unseen: list[str]) -> str:
    """The blind motions in words: ``the base frame (translation and rotation), scale``."""
    parts = []
    t = [u for u in unseen if u.startswith("translation")]
    r = [u for u in unseen if u.startswith("rotation")]
    if len(t) == 3 and len(r) == 3 and all(" " not in u[len("rotation "):] for u in r):
        parts.append("the base frame (where the arm stands: translation and rotation of the "
                     "whole arm)")
    else:
        parts += t + r
    if "scale" in unseen:
        parts.append("scale (every length of the arm in proportion)")
    parts += [u + " (every length of the arm in proportion about that point)"
              for u in unseen if u.startswith("scale about")]
    parts += [u for u in unseen if u.startswith("the motion")]
    return ", ".join(parts)


def fixture_words(shown: list[str]) -> str:
    """What known fixtures make visible, in words (`StackAnalysis.shown_by_fixtures`)."""
    parts = []
    if "translation" in shown and "rotation" in shown:
        parts.append("the base frame (where the arm stands: translation and rotation)")
    else:
        parts += [f"the {w} of the base frame" for w in ("translation", "rotation")
                  if w in shown]
    if "scale" in shown:
        parts.append("the scale")
    return " and ".join(parts)
