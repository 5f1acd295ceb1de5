"""Identifiability of a robot system: what each chain's data see, and what only the
combination of chains does.

The stacked problem of a system (`kinecal.kinematics.tree.SystemModel`) is analysed once
with every row (`analysis.analyse_stack`: what the calibration identifies) and once per
tip with the rows that chain's data make alone (`tips.row_tips`: its own tracker points,
touches and distances; a bar between two hands, a point touched by two tips or a probe on
one chain touching a workpiece on another need both). A parameter identifiable with
every row but with no single chain's rows is seen by the **combination** only: e.g. a
positioner's axes seen by an arm's probe touching the workpiece it carries, or an arm's
base that only a point touched by both hands ties to the other arm.

Parameters two chains reach are **shared** (the torso's joints, the base frame, a rail
under an arm); for each the tips whose data alone identify it are listed. Confounded
parameters whose chains differ (a shared torso offset confounded with one arm's base) are
reported across chains.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal.calibration.blocks.analysis import StackAnalysis, analyse_stack, stack_scale
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.tips import row_tips

__all__ = ["NULL_SHARE", "system_identifiability", "system_lines"]

#: a parameter counts as determined by a chain's rows when the null directions of those
#: rows move it by less than this share (unit-norm directions in scaled columns)
NULL_SHARE = 1e-3
#: a held parameter is confounded with free ones when they reproduce its effect (scaled,
#: blind motions removed) to this fraction
EXPLAINED = 1e-3


def _config_tips(problem: StackedProblem) -> np.ndarray:
    parts = []
    for b in problem.blocks:
        q, m = b.configurations()
        parts.append(np.zeros(len(q), dtype=np.intp) if m is None else np.asarray(m))
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.intp)


def _estimable(reduced: np.ndarray, names: list[str], wanted: list[str], tol: float
               ) -> list[str]:
    """The `wanted` parameters the (scaled, reduced) information `reduced` ``(k, k)`` of
    `names` determines with every `wanted` one free: those no null direction of its
    `wanted` columns moves (independent of which member of a confounded pair a pivoting
    would keep)."""
    pos = [names.index(n) for n in wanted]
    if not pos:
        return []
    B = reduced[:, pos]
    _, s, Vt = np.linalg.svd(B, full_matrices=True)
    s = np.r_[s, np.zeros(len(pos) - s.size)]
    null = Vt[s <= tol * max(float(s.max(initial=0.0)), 1e-300)]
    moved = np.linalg.norm(null, axis=0) if null.size else np.zeros(len(pos))
    return [n for n, m in zip(wanted, moved, strict=True) if m < NULL_SHARE]


def _across(analysis: StackAnalysis, names: list[str], free: list[str], reach: dict
            ) -> dict[str, dict[str, float]]:
    """Held parameters whose effect the free ones of other chains reproduce (least squares
    on the reduced information leaving less than `EXPLAINED` of it): ``{held: {free: c}}``
    (parameter units), the partners on a different set of chains only."""
    B, D = analysis.reduced, analysis.scale
    kept = [names.index(n) for n in free]
    out: dict[str, dict[str, float]] = {}
    if not kept:
        return out
    held = [j for j, n in enumerate(names) if n not in free
            and float(np.linalg.norm(B[:, j])) > 0.0]
    if not held:
        return out
    coef, *_ = np.linalg.lstsq(B[:, kept], B[:, held], rcond=None)  # one factorisation
    for c, j in zip(coef.T, held, strict=True):
        n, col = names[j], B[:, j]
        if np.linalg.norm(B[:, kept] @ c - col) > EXPLAINED * float(np.linalg.norm(col)):
            continue  # weak rather than confounded: no partners to name
        c = c * D[kept] / D[j]
        big = np.abs(c) > 1e-6 * max(float(np.abs(c).max()), 1e-300)
        other = {free[i]: float(c[i]) for i in np.flatnonzero(big)
                 if reach[free[i]] != reach[n]}
        if other:
            out[n] = other
    return out


def system_identifiability(problem: StackedProblem, x: np.ndarray, tol: float,
                           analysis: StackAnalysis) -> dict[str, Any]:
    """The system's identifiability section of a result (module docstring).

    Parameters
    ----------
    problem : StackedProblem
        The stacked problem with the candidate parameters free, at the solution.
    x : ndarray
    tol : float
        Rank threshold.
    analysis : StackAnalysis
        The analysis with every row (the calibration's, its ``report`` for the free set
        fitted); its identifiable parameters are the free set each chain's rows are judged
        on.

    Returns
    -------
    dict
        ``tips``: per tip ``{rows, parameters, identifiable}`` (residual rows its data make
        alone, its chain's parameter count, the free parameters those rows determine);
        ``shared``: the shared parameters; ``shared_seen_by``: per shared free parameter
        the tips that determine it alone; ``combination_only``: free parameters no chain's
        rows determine alone; ``confounded_across_chains``: held parameters confounded
        with free ones of other chains.
    """
    model = problem.model
    report = analysis.report
    names = list(report.names)
    free = list(report.identifiable)
    chain = {t: set(model.chain_parameters(t)) for t in model.tips}
    reach = {n: frozenset(t for t in model.tips if n in chain[t]) for n in names}
    cfg = _config_tips(problem)
    tips: dict[str, Any] = {}
    alone: set[str] = set()
    # the rows of the blocks with unknowns once for every tip (the others: `arm_normal`)
    weighted = list(problem._weighted_rows(x, only=[b.n_nuisance > 0 for b in problem.blocks]))
    scaled = stack_scale(problem, problem.params(x))  # one scale for every tip's analysis
    for t, tip in enumerate(model.tips):
        keep = [row_tips(b, model, t) for b in problem.blocks]
        rows = int(sum(int(k.sum()) for k in keep))
        ident: list[str] = []
        if rows:
            ana = analyse_stack(problem, x, tol, keep=keep, configs=cfg == t, rows=weighted,
                                scaled=scaled, report=False)
            ident = [n for n in _estimable(ana.reduced, names, free, tol) if tip in reach[n]]
        alone |= set(ident)
        tips[tip] = {"rows": rows, "parameters": len(model.chain_parameters(tip)),
                     "identifiable": ident}
    shared = set(model.shared_parameters())
    across = _across(analysis, names, free, reach)
    return {
        "tips": tips,
        "shared": [n for n in model.parameter_names if n in shared],
        "shared_seen_by": {n: [t for t in model.tips if n in tips[t]["identifiable"]]
                           for n in free if n in shared},
        "combination_only": [n for n in free if n not in alone],
        "confounded_across_chains": across,
    }


def system_lines(section: dict[str, Any]) -> list[str]:
    """The system section in words (summaries, the identifiability command)."""
    lines = ["", "system: what each chain's data identify alone"]
    for tip, entry in section["tips"].items():
        lines.append(f"  {tip}: {entry['rows']} residual rows, {len(entry['identifiable'])} "
                     f"of its chain's {entry['parameters']} parameters identified alone")
    seen = section["shared_seen_by"]
    if seen:
        by = [f"{n} ({', '.join(t) or 'no chain alone'})" for n, t in list(seen.items())[:8]]
        lines.append("  shared parameters, and the chains that see them alone: "
                     + "; ".join(by) + (" ..." if len(seen) > 8 else ""))
    only = section["combination_only"]
    if only:
        lines.append("  identified only by the combination of chains: " + ", ".join(only[:12])
                     + (" ..." if len(only) > 12 else ""))
    across = section["confounded_across_chains"]
    if across:
        shown = [f"{n} ~ {', '.join(p)}" for n, p in list(across.items())[:6]]
        lines.append("  confounded across chains: " + "; ".join(shown)
                     + (" ..." if len(across) > 6 else ""))
    return lines
