"""Identifiability of kinematic parameters: pivoted QR, SVD and observability indices.

The identification Jacobian ``J`` (rows: measured coordinates, columns: parameters) is
first made unit-free, so that lengths and angles compare: either by a physical scale per
column (`analyse`'s ``scale``; calibration uses 1 for lengths and a characteristic length
``L`` of the measured workspace for angles, i.e. an angle counts as the arc it sweeps at
distance ``L``), or, without ``scale``, by scaling every column to unit norm (column
equilibration). Then

* QR with column pivoting orders the columns by how much new information each brings;
  the columns past the numerical rank are the unidentifiable parameters: each is, to
  working precision, a combination of the kept columns, and we report which ones;
* the singular values give the condition number and the observability indices
  O1 (Borm and Menq 1991), O2 (Driels and Pathre 1990), O3 and O4 (Nahvi and Hollerbach
  1996) and O5 (Sun and Hollerbach 2008).

Paper 002 (Zhao, Yang) removes the IRB-120's unidentifiable parameters this way (QR), 25 -> 20.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.optimize.factor import qr_update

__all__ = [
    "IdentifiabilityReport",
    "analyse",
    "analyse_factor",
    "conditioning",
    "observability_indices",
    "pivoted_qr_diagonal",
    "separated_columns",
]

#: relative threshold on |R_kk| / |R_00| below which a pivoted column counts as dependent
RANK_TOL = 1e-8
#: relative difference of remaining column norms below which pivoting sees a tie
TIE_TOL = 1e-9
#: rank threshold for parameters that become identifiable at the identified geometry: they
#: are freed only when well separated (pivot above 1e-4 of the largest), so that a
#: second-order effect never makes the problem ill-conditioned (`separated_columns`)
GROWTH_TOL = 1e-4


@dataclass(repr=False)
class IdentifiabilityReport:
    """Result of `analyse`.

    Attributes
    ----------
    names : list of str
        The analysed parameters (columns of the Jacobian), in input order.
    rank : int
        Numerical rank of the scaled Jacobian.
    identifiable : list of str
        Parameters kept (input order).
    unidentifiable : list of str
        Parameters that are combinations of the identifiable ones (input order).
    confounded_with : dict of str to dict of str to float
        For each unidentifiable parameter, the identifiable parameters whose combination
        has the same effect, with coefficients in parameter units (length unit, rad): a
        unit change of the unidentifiable parameter equals ``sum(c * unit change)``.
    condition_number : float
        sigma_max / sigma_min of the scaled Jacobian restricted to the identifiable set.
    singular_values : ndarray, shape (n,)
        Singular values of the scaled full Jacobian, descending.
    observability : dict of str to float
        O1..O5 of the identifiable set.
    """

    names: list[str]
    rank: int
    identifiable: list[str]
    unidentifiable: list[str]
    confounded_with: dict[str, dict[str, float]] = field(default_factory=dict)
    condition_number: float = float("nan")
    singular_values: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    observability: dict[str, float] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"<IdentifiabilityReport rank {self.rank} of {len(self.names)}, condition "
                f"number {self.condition_number:.3g}, {len(self.unidentifiable)} "
                "unidentifiable>")

    def to_dict(self) -> dict:
        """JSON-able dict (the ``kinecal identifiability --json`` contract)."""
        return {
            "rank": self.rank,
            "n_parameters": len(self.names),
            "identifiable": list(self.identifiable),
            "unidentifiable": list(self.unidentifiable),
            "confounded_with": self.confounded_with,
            "condition_number": float(self.condition_number),
            "observability": {k: float(v) for k, v in self.observability.items()},
            "singular_values": [float(s) for s in self.singular_values],
        }

    def explain(self) -> str:
        """Human-readable lines: why each dropped parameter is not identifiable."""
        lines = [f"rank {self.rank} of {len(self.names)}; condition number "
                 f"{self.condition_number:.3g} (identifiable set, scaled columns)"]
        for name in self.unidentifiable:
            parts = self.confounded_with.get(name, {})
            combo = " ".join(f"{c:+.3g}*{n}" for n, c in parts.items()) or "0 (no effect)"
            lines.append(f"  {name}: its effect equals {combo}")
        if self.unidentifiable:
            lines.append("  (coefficients per unit: length unit, rad)")
        return "\n".join(lines)


def observability_indices(singular_values: NDArray[np.float64], m: int) -> dict[str, float]:
    """Observability indices of singular values ``s`` (descending) of an ``m x L`` Jacobian.

    Returns
    -------
    dict
        ``O1 = (prod s)^(1/L) / sqrt(m)`` (Borm-Menq), ``O2 = s_min / s_max`` (Driels-Pathre),
        ``O3 = s_min`` (Nahvi-Hollerbach), ``O4 = s_min^2 / s_max`` (noise amplification,
        Nahvi-Hollerbach), ``O5 = 1 / sum(1 / s)`` (Sun-Hollerbach).
    """
    s = np.asarray(singular_values, dtype=float)
    if s.size == 0 or s[-1] <= 0:
        return {"O1": 0.0, "O2": 0.0, "O3": 0.0, "O4": 0.0, "O5": 0.0}
    L = s.size
    return {
        "O1": float(np.exp(np.log(s).sum() / L) / np.sqrt(m)),
        "O2": float(s[-1] / s[0]),
        "O3": float(s[-1]),
        "O4": float(s[-1] ** 2 / s[0]),
        "O5": float(1.0 / (1.0 / s).sum()),
    }


def analyse(
    J: NDArray[np.float64], names: Sequence[str], tol: float = RANK_TOL,
    scale: NDArray[np.float64] | None = None,
) -> IdentifiabilityReport:
    """Identifiability of the parameters behind the Jacobian `J`.

    Parameters
    ----------
    J : ndarray, shape (m, n)
        Identification Jacobian (any units per column; columns are scaled to unit norm).
    names : sequence of str, length n
        Parameter names of the columns.
    tol : float
        Relative rank threshold on the pivoted R diagonal.
    scale : ndarray, shape (n,), optional
        Column scale factors making the columns comparable (see module docstring); unit
        column norms when omitted.

    Returns
    -------
    IdentifiabilityReport

    Notes
    -----
    `J` is reduced to its R factor (row blocks folded one at a time, `qr_update`) and
    handed to `analyse_factor`: every number of the report depends on ``J`` only through
    ``J^T J``.
    """
    J = np.asarray(J, dtype=float)
    names = list(names)
    if J.ndim != 2 or J.shape[1] != len(names):
        raise InputError(f"Jacobian shape {J.shape} does not match {len(names)} names")
    R = None
    step = max(4 * J.shape[1], 4096)
    for s in range(0, max(J.shape[0], 1), step):
        R = qr_update(R, J[s:s + step])
    return analyse_factor(R, names, J.shape[0], tol=tol, scale=scale)


def analyse_factor(
    R: NDArray[np.float64], names: Sequence[str], n_rows: int, tol: float = RANK_TOL,
    scale: NDArray[np.float64] | None = None,
) -> IdentifiabilityReport:
    """Identifiability from a square-root factor of ``J^T J`` (see `analyse`).

    Parameters
    ----------
    R : ndarray, shape (k, n)
        Any factor with ``R^T R = J^T J``: the R of a (TSQR) QR factorisation of ``J``
        (exact) or a root of an accumulated Gram matrix (`kinecal.optimize.factor.gram_root`;
        directions below ``sqrt(eps)`` are lost). Column-pivoted QR of ``R`` makes the same
        pivoting decisions as that of ``J``, because ``J = Q R`` with ``Q`` orthonormal
        preserves column norms and inner products; the least-squares confounding
        coefficients and the singular values are those of ``J`` as well.
    names : sequence of str, length n
        Parameter names of the columns.
    n_rows : int
        Rows ``m`` of ``J`` (for O1, which divides by ``sqrt(m)``).
    tol, scale
        As in `analyse`.

    Returns
    -------
    IdentifiabilityReport
    """
    R = np.asarray(R, dtype=float)
    names = list(names)
    if R.ndim != 2 or R.shape[1] != len(names):
        raise InputError(f"Jacobian factor shape {R.shape} does not match {len(names)} names")
    if not np.isfinite(R).all():
        raise InputError("Jacobian contains NaN or infinite values")
    if scale is None:
        norms = np.linalg.norm(R, axis=0)
        zero = norms <= tol * max(norms.max(initial=0.0), 1.0)
        factors = 1.0 / np.where(zero, 1.0, norms)
    else:
        factors = np.asarray(scale, dtype=float)
        if factors.shape != (len(names),) or not (factors > 0).all():
            raise InputError(f"scale: expected {len(names)} positive factors")
        norms = np.linalg.norm(R * factors, axis=0)
        zero = norms <= tol * max(norms.max(initial=0.0), 1e-300)
    Rs = R * factors
    Rs[:, zero] = 0.0
    diag, piv = pivoted_qr_diagonal(Rs)
    rank = int((diag > tol * diag[0]).sum()) if diag.size and diag[0] > 0 else 0
    kept = np.sort(piv[:rank])
    dropped = np.sort(piv[rank:])
    confounded: dict[str, dict[str, float]] = {}
    if dropped.size and rank:
        coef, *_ = np.linalg.lstsq(Rs[:, kept], Rs[:, dropped], rcond=None)
        # back to parameter units: J_d f_d = J_k f_k c  ->  J_d = J_k (f_k c / f_d)
        coef = coef * factors[kept][:, None] / factors[dropped][None, :]
        for j, col in enumerate(dropped):
            c = coef[:, j]
            big = np.abs(c) > 1e-6 * max(np.abs(c).max(), 1e-300)
            confounded[names[col]] = {names[kept[i]]: float(c[i]) for i in np.flatnonzero(big)}
    n_sv = min(n_rows, len(names))
    s_all = np.linalg.svd(Rs, compute_uv=False)[:n_sv] if Rs.size else np.zeros(0)
    cond, s_id = conditioning(Rs[:, kept]) if rank else (float("inf"), np.zeros(0))
    return IdentifiabilityReport(
        names=names,
        rank=rank,
        identifiable=[names[k] for k in kept],
        unidentifiable=[names[k] for k in dropped],
        confounded_with=confounded,
        condition_number=cond,
        singular_values=s_all,
        observability=observability_indices(s_id, n_rows),
    )


def pivoted_qr_diagonal(
    A: NDArray[np.float64], tie: float = TIE_TOL, stop: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """``|diag(R)|`` and the column order of Householder QR with column pivoting of `A`.

    Each step takes the column with the largest remaining norm (Businger and Golub 1965);
    among columns within a relative `tie` of that largest norm (parameters whose effects are
    equal to working precision, such as a base-frame z and the first link's d when the two
    axes coincide) the one *last* in column order wins, so that base- and tool-frame
    parameters, listed last, take up what is confounded with a joint's. An exact rule
    instead of LAPACK's round-off: the choice does not depend on how ``J`` was reduced to
    its factor (row order, chunk sizes).

    Parameters
    ----------
    A : ndarray, shape (m, n)
    tie : float
        Relative tolerance of a tie between remaining column norms.
    stop : float
        Stop once every remaining column norm is at most `stop` (their order is then
        left as it is and their pivots are 0): a rank decision needs no more.

    Returns
    -------
    diag : ndarray, shape (min(m, n),)
        Absolute pivots ``|R_kk|``, non-increasing.
    piv : ndarray, shape (n,)
        Column order (``piv[k]`` is the column pivoted at step ``k``).
    """
    W = np.array(A, dtype=float, copy=True)
    m, n = W.shape
    piv = np.arange(n)
    diag = np.zeros(min(m, n))
    for j in range(min(m, n)):
        Wj = W[j:, j:]
        norms = np.sqrt(np.einsum("ij,ij->j", Wj, Wj))
        top = norms.max()
        if top <= stop:
            break
        near = np.flatnonzero(norms >= top * (1.0 - tie))
        c = j + near[np.argmax(piv[j + near])]
        W[:, [j, c]] = W[:, [c, j]]
        piv[[j, c]] = piv[[c, j]]
        x = W[j:, j]
        alpha = -np.copysign(np.linalg.norm(x), x[0])
        v = x.copy()
        v[0] -= alpha
        vv = float(v @ v)
        diag[j] = abs(alpha)
        if vv > 0.0:
            W[j:, j:] -= v[:, None] * ((2.0 / vv) * (v @ W[j:, j:]))[None, :]
    return diag, piv


def conditioning(R: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """Condition number and singular values (descending) of a (scaled) factor ``(k, n)``."""
    s = np.linalg.svd(R, compute_uv=False) if R.size else np.zeros(0)
    cond = float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")
    return cond, s


def separated_columns(B: NDArray[np.float64], free: Sequence[int], held: Sequence[int],
                      tol: float) -> NDArray[np.intp]:
    """The held columns that a fit could free: those of the (scaled) factor `B` ``(r, k)``
    keeping a pivot above ``max(tol, GROWTH_TOL)`` of the free set's largest after the
    free columns are projected out (pivoted QR of the rest; the free set only grows, a
    confounded pair is never swapped). The growth step of every calibration of an arm,
    the serial one's (`kinecal.calibration.serial.solve.grow_identifiable`) as the
    stack's (`kinecal.calibration.blocks.solve`).

    Returns
    -------
    ndarray of int
        Positions into `held`, sorted.
    """
    from scipy.linalg import qr

    Q, Rf = np.linalg.qr(B[:, list(free)])
    rest = B[:, list(held)] - Q @ (Q.T @ B[:, list(held)])
    _, R, piv = qr(rest, mode="economic", pivoting=True)
    ref = np.abs(np.diag(Rf)).max() if Rf.size else 1.0
    diag = np.abs(np.diag(R))
    return np.sort(piv[: int((diag > max(tol, GROWTH_TOL) * ref).sum())])
