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
of the true problem, and names the motions in words (`kinecal.calibration.blocks.motions`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.motions import blind_basis, configurations, fixture_visibility
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.identifiability import IdentifiabilityReport, analyse_factor
from kinecal.calibration.serial.problem import column_scale
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.optimize.factor import gram_root, qr_update

__all__ = ["StackAnalysis", "analyse_stack", "report_for", "stack_scale"]

Array = NDArray[np.float64]

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
    report : IdentifiabilityReport or None
        The arm's candidate parameters, nuisance marginalised, blind motions removed (None
        for the factors only).
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

    report: IdentifiabilityReport | None
    unseen: list[str]
    factor: Array
    reduced: Array
    scale: Array
    length: float
    n_rows: int = 0
    shown_by_fixtures: list[str] = field(default_factory=list)


def stack_scale(problem: StackedProblem, params: Array, names=None) -> tuple[Array, float,
                                                                          Array, Array]:
    """Arm column scale ``(k,)``, characteristic length, configurations and tool points.

    As `kinecal.calibration.serial.problem.column_scale` over every tool point the blocks
    measure.
    """
    q, marker = configurations(problem)
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


def analyse_stack(problem: StackedProblem, x: Array, tol: float, check: bool = False,
                  keep: list[Array] | None = None, configs: Array | None = None,
                  rows: list | None = None, scaled: tuple | None = None,
                  report: bool = True) -> StackAnalysis:
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
    scaled : tuple, optional
        `stack_scale` of `problem` at `x`, when several analyses of one point share it.
    report : bool
        Analyse the factor (the pivoted QR, singular values and confounding of the
        report); False: the factors only (``report`` None, no fixtures' visibility).
    """
    params = problem.params(x)
    D, L, q, P = stack_scale(problem, params) if scaled is None else scaled
    Raa = _arm_factor(problem, x, D, L, check, keep, rows, tol)
    nn = problem.n - problem.k
    used = None if keep is None else [bool(k.any()) for k in keep]
    Q, unseen = blind_basis(problem, params, q, P, D, used=used, configs=configs)
    B = Raa - (Raa @ Q) @ Q.T if Q.size else Raa
    m = problem.m_used if keep is None else int(sum(int(k.sum()) for k in keep))
    n_rows = max(m - nn, 1)
    if not report:  # the factors only (a growth step, an analysis per chain)
        return StackAnalysis(None, unseen, Raa / D, B, D, L, n_rows)
    found = analyse_factor(B / D, problem.free, n_rows, tol=tol, scale=D)
    return StackAnalysis(found, unseen, Raa / D, B, D, L, n_rows,
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


