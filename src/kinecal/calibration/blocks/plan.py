"""Plan a mix of measurement kinds before measuring: what rows of several kinds identify.

``kinecal identifiability MODEL --data A.csv --data B.csv`` runs `analyse_kinds` on
measured or simulated files (``kinecal simulate MODEL --kind ballbar --errors zero ...``):
the rank on the stack with every pivot, point and plane free, the parameters each kind's
blindness leaves unidentified, and those motions in words.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from kinecal.calibration.blocks.analysis import StackAnalysis, analyse_stack
from kinecal.calibration.blocks.api import start_blocks
from kinecal.calibration.blocks.make import DataSet, make_blocks, marker_names
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.weights import initial_sigma
from kinecal.calibration.identifiability import RANK_TOL
from kinecal.calibration.serial.problem import candidate_names
from kinecal.kinematics.serial.markers import model_for_markers
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["analyse_kinds"]


def analyse_kinds(model: SerialModel, data: Sequence[DataSet], free: str | Sequence[str] = "all",
                  *, sigma: Sequence[float | None] | None = None, tol: float = RANK_TOL
                  ) -> tuple[StackAnalysis, list[dict[str, Any]]]:
    """Identifiability of `free` (``all``, ``identifiable`` or names) from data sets of any
    kinds at the nominal geometry, each set's unknowns fitted to it.

    Returns
    -------
    StackAnalysis
        ``report`` (the `kinecal identifiability` JSON) and ``unseen`` (motions of the whole
        arm the mix does not see).
    list of dict
        Per set: ``file``, ``kind``, ``observations``, ``rows``, ``unknowns`` (its own).
    """
    model = model_for_markers(model, marker_names(list(data)))
    blocks = make_blocks(model, list(data), sigma)
    p0 = model.nominal
    nuis, _ = start_blocks(model, blocks, p0)
    sig, _ = initial_sigma(blocks)
    names = candidate_names(model, "all" if free == "identifiable" else free)
    problem = StackedProblem(model, blocks, names, sig)
    ana = analyse_stack(problem, problem.pack(p0, nuis), tol, check=True)
    kinds = [{"file": b.source, "kind": b.kind, "observations": int(b.n_obs),
              "rows": int(b.n_rows), "unknowns": int(b.n_nuisance)} for b in blocks]
    return ana, kinds
