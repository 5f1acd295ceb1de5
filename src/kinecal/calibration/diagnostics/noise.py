"""The instrument's stated noise: is the residual of a fit consistent with it?

``calibrate(model, data, sigma=S)`` (``kinecal calibrate --sigma S``): ``S`` is the
instrument's 1-sigma noise per coordinate (model length unit) of a row of weight 1 (a
row of weight ``w`` has the noise ``S / sqrt(w)``). Without repeated poses nothing else
tells the residual's noise from the errors the model misses; with ``S`` the classical
global test of the variance factor (the "overall model test" of geodetic network
adjustment) does:

* Under the model with noise ``S``, the weighted residual sum of squares of the position
  rows over ``S^2`` follows a chi-square distribution with ``f`` degrees of freedom:
  ``f = 3 n - r`` (``n`` independent poses, ``r`` the rank of the fit); with measured
  orientations the parameters are shared by position and rotation rows, and
  ``f = 3 n - trace(H_pos)``, the position rows' share of the hat matrix.
* ``residual-below-noise`` is warned when the statistic lies in the lower ``ALPHA`` tail
  and the residual's RMS per coordinate is at most `MAX_DEFICIT` (half) of ``S``: a
  pessimistic stated noise (another unit, a worst case) doubles the standard errors
  computed with it.
* ``residual-above-noise`` is warned when that statistic exceeds its upper ``ALPHA``
  quantile (clean data trip it with probability 0.001) *and* the residual's RMS per
  coordinate is at least ``sqrt(1 + MIN_EXCESS^2)`` = 1.118 times ``S``: the part the model
  misses is at least half the stated noise (below that, a few thousand poses would make
  a stated noise rounded to one significant digit "significant").

Standard errors are then reported both ways: the result's ``std`` (and "model uncertainty
left") keep the estimate from the residual itself (``sigma^2 = RSS / f``, which includes
whatever the model misses); ``noise.std`` and ``noise.predicted_error`` take the stated
noise as known (covariance ``S^2 (J^T W J)^+`` on the identifiable subspace). When the test
passes the two agree within the sampling error of the estimate; when it fails, the
estimate from the residual is the honest one. With measured orientations the
known-noise values assume the rotation rows carry the noise ``S`` too, i.e.
``--rotation-weight`` = ``S`` / the orientation noise (rad).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._special import chdtr, chdtrc
from kinecal.calibration.diagnostics._common import ALPHA
from kinecal.diagnostics import warn
from kinecal.errors import InputError

__all__ = ["MAX_DEFICIT", "MIN_EXCESS", "check_stated_noise", "check_stated_sigma",
           "known_covariance", "noise_entry", "noise_lines"]

Array = NDArray[np.float64]

#: the model misses "something" when its unmodelled part (RMS per coordinate) is at least
#: this fraction of the stated noise: the residual is then >= sqrt(1 + 0.5^2) = 1.118 S
MIN_EXCESS = 0.5
#: a stated noise this many times above the residual (RMS per coordinate, and in the
#: chi-square lower tail) is warned as pessimistic: the standard errors with it are more
#: than twice too large
MAX_DEFICIT = 0.5


def check_stated_sigma(model, sigma: float | None, where: str = "--sigma") -> float | None:
    """Refuse (before any work) a stated noise that is not a positive finite number, that
    is larger than the machine (`kinecal.calibration.diagnostics.sizes`), or below the
    double-precision resolution of its coordinates (its weight would overflow the fit's
    squares: ``--sigma 1e-300`` ended in a division by zero)."""
    if sigma is None:
        return None
    from kinecal._limits import check_finite
    from kinecal.calibration.diagnostics.sizes import check_length_noise, serial_size

    value = check_finite(sigma, where, positive=True)
    size = serial_size(model)
    check_length_noise(value, size, where, model.length_unit, "stated noise")
    floor = float(np.finfo(float).eps) * size
    if value < floor:
        raise InputError(f"a stated noise of {value:.4g} {model.length_unit} is below the "
                         "resolution of double-precision coordinates of this machine "
                         f"({floor:.3g} {model.length_unit}): expected at least that (is the "
                         "unit right?)", option=where)
    return value


def known_covariance(unc, sigma: float) -> Array:
    """Covariance ``(k, k)`` of the free parameters with the noise `sigma` known:
    ``sigma^2 (J^T W J)^+`` on the fitted subspace of `unc` (an `Uncertainty`)."""
    V, w, D = unc.fitted, unc.fitted_values, unc.scale
    if V.size == 0:
        return np.zeros_like(unc.covariance)
    return sigma**2 * (D[:, None] * ((V / w) @ V.T) * D[None, :])


def _position_dof(problem, x: Array, keep: Array, rank: int, normal: Array | None) -> float:
    """Residual degrees of freedom of the position rows of the poses `keep`."""
    if problem.rows == 3:
        return float(3 * keep.size - rank)
    from kinecal.calibration.diagnostics.fit import pose_leverage

    h = pose_leverage(problem, x, normal)  # mean leverage of each pose's position rows
    return float(3 * keep.size - 3.0 * h[keep].sum())


def check_stated_noise(problem, x: Array, unc, sigma: float, *,
                       unique_rows: Array | None = None, excluded: Sequence[int] = (),
                       normal: Array | None = None, method: str = "lm") -> dict[str, Any]:
    """``residual-above-noise``: the chi-square test of the fit's residual against the
    stated noise (module docstring); returns the result JSON's ``noise`` entry.

    Parameters
    ----------
    problem : CalibrationProblem
        The fitted problem.
    x : ndarray, shape (k,)
        Solution (free parameters).
    unc : Uncertainty
        The fit's uncertainty (fitted subspace, estimability).
    sigma : float
        Stated noise per coordinate of a row of weight 1 (length unit).
    unique_rows : ndarray of int, optional
        The rows counted as independent (exact copies of a row count once), as in the
        covariance.
    excluded : sequence of int
        Poses left out (a robust loss' outliers).
    normal : ndarray, shape (k, k), optional
        The weighted ``J^T J`` at `x` (saves a pass with measured orientations).
    method : str
        The calibration method (a metaheuristic does not minimise the squared error).

    Returns
    -------
    dict
        ``stated_sigma``, ``residual_sigma`` (RMS per coordinate of the position residual,
        unit weight), ``ratio``, ``chi2``, ``dof``, ``p_value`` (upper tail), ``verdict``
        (``consistent``, ``above``: warned, ``below``: the residual is as far below the
        noise, in the lower tail), ``consistent``, ``std``
        (standard errors with the noise known, model file units, None where not
        identifiable).
    """
    model = problem.model
    n = len(problem.data)
    keep = np.arange(n) if unique_rows is None else np.asarray(unique_rows, dtype=np.intp)
    if len(excluded):
        keep = np.setdiff1d(keep, np.asarray(excluded, dtype=np.intp))
    e = problem.errors(x)[keep]
    w = (np.ones(keep.size) if problem.data.weights is None
         else np.asarray(problem.data.weights, dtype=float)[keep])
    rss = float(np.einsum("i,ij,ij->", w, e, e))
    rank = int(unc.fitted.shape[1])
    dof = _position_dof(problem, x, keep, rank, normal)
    out: dict[str, Any] = {"stated_sigma": float(sigma), "residual_sigma": None, "ratio": None,
                           "chi2": rss / sigma**2, "dof": dof, "p_value": None,
                           "verdict": None, "consistent": None}
    if dof > 0:
        resid = float(np.sqrt(rss / dof))
        p = float(chdtrc(dof, rss / sigma**2))
        ratio = resid / sigma
        above = p < ALPHA and ratio >= np.sqrt(1.0 + MIN_EXCESS**2)
        below = float(chdtr(dof, rss / sigma**2)) < ALPHA and ratio <= 1.0 / np.sqrt(
            1.0 + MIN_EXCESS**2)
        verdict = "above" if above else "below" if below else "consistent"
        out.update(residual_sigma=resid, ratio=ratio, p_value=p, verdict=verdict,
                   consistent=verdict == "consistent")
        if below and ratio <= MAX_DEFICIT:
            warn("residual-below-noise",
                 f"the residual is {ratio:.3g} times the stated instrument noise "
                 f"({resid:.3g} against {sigma:.3g} {model.length_unit} per coordinate; "
                 f"chi-square {rss / sigma**2:.4g} on {dof:.0f} degrees of freedom, lower "
                 f"tail p = {float(chdtr(dof, rss / sigma**2)):.2g}): the stated noise is "
                 "pessimistic (another unit, or the instrument's worst case rather than its "
                 "1-sigma noise per coordinate), and so are the standard errors computed "
                 "with it")
        if above:
            unit = model.length_unit
            short = ("" if method in ("lm", "householder") else
                     f"; method {method} does not minimise the squared error, so part of the "
                     "excess may be the optimizer's")
            warn("residual-above-noise",
                 f"the residual is {ratio:.3g} times the stated instrument noise "
                 f"({resid:.3g} against {sigma:.3g} {unit} per coordinate; chi-square "
                 f"{rss / sigma**2:.4g} on {dof:.0f} degrees of freedom, p = {p:.2g}): the "
                 "model misses something: a base or tool frame, non-geometric errors "
                 "(try --error-model auto), outliers (try --loss soft_l1), or the stated "
                 f"noise is optimistic{short}")
    cov = known_covariance(unc, sigma)
    std = np.where(unc.estimable, np.sqrt(np.clip(np.diag(cov), 0.0, None)), np.inf)
    deg = model.angle_unit == "deg"
    angle = model.is_angle()[problem.index]
    conv = np.where(angle & deg, 180.0 / np.pi, 1.0)
    out["std"] = {name: (float(s * c) if np.isfinite(s) else None)
                  for name, s, c in zip(problem.free, std, conv, strict=True)}
    return out


def _predicted_known(result, entry: dict) -> dict[str, float | None]:
    """The result's predicted position errors with the stated noise known: the estimated
    ones scaled by ``S / sigma_hat`` (both covariances share ``(J^T W J)^+``)."""
    S = float(entry["stated_sigma"])
    sigma = float(result.sigma)
    if np.isfinite(sigma) and sigma > 0:
        pred = result.predicted_error_summary()
        return {k: (None if v is None else float(v) * S / sigma) for k, v in pred.items()}
    if result.uncertainty is None:
        return {"calibration_mean": None, "validation_mean": None}
    import dataclasses

    known = dataclasses.replace(result, covariance=known_covariance(result.uncertainty, S))
    return known.predicted_error_summary()


def noise_entry(result) -> dict[str, Any] | None:
    """The ``noise`` entry of the result JSON (None without a stated noise): the test and
    the standard errors of `check_stated_noise`, and ``predicted_error`` (mean predicted
    position error on the calibration and validation poses with the noise known)."""
    entry = result.extra.get("noise")
    if not isinstance(entry, dict):
        return None
    return {**entry, "predicted_error": _predicted_known(result, entry)}


def noise_lines(result, shown: tuple[str, float] | None = None) -> list[str]:
    """Summary lines on the stated noise ([] without one); lengths in the model's unit, or
    in `shown` (``(unit name, factor)``, `kinecal.metrology.units.display_unit`)."""
    entry = noise_entry(result)
    if entry is None:
        return []
    unit, f = shown if shown is not None else (result.nominal_model.length_unit, 1.0)
    S = entry["stated_sigma"] * f
    if entry["ratio"] is None:
        return [f"stated noise {S:.3g} {unit} per coordinate: no residual degrees of freedom "
                "to test it"]
    verdict = {"consistent": "consistent with it", "above": "ABOVE it: see the warning",
               "below": "below it: the stated noise looks pessimistic, and so do the "
                        "standard errors with it"}[entry["verdict"]]
    lines = [f"stated noise {S:.3g} {unit} per coordinate: residual "
             f"{entry['residual_sigma'] * f:.3g}"
             f" {unit} ({entry['ratio']:.3g} times; chi-square p = {entry['p_value']:.2g}, "
             f"{verdict})"]
    pred = entry["predicted_error"]
    if result.bounded and pred.get("calibration_mean") is not None:
        def size(v: float | None) -> str:
            return f"{v * f:.3g} {unit}" if v is not None and np.isfinite(v) else "not bounded"

        where = f"{size(pred['calibration_mean'])} on the calibration poses"
        if pred.get("validation_mean") is not None:
            where += f", {size(pred['validation_mean'])} on the validation poses"
        lines.append(f"model uncertainty left with the stated noise: {where}")
    return lines
