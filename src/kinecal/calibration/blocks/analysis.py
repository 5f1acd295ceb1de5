"""Identifiability of a stacked problem: the arm's parameters with every block's unknowns
free, and the motions of the whole arm that the mix of measurement kinds cannot see.

The nuisance columns are marginalised exactly: the stacked, weighted Jacobian with the
nuisance columns first, ``[J_n | J_a]``, is folded block by block into the trailing
``(k, k)`` block ``R_aa`` of its R factor (`kinecal.optimize.factor.qr_update`; each
block's own unknowns eliminated from its own rows), which satisfies
``R_aa^T R_aa = J_a^T (I - P_n) J_a``, the arm's information once every pivot, point and
plane has taken what it can. `kinecal.calibration.identifiability`'s pivoted QR then runs
on ``R_aa``.

Motions no kind of the mix sees. A ballbar's distances do not change when the whole arm
moves rigidly with its pivots; fixed points and planes neither when the arm moves rigidly
or grows uniformly with them. Each block says which of these *similarity motions* of the
measurement frame it is blind to (``blind_to``: translation, rotation, scale); the mix is
blind to those every block is blind to. Such a motion is an exact null direction only at
consistent data (at the nominal geometry a point's touches disagree by the arm's errors,
and the motion shows faintly, ~ error / size); the analysis therefore removes from
``R_aa`` the arm directions that produce the blind motions on the tool points (least
squares on the tool-point Jacobian), so that the rank and the parameters held are those
of the true problem, and names the motions in words.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import MOTION_WORDS
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.identifiability import IdentifiabilityReport, analyse_factor
from kinecal.calibration.serial.problem import column_scale
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.optimize.factor import gram_root, qr_update

__all__ = ["MOTIONS", "StackAnalysis", "analyse_stack", "blind_basis", "blind_motions",
           "fixture_visibility", "fixture_words", "motion_names", "report_for", "stack_scale",
           "unseen_words"]

Array = NDArray[np.float64]

#: the similarity motions of the measurement frame, by the blind-to words of the blocks
MOTIONS = {"translation": ("translation x", "translation y", "translation z"),
           "rotation": ("rotation x", "rotation y", "rotation z"),
           "scale": ("scale",)}
#: a motion counts as produced by the arm's parameters when their least-squares fit
#: leaves less than this fraction of it on the tool points
PRODUCIBLE = 1e-6
#: a block's own unknowns count as undetermined below this relative singular value
NUISANCE_TOL = 1e-9
#: smallest rank threshold decided on a root of the Gram matrix of the blocks without
#: unknowns (it loses the directions below sqrt(eps) of the largest singular value; below,
#: their rows are folded exactly): the serial calibration's `GRAM_TOL`
GRAM_TOL = 1e-6


@dataclass
class StackAnalysis:
    """What `analyse_stack` found.

    Attributes
    ----------
    report : IdentifiabilityReport
        The arm's candidate parameters, nuisance marginalised, blind motions removed.
    unseen : list of str
        Motions of the whole arm the mix does not see (``translation x`` ... ``scale``)
        that the candidate parameters can make.
    factor : ndarray, shape (k, k)
        ``R_aa`` (parameter units) before the blind motions were removed.
    reduced : ndarray, shape (k, k)
        ``R_aa`` in scaled columns with the blind motions removed (what the rank is
        decided on).
    scale : ndarray, shape (k,)
        Column scale of the arm's candidates (1 for lengths, 1 / L for angles).
    length : float
        The workspace's characteristic length L.
    n_rows : int
        Residual rows left after the unknowns (and rows left out of the fit).
    shown_by_fixtures : list of str
        What the known fixtures make visible (``translation``, ``rotation``, ``scale`` of
        the whole arm) that the mix would not see were they unknown
        (`fixture_visibility`).
    """

    report: IdentifiabilityReport
    unseen: list[str]
    factor: Array
    reduced: Array
    scale: Array
    length: float
    n_rows: int = 0
    shown_by_fixtures: list[str] = field(default_factory=list)


def _configurations(problem: StackedProblem) -> tuple[Array, NDArray[np.intp] | None]:
    model = problem.model
    qs, ms = [], []
    for b in problem.blocks:
        q, m = b.configurations()
        qs.append(q)
        ms.append(np.zeros(len(q), dtype=np.intp) if m is None else m)
    q = np.concatenate(qs)
    return q, (np.concatenate(ms) if model.marker_names else None)


def stack_scale(problem: StackedProblem, params: Array, names=None) -> tuple[Array, float,
                                                                          Array, Array]:
    """Arm column scale ``(k,)``, characteristic length, configurations and tool points.

    As `kinecal.calibration.serial.problem.column_scale` over every tool point the blocks
    measure.
    """
    q, marker = _configurations(problem)
    P = problem.model.positions(q, params, marker)
    meas = Measurements(q, P, marker=marker,
                        marker_names=problem.model.marker_names if marker is not None else ())
    names = problem.free if names is None else names
    D = column_scale(problem.model, meas, names, params, positions=P)
    d = P - P.mean(axis=0)
    L = float(np.sqrt(np.einsum("ij,ij->", d, d) / max(len(d), 1))) or 1.0
    return D, L, q, P


def _arm_factor(problem: StackedProblem, x: Array, D: Array, L: float, check: bool,
                keep: list[Array] | None = None, rows: list | None = None,
                tol: float = GRAM_TOL) -> Array:
    """``R_aa`` ``(k, k)`` of the scaled, weighted ``[J_n | J_a]`` (module docstring); with
    `check`, refuses a block whose rows do not determine its own unknowns; `keep`: per
    block, the residual rows to use (the others left out); `rows`: the blocks' weighted
    rows at `x` when already evaluated (`StackedProblem._weighted_rows`; None for the
    blocks without unknowns); `tol`: the rank threshold the factor is for.

    Each block's nuisance columns are its own, so its unknowns are eliminated from its
    rows alone: the trailing ``(k, k)`` of the R factor of ``[J_nb | J_ab]`` carries
    ``J_ab^T (I - P_nb) J_ab``, and those of all blocks fold into ``R_aa`` (the factor of
    the whole stack would cost the cube of every unknown per block: 84 s for 100 files of
    fixed points). The blocks without unknowns that accumulate their normal equations
    (`ResidualBlock.arm_normal`: tracker rows, chunk by chunk and chain by chain) enter
    through a root of their summed Gram matrix (`kinecal.optimize.factor.gram_root`)
    when `tol` is at least `GRAM_TOL`, as the serial calibration's analysis does.
    """
    k = problem.k
    p = problem.params(x)
    G = np.zeros((k, k))
    folded = [False] * len(problem.blocks)
    if tol >= GRAM_TOL:
        for i, (b, w) in enumerate(zip(problem.blocks, problem.row_weight, strict=True)):
            got = (b.arm_normal(problem.model, p, problem.index,
                                w if keep is None else w * keep[i], problem.groups[i])
                   if b.n_nuisance == 0 else None)
            if got is not None:
                G += got[1]
                folded[i] = True
    R = qr_update(None, gram_root(G * D[:, None] * D[None, :])) if any(folded) else None
    if all(folded):
        return np.zeros((k, k)) if R is None else R
    if rows is None or any(r is None for r, f in zip(rows, folded, strict=True) if not f):
        rows = problem._weighted_rows(x, only=[not f for f in folded])
    for i, (b, part) in enumerate(zip(problem.blocks, rows, strict=True)):
        if folded[i]:
            continue
        _, Ja, Jn, _s = part
        if keep is not None:
            Ja, Jn = Ja[keep[i]], Jn[keep[i]]
        if b.n_nuisance and check:
            Js = Jn * b.nuisance_scale(L)
            sv = np.linalg.svd(Js, compute_uv=False)
            if sv.size < b.n_nuisance or sv[-1] <= NUISANCE_TOL * max(sv[0], 1e-300):
                raise InputError(f"{b.name}: its rows do not determine its own unknowns "
                                 f"({', '.join(b.nuisance_names[:6])}...): too few or too "
                                 "similar rows per group")
        nb = Jn.shape[1]
        both = np.zeros((Ja.shape[0], nb + k), order="F")
        both[:, :nb] = Jn * b.nuisance_scale(L)
        both[:, nb:] = Ja * D
        own = qr_update(None, both)[nb:, nb:] if nb else both[:, nb:]
        R = qr_update(R, own)
    return np.zeros((k, k)) if R is None else R


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
    _, marker = _configurations(problem)
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


def analyse_stack(problem: StackedProblem, x: Array, tol: float, check: bool = False,
                  keep: list[Array] | None = None, configs: Array | None = None,
                  rows: list | None = None) -> StackAnalysis:
    """Identifiability of `problem`'s arm parameters at `x` (module docstring).

    Parameters
    ----------
    problem : StackedProblem
        With the candidate parameters free.
    x : ndarray, shape (n,)
    tol : float
        Relative rank threshold (`kinecal.calibration.identifiability.analyse_factor`).
    check : bool
        Refuse (`InputError`) a block whose rows do not determine its own unknowns (the
        data's fault at the start values; at a solution, the fit's).
    keep : list of ndarray of bool, optional
        Per block, the residual rows to analyse (e.g. one chain's of a robot system); the
        blocks without any count neither for the blind motions.
    configs : ndarray of bool, optional
        With `keep`: the configurations (of the blocks in order) those rows measure.
    rows : list, optional
        The blocks' weighted rows at `x` (`StackedProblem._weighted_rows`), when several
        analyses of one point share them.
    """
    params = problem.params(x)
    D, L, q, P = stack_scale(problem, params)
    Raa = _arm_factor(problem, x, D, L, check, keep, rows, tol)
    nn = problem.n - problem.k
    used = None if keep is None else [bool(k.any()) for k in keep]
    Q, unseen = blind_basis(problem, params, q, P, D, used=used, configs=configs)
    B = Raa - (Raa @ Q) @ Q.T if Q.size else Raa
    m = problem.m_used if keep is None else int(sum(int(k.sum()) for k in keep))
    n_rows = max(m - nn, 1)
    report = analyse_factor(B / D, problem.free, n_rows, tol=tol, scale=D)
    return StackAnalysis(report, unseen, Raa / D, B, D, L, n_rows,
                         fixture_visibility(problem, params, q, P, D))


def report_for(analysis: StackAnalysis, free: list[str], tol: float) -> IdentifiabilityReport:
    """The report of a fit on `free` from the analysis of all candidates.

    Rank, condition number and observability are those of the free set; the held
    candidates are unidentifiable, each with the free parameters whose combination has its
    effect (the pivoting of the candidates may have kept another member of a confounded
    pair than the fit did: d2 for d3 of near-parallel axes).
    """
    names = analysis.report.names
    pos = [names.index(n) for n in free]
    D, B = analysis.scale, analysis.reduced
    sub = analyse_factor(B[:, pos] / D[pos], free, analysis.n_rows, tol=tol, scale=D[pos])
    kept = [names.index(n) for n in sub.identifiable]
    held = [j for j, n in enumerate(names) if n not in sub.identifiable]
    confounded = dict(sub.confounded_with)
    if kept and held:
        coef = np.linalg.lstsq(B[:, kept], B[:, held], rcond=None)[0]
        coef = coef * D[kept][:, None] / D[held][None, :]
        whole = np.linalg.norm(B, 2)
        for j, col in enumerate(held):
            if names[col] in confounded:
                continue
            c = coef[:, j]
            big = np.abs(c) > 1e-6 * max(np.abs(c).max(), 1e-300)
            norm = np.linalg.norm(B[:, col])
            confounded[names[col]] = ({} if norm <= tol * whole else
                                      {names[kept[i]]: float(c[i]) for i in np.flatnonzero(big)})
    return IdentifiabilityReport(
        names=list(names), rank=sub.rank, identifiable=list(sub.identifiable),
        unidentifiable=[n for n in names if n not in sub.identifiable],
        confounded_with={n: confounded.get(n, {}) for n in names if n not in sub.identifiable},
        condition_number=sub.condition_number,
        singular_values=analysis.report.singular_values, observability=sub.observability)


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
