"""What a camera identifies of an arm: the rank analysis on the pixel Jacobian, in words.

The block's own unknowns (X, the board pose, free intrinsics) are always solved, so the
arm's parameters are analysed *beside* them: their Jacobian columns are projected on the
complement of the nuisance columns (what the nuisance cannot imitate), and the pivoted QR
of `kinecal.calibration.identifiability.analyse_factor` runs on that projection. A
parameter whose column the nuisance imitates entirely is not identifiable; the nuisance
group that imitates it names the reason:

- the **board pose** (eye-in-hand) or **X = cam2base** (eye-to-hand): the arm's base frame
  and what moves it rigidly (the first joint's position and zero) are seen only relative
  to a frame the camera cannot anchor;
- **X = cam2flange** (eye-in-hand) or the **board pose on the flange** (eye-to-hand): the
  tool frame and the last joint's offsets are indistinguishable from where the camera
  (or board) sits on the flange;
- the **intrinsics** (when free).

**Scale**: the board's printed size is the only length the pixels carry. When every
length the pixels see is free (the usual case), a uniform scale of the arm, X and the board
pose is imitated exactly by a scale of the board: the identified lengths then inherit the
board's size error one for one (``--board`` 1 % large, arm 1 % large). The analysis tests
the board-scale column against the free columns and says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from kinecal.calibration.camera.block import PixelBlock
from kinecal.calibration.identifiability import IdentifiabilityReport, analyse_factor

Array = NDArray[np.float64]

__all__ = ["CameraIdentifiability", "camera_identifiability"]

#: a nuisance group counts as taking up a parameter when it carries this share of it
SHARE = 0.05


@dataclass
class CameraIdentifiability:
    """Result of `camera_identifiability`.

    Attributes
    ----------
    report : IdentifiabilityReport
        The arm's candidate parameters analysed beside the nuisance (rank, identifiable,
        unidentifiable, confounded_with among the arm's parameters).
    taken_up_by : dict of str to list of str
        For each unidentifiable parameter, the nuisance groups (``X``, ``board``,
        ``intrinsics``) that imitate it.
    scale_free : bool
        True when a uniform scale (arm lengths, X, board pose) is imitated by the board's
        size: the lengths come from the ``--board`` size alone.
    sentences : list of str
        What the camera cannot identify, in words.
    """

    report: IdentifiabilityReport
    taken_up_by: dict[str, list[str]] = field(default_factory=dict)
    scale_free: bool = True
    sentences: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able: the report's keys plus ``taken_up_by``, ``scale_from_board`` and
        ``not_seen`` (the sentences)."""
        return {**self.report.to_dict(), "taken_up_by": self.taken_up_by,
                "scale_from_board": self.scale_free, "not_seen": list(self.sentences)}


def _orth(A: Array) -> Array:
    """Orthonormal basis of the column space of `A` (rank by a relative 1e-10)."""
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    Q, R, _ = scipy.linalg.qr(A, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    k = int((d > 1e-10 * max(d[0], 1e-300)).sum())
    return Q[:, :k]


def _unit(A: Array) -> tuple[Array, Array]:
    n = np.linalg.norm(A, axis=0)
    n = np.where(n > 0, n, 1.0)
    return A / n, n


def camera_identifiability(block: PixelBlock, params: Array, nu: Array,
                           candidates: Sequence[str], tol: float = 1e-4
                           ) -> CameraIdentifiability:
    """Identifiability of the arm's `candidates` from the block's pixels, nuisance solved.

    Parameters
    ----------
    block : PixelBlock
    params : ndarray, shape (n_params,)
        Arm parameters where the analysis is made (nominal at the start).
    nu : ndarray, shape (n_nuisance,)
        The block's own parameters there.
    candidates : sequence of str
        Arm parameters to analyse.
    tol : float
        Relative rank threshold (`kinecal.calibration.serial.api.CALIBRATION_RANK_TOL`).

    Returns
    -------
    CameraIdentifiability
    """
    names = list(candidates)
    cols = block.model.index(names)
    _, Ja, Jn = block.predict(params, nu, cols, jac=True, scale_column=True)
    m = 2 * block.n_corners
    Ja = Ja.reshape(m, -1)
    Jn = Jn.reshape(m, -1)
    Js, Jn = Jn[:, -1], Jn[:, :-1]
    An, _ = _unit(Jn)
    Aa, _ = _unit(Ja)
    Q = _orth(An)
    proj = Aa - Q @ (Q.T @ Aa)  # what the nuisance cannot imitate (unit columns)
    R = scipy.linalg.qr(proj, mode="r")[0][: len(names)]
    report = analyse_factor(R, names, m, tol=tol, scale=np.ones(len(names)))
    groups = block.nuisance_groups()
    taken: dict[str, list[str]] = {}
    kept = [names.index(n) for n in report.identifiable]
    basis = np.hstack([An, Aa[:, kept]])
    for name in report.unidentifiable:
        j = names.index(name)
        coef = np.linalg.lstsq(basis, Aa[:, j], rcond=None)[0]
        by = []
        for g, sl in groups.items():
            part = An[:, sl] @ coef[sl]
            if np.linalg.norm(part) > SHARE:
                by.append(g)
        taken[name] = by
    free_basis = _orth(np.hstack([An, Aa[:, kept]]))
    s_unit = Js / max(np.linalg.norm(Js), 1e-300)
    left = np.linalg.norm(s_unit - free_basis @ (free_basis.T @ s_unit))
    scale_free = bool(left < np.sqrt(tol))
    out = CameraIdentifiability(report, taken, scale_free)
    out.sentences = _sentences(out, block.setup)
    return out


def _sentences(info: CameraIdentifiability, setup: str) -> list[str]:
    """The words of the analysis (see the module docstring)."""
    in_hand = setup == "eye-in-hand"
    base_group = "board" if in_hand else "X"
    flange_group = "X" if in_hand else "board"
    base = [n for n, g in info.taken_up_by.items() if base_group in g]
    flange = [n for n, g in info.taken_up_by.items() if flange_group in g and n not in base]
    intr = [n for n, g in info.taken_up_by.items()
            if "intrinsics" in g and n not in base + flange]
    rest = [n for n in info.report.unidentifiable if n not in base + flange + intr]
    out = []
    if base:
        what = "the board pose (target2base)" if in_hand else "the camera pose (X = cam2base)"
        out.append(f"base frame against {what}: {', '.join(base)} move the whole arm "
                   f"rigidly, which {what} imitates; held at nominal (a camera does not see "
                   "the base)")
    if flange:
        what = ("the camera mount (X = cam2flange)" if in_hand
                else "the board mount (target2flange)")
        out.append(f"flange against {what}: {', '.join(flange)} move the end frame as "
                   f"{what} does; held at nominal (the mount absorbs them: a tool point "
                   "needs its own tool calibration)")
    if intr:
        out.append(f"intrinsics: {', '.join(intr)} are imitated by the free camera "
                   "intrinsics; held at nominal")
    for n in rest:
        parts = info.report.confounded_with.get(n, {})
        combo = ", ".join(parts) or "nothing (no effect on the pixels)"
        out.append(f"{n}: a combination of {combo} (these stations cannot tell them apart); "
                   "held at nominal")
    if info.scale_free:
        out.append("scale: set by the board's size alone: every identified length scales "
                   "with the --board square size (a board printed 1 % large makes the arm "
                   "1 % large); the images cannot check it")
    return out
