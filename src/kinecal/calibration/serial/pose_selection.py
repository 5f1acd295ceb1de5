"""Choosing calibration poses that maximise observability.

From a candidate set of joint configurations (e.g. thousands of random reachable ones),
pick ``k`` whose stacked identification Jacobian has the largest observability index.
The default index is O1 (Borm and Menq 1991), the geometric mean of the singular values,
i.e. D-optimality: maximising ``log det(J^T J)``. The search is the classic greedy build-up
followed by Fedorov-style exchanges (replace the pose that contributes least by the
candidate that adds most), as in Sun and Hollerbach (2008), "Observability index selection
for robot calibration". Both steps use rank-one determinant updates, so a candidate's gain
is one quadratic form: no Python loop over candidates.

A model with several markers (tool points on one flange) is measured at every marker in
each configuration, as `kinecal.calibration.serial.simulate` simulates it: a candidate is then one
configuration with the ``3 M`` rows of its ``M`` markers, so the selection makes every
marker's tool point observable, not only the first one's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal._blas import small_products
from kinecal.calibration.identifiability import observability_indices
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["candidate_measurements", "d_optimal", "marker_rows", "select_poses"]

Array = NDArray[np.float64]


def marker_rows(model: SerialModel, q: Array) -> tuple[Array, NDArray[np.intp] | None]:
    """Configurations `q` ``(N, n_joints)`` measured at every marker of `model`.

    Returns
    -------
    q_rows : ndarray, shape (N * M, n_joints)
        Each configuration repeated once per marker (`q` itself without markers).
    marker : ndarray of int, shape (N * M,) or None
        The marker of each row, markers in turn (None without markers).
    """
    q = np.asarray(q, dtype=float)
    if not model.marker_names:
        return q, None
    m = len(model.marker_names)
    return np.repeat(q, m, axis=0), np.tile(np.arange(m, dtype=np.intp), len(q))


def candidate_measurements(model: SerialModel, q: Array) -> Measurements:
    """Noise-free measurements of the nominal `model` at configurations `q`, every marker
    in each (for the identifiability analysis of a pose plan)."""
    rows, marker = marker_rows(model, q)
    return Measurements(rows, model.positions(rows, None, marker), marker=marker,
                        marker_names=model.marker_names if marker is not None else ())


def _blocks(model: SerialModel, q: Array, names: Sequence[str]) -> Array:
    """Per-configuration Jacobian blocks ``(N, 3 M, k)`` (``M`` markers, 1 without), columns
    scaled to unit RMS over the rows."""
    rows, marker = marker_rows(model, q)
    J = model.identification_jacobian(rows, marker=marker)[:, :, model.index(list(names))]
    J = J.reshape(len(q), -1, J.shape[-1])
    scale = np.sqrt((J**2).sum(axis=(0, 1)) / (J.shape[0] * J.shape[1] / 3))
    return J / np.where(scale > 0, scale, 1.0)


def _gain(M_inv: Array, B: Array) -> Array:
    """``log det(I + B M^-1 B^T)`` for each block ``B`` (N, r, k): gain of adding a pose."""
    G = np.eye(B.shape[1]) + B @ M_inv @ np.swapaxes(B, 1, 2)
    return np.linalg.slogdet(G)[1]


def d_optimal(B: Array, count: int, *, exchanges: int = 2, ridge: float = 1e-6) -> list[int]:
    """`count` of the candidate row blocks ``B`` ``(N, r, k)`` maximising ``log det`` of
    their information ``sum B_j^T B_j``: greedy build-up, then Fedorov-style exchanges.

    Returns the chosen candidates' indices in selection order.
    """
    k = B.shape[2]
    M = ridge * np.eye(k)
    chosen: list[int] = []
    available = np.ones(B.shape[0], dtype=bool)
    for _ in range(count):  # greedy build-up
        gain = np.where(available, _gain(np.linalg.inv(M), B), -np.inf)
        j = int(np.argmax(gain))
        chosen.append(j)
        available[j] = False
        M = M + B[j].T @ B[j]
    for _ in range(exchanges):  # Fedorov-style exchange: drop the weakest, add the best
        improved = False
        for pos in range(count):
            out = chosen[pos]
            M_without = M - B[out].T @ B[out]
            gain = np.where(available, _gain(np.linalg.inv(M_without), B), -np.inf)
            j = int(np.argmax(gain))
            loss = _gain(np.linalg.inv(M_without), B[out:out + 1])[0]
            if gain[j] > loss + 1e-12:
                available[out], available[j] = True, False
                chosen[pos] = j
                M = M_without + B[j].T @ B[j]
                improved = True
        if not improved:
            break
    return chosen


@small_products
def select_poses(
    model: SerialModel,
    candidates: Array,
    count: int,
    *,
    free: Sequence[str] | None = None,
    exchanges: int = 2,
    ridge: float = 1e-6,
) -> tuple[NDArray[np.intp], dict[str, float]]:
    """Indices of `count` candidate poses maximising O1 (D-optimal design).

    Parameters
    ----------
    model : SerialModel
        Nominal model.
    candidates : ndarray, shape (N, n_joints)
        Candidate joint configurations (rad).
    count : int
        Configurations to select (``3 * count`` equations, ``3 * M * count`` with ``M``
        markers, must reach the number of parameters).
    free : sequence of str, optional
        Parameters to make observable (default: the model's calibratable ones; pass the
        identifiable set for a full-rank design).
    exchanges : int
        Passes of the exchange step after the greedy build-up.
    ridge : float
        Small ridge keeping the information matrix invertible while the set is small.

    Returns
    -------
    index : ndarray of int, shape (count,)
        Selected rows of `candidates`, in selection order.
    observability : dict
        O1..O5 of the selected set (unit-RMS columns).
    """
    q = np.asarray(candidates, dtype=float)
    names = list(model.calibratable) if free is None else list(free)
    if count < 1 or count > q.shape[0]:
        raise InputError(f"count: expected 1..{q.shape[0]} poses, got {count}", option="--count")
    rows = 3 * max(len(model.marker_names), 1)  # equations per configuration
    if rows * count < len(names):
        raise InputError(f"{count} poses give {rows * count} equations for {len(names)} "
                         "parameters", option="--count")
    B = _blocks(model, q, names)
    k = len(names)
    chosen = d_optimal(B, count, exchanges=exchanges, ridge=ridge)
    idx = np.array(chosen, dtype=np.intp)
    s = np.linalg.svd(B[idx].reshape(-1, k), compute_uv=False)
    return idx, observability_indices(s, rows * count)
