"""Plan a mix of measurement kinds before measuring: what rows of several kinds identify,
and which rows of a kind to measure (`select_kind_poses`, ``kinecal select-poses --kind``).

``kinecal identifiability MODEL --data A.csv --data B.csv`` runs `analyse_kinds` on
measured or simulated files (``kinecal simulate MODEL --kind ballbar --errors zero ...``):
the rank on the stack with every pivot, point and plane free, the parameters each kind's
blindness leaves unidentified, and those motions in words.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kinecal.calibration.blocks.analysis import StackAnalysis, analyse_stack
from kinecal.calibration.blocks.api import RANK_TOL as CAL_RANK_TOL
from kinecal.calibration.blocks.checks import check_block_data
from kinecal.calibration.blocks.decide import solve_blocks
from kinecal.calibration.blocks.make import DataSet, make_blocks, marker_names
from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.system_ident import system_identifiability
from kinecal.calibration.serial.pose_selection import d_optimal
from kinecal.calibration.serial.problem import candidate_names
from kinecal.data import GaugeMeasurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import model_for_markers
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["analyse_kinds", "analyse_system", "select_kind_poses", "select_system_poses"]


def analyse_kinds(model: SerialModel, data: Sequence[DataSet], free: str | Sequence[str] = "all",
                  *, sigma: Sequence[float | None] | None = None, tol: float = CAL_RANK_TOL
                  ) -> tuple[StackAnalysis, list[dict[str, Any]]]:
    """What `calibrate_blocks` frees of `free` (``all``, ``identifiable`` or names) from
    data sets of any kinds: its own rule (`kinecal.calibration.blocks.decide`), the
    candidates' rank at nominal at `tol`, each set's unknowns fitted to it, outliers left
    out, the parameters that became identifiable at the solution freed when they pay.

    Returns
    -------
    StackAnalysis
        ``report`` (the `kinecal identifiability` JSON: the free set identifiable, the
        other candidates not) and ``unseen`` (motions of the whole arm the mix does not
        see).
    list of dict
        Per set: ``file``, ``kind``, ``observations``, ``rows``, ``unknowns`` (its own),
        ``known`` (its known fixtures: points or planes).
    """
    sol, blocks = _solve(model, data, free, sigma, tol)
    return sol.analysis, _kinds(blocks)


def _solve(model, data: Sequence[DataSet], free, sigma, tol: float):
    """`solve_blocks` of the data sets with the data checks; and their blocks."""
    model = model_for_markers(model, marker_names(list(data)))
    blocks = make_blocks(model, list(data), sigma)
    names = candidate_names(model, "all" if free == "identifiable" else free)

    def check(nuis, before, ana0, chosen) -> None:
        check_block_data(model, blocks, nuis, before, names)

    return solve_blocks(model, blocks, names, True, rank_tol=tol, check=check), blocks


def _kinds(blocks) -> list[dict[str, Any]]:
    return [{"file": b.source, "kind": b.kind, "observations": int(b.n_obs),
             "rows": int(b.n_rows), "unknowns": int(b.n_nuisance),
             "known": int(np.sum(getattr(b, "known_mask", ())))} for b in blocks]


def analyse_system(model, data: Sequence[DataSet], free: str | Sequence[str] = "all", *,
                   sigma: Sequence[float | None] | None = None, tol: float = CAL_RANK_TOL
                   ) -> tuple[StackAnalysis, list[dict[str, Any]], dict[str, Any]]:
    """What `calibrate_blocks` frees from a robot system's data sets (`analyse_kinds`), and
    the system section (`kinecal.calibration.blocks.system_ident.system_identifiability`:
    what each chain's rows identify alone, what only the combination does); ``kinecal
    identifiability SYSTEM --data ...``."""
    sol, blocks = _solve(model, data, free, sigma, tol)
    prob = sol.fit.problem
    x = np.asarray(sol.fit.result.x, dtype=float)
    final = sol.final
    section = system_identifiability(final, final.pack(prob.params(x), prob.nuisance(x)), tol,
                                     sol.analysis)
    return sol.analysis, _kinds(blocks), section


def select_kind_poses(model: SerialModel, kind: str, count: int, *, candidates: int = 100,
                      rng: int | np.random.Generator | None = None, **geometry
                      ) -> tuple[GaugeMeasurements, dict[str, Any]]:
    """Rows of a gauge kind that identify the most (D-optimal on the stacked information).

    Candidates are `candidates` reachable rows per pivot, point or plane (pairs: bar
    placements) of the nominal arm (`simulate_kind`; `geometry`: its ``centres``, ``planes``,
    ``length``, ``radius``, ``groups``); `count` per group (pairs: in all) are chosen to
    maximise ``log det`` of the information of the arm's identifiable parameters *and* the
    gauges' own unknowns (`kinecal.calibration.serial.pose_selection.d_optimal`; unit-RMS
    columns), so that no gauge is left undetermined.

    Returns
    -------
    GaugeMeasurements
        The chosen rows (group by group), with the nominal arm's distances for the
        distance kinds: a plan, and a file ``kinecal identifiability --data`` reads.
    dict
        ``identifiable`` (names), ``rank``, ``not_seen`` and ``O1``..``O5`` of the plan.
    """
    gen = np.random.default_rng(rng)
    sim = simulate_kind(model, kind, candidates, rng=gen, option="--candidates", **geometry)
    data = sim.data
    block = make_blocks(model, [data])[0]
    p0 = model.nominal
    v = block.start(model, p0)
    problem = StackedProblem(model, [block], candidate_names(model, "all"),
                             [np.ones(block.n_obs)])
    ana = analyse_stack(problem, problem.pack(p0, [v]), 1e-4, check=True)
    names = ana.report.identifiable
    rows = block.evaluate(model, p0, v, model.index(names), jacobian=True)
    J = np.hstack([rows.arm, rows.nuisance])
    J = J / np.maximum(np.sqrt((J**2).mean(axis=0)), 1e-300)
    B = J.reshape(block.n_obs, -1, J.shape[1])
    groups = len(block.live_groups)
    want = count if kind == "pair" else count * groups
    if want > block.n_obs or want * B.shape[1] < J.shape[1]:
        raise InputError(f"count: {count} per gauge gives {want * B.shape[1]} equations for "
                         f"{J.shape[1]} unknowns (or more than the {block.n_obs} candidates)",
                         option="--count")
    chosen = np.sort(np.asarray(d_optimal(B, want), dtype=np.intp))
    if kind == "pair":
        idx = np.ravel(np.column_stack([block.a[chosen], block.b[chosen]]))
    else:
        idx = chosen
    group = np.asarray(data.group)[idx]
    if kind != "pair" and np.bincount(group, minlength=groups).min() < block.min_rows:
        raise InputError(f"the selection leaves a {block.group_word} with fewer than "
                         f"{block.min_rows} rows: ask for more (--count)", option="--count")
    order = np.argsort(group, kind="stable")
    idx = idx[order]
    plan = GaugeMeasurements(kind, data.q[idx], np.asarray(data.group)[idx], data.group_names,
                             None if data.distance is None else data.distance[idx],
                             source=f"planned {kind} of {model.name}")
    sel = J.reshape(block.n_obs, -1, J.shape[1])[chosen].reshape(-1, J.shape[1])
    from kinecal.calibration.identifiability import observability_indices

    sv = np.linalg.svd(sel, compute_uv=False)
    return plan, {"identifiable": list(names), "rank": ana.report.rank,
                  "not_seen": list(ana.unseen), **observability_indices(sv, sel.shape[0])}


def select_system_poses(model, count: int, *, candidates: int = 500,
                        tips: Sequence[str] | None = None,
                        rng: int | np.random.Generator | None = None
                        ) -> tuple[Any, dict[str, Any]]:
    """Tracker rows of a robot system that identify the most: which chain, in which
    configuration (``kinecal select-poses SYSTEM``).

    `candidates` random configurations per tip (`tips`, default all) of the nominal
    system; `count` rows in all chosen to maximise ``log det`` of the information of the
    parameters the candidates identify (unit-RMS columns; greedy build-up and exchanges,
    `kinecal.calibration.serial.pose_selection.d_optimal`).

    Returns
    -------
    Measurements
        The chosen rows (their tips in ``marker``), nominal tool points as ``xyz``.
    dict
        ``identifiable``, ``rank``, ``per_tip`` (rows chosen per tip), ``O1``..``O5``.
    """
    from kinecal.calibration.blocks.system_simulate import simulate_system
    from kinecal.calibration.identifiability import observability_indices

    data = simulate_system(model, candidates, tips=tips, rng=rng).data
    names = analyse_system(model, [data], "all")[0].report.identifiable
    if count < 1 or count > len(data) or 3 * count < len(names):
        raise InputError(f"count: {count} rows give {3 * count} equations for {len(names)} "
                         f"identifiable parameters (and at most {len(data)} candidates): "
                         f"expected {-(-len(names) // 3)} to {len(data)}", option="--count")
    idx = model.index(names)
    J = model.identification_jacobian(data.q, marker=data.marker)[:, :, idx]
    J = J / np.maximum(np.sqrt((J ** 2).mean(axis=(0, 1))), 1e-300)
    chosen = np.sort(np.asarray(d_optimal(J, count), dtype=np.intp))
    plan = data.subset(chosen)
    s = np.linalg.svd(J[chosen].reshape(-1, idx.size), compute_uv=False)
    per_tip = {t: int((plan.marker == k).sum()) for k, t in enumerate(model.tips)}
    return plan, {"identifiable": list(names), "rank": len(names), "per_tip": per_tip,
                  **observability_indices(s, 3 * count)}
