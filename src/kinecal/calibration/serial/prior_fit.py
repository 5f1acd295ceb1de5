"""The MAP fit of a serial calibration with a prior, its uncertainty, and which directions
the data decided and which the prior did (`kinecal.calibration.serial.prior`).

The prior rows are ``sigma (x_j - mu_j) / s_j`` beside the data rows (length unit,
weighted like a row of weight 1): with ``sigma`` the noise per coordinate (stated with
``--sigma``, else estimated from the fit without the prior, ``RSS / (m - rank)``) the sum
of squares is ``sigma^2`` times the negative log posterior, and its minimum the MAP
estimate. The posterior covariance is ``(F + P)^-1`` with the data's information
``F = J^T W J / sigma^2`` and the prior's ``P = diag(1 / s^2)``: in a direction the data
do not see it is the prior's own variance, never zero and never unbounded.

Which directions the data decided: the eigenvalues ``lambda`` of ``F`` whitened by the
prior (``S^{1/2} F S^{1/2}``, ``S = diag(s^2)``, on the parameters with a prior, with
those without one marginalised) compare the two informations; ``lambda >= 1`` is a
direction the data know better than the prior. Per parameter, its data share is
``1 - var_posterior / s^2``: 0 when the posterior is the prior, 1 when the prior has no
say; a parameter with a share below one half was decided by the prior.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.prior import Prior, prior_text
from kinecal.calibration.serial.problem import CalibrationProblem, column_scale
from kinecal.calibration.uncertainty import Uncertainty, estimable_rows
from kinecal.errors import InputError
from kinecal.optimize._common import FitResult
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = [
    "PriorFit",
    "PriorProblem",
    "fit_with_prior",
    "map_from_both",
    "noise_level",
    "posterior_uncertainty",
    "prior_entry",
    "prior_split",
    "solve_map",
]

Array = NDArray[np.float64]

#: data share below which a parameter counts as decided by the prior
PRIOR_DECIDED = 0.5


class PriorProblem:
    """A `CalibrationProblem` with the prior's rows after the data rows (the interface
    Levenberg-Marquardt uses: `residuals`, `jacobian`, `normal_equations`).

    Parameters
    ----------
    problem : CalibrationProblem
    prior : Prior
    noise : float
        Noise per coordinate of a row of weight 1 (length unit).
    """

    def __init__(self, problem: CalibrationProblem, prior: Prior, noise: float) -> None:
        self.problem = problem
        self.mean = np.asarray(prior.mean, dtype=float)
        self.w = noise * np.sqrt(prior.precision)
        self.m = problem.rows * len(problem.data)

    def prior_rows(self, x: Array) -> Array:
        return self.w * (np.asarray(x, dtype=float) - self.mean)

    def residuals(self, x: Array) -> Array:
        return np.concatenate([self.problem.residuals(x), self.prior_rows(x)])

    def jacobian(self, x: Array) -> Array:
        return np.vstack([self.problem.jacobian(x), np.diag(self.w)])

    def normal_equations(self, x: Array) -> tuple[Array, Array, Array]:
        r, A, g = self.problem.normal_equations(x)
        rp = self.prior_rows(x)
        return np.concatenate([r, rp]), A + np.diag(self.w**2), g + self.w * rp

    def monitor(self, r: Array) -> float:
        """Mean distance error of the data rows."""
        return self.problem.mean_distance_from_residuals(np.asarray(r)[:self.m])


def noise_level(problem: CalibrationProblem, res: OptimizeResult, rank: int,
                sigma: float | None) -> tuple[float, str]:
    """The noise the prior rows are weighted with: the stated `sigma`, or estimated from
    the fit `res` without the prior (``RSS / (m - rank)``).

    Raises
    ------
    InputError
        No degrees of freedom left to estimate it and none stated.
    """
    if sigma is not None:
        return float(sigma), "stated"
    dof = problem.rows * len(problem.data) - rank
    rss = 2.0 * float(res.fun)
    if dof <= 0 or not rss > 0:
        raise InputError("a prior needs the noise of the measurements: the fit without it "
                         "leaves no residual to estimate it from; state it (--sigma)",
                         option="--prior")
    return float(np.sqrt(rss / dof)), "estimated"


@dataclass
class PriorFit:
    """A MAP fit (module docstring).

    Attributes
    ----------
    prior : Prior
    noise : float
        The noise per coordinate the prior rows are weighted with (length unit).
    noise_source : {"stated", "estimated"}
    result : OptimizeResult
        The fit: ``x``; ``residual``, ``fun`` and ``normal_matrix`` of the data rows only.
    normal : ndarray, shape (k, k)
        The data's ``J^T W J`` plus the prior's ``sigma^2 P`` at ``x`` (weighted units).
    uncertainty : Uncertainty
        The posterior (`posterior_uncertainty`).
    split : dict
        `prior_split`.
    """

    prior: Prior
    noise: float
    noise_source: str
    result: OptimizeResult
    normal: Array
    uncertainty: Uncertainty
    split: dict


def solve_map(pp: PriorProblem, x0: Array) -> OptimizeResult:
    """Levenberg-Marquardt on the data and prior rows of `pp` from `x0`."""
    return levenberg_marquardt.fit(pp.residuals, pp.jacobian, x0, monitor=pp.monitor,
                               normal_equations=pp.normal_equations)


def map_from_both(pp: PriorProblem, prior: Prior, x: Array) -> OptimizeResult:
    """The MAP fit of `pp` started from `x` and from the prior values (where the prior
    speaks; elsewhere `x`): a non-linear fit can have more than one minimum (a fit without
    a prior that wandered off keeps a basin of its own), the lower posterior wins."""
    fit = solve_map(pp, x)
    start = np.where(prior.precision > 0, prior.mean, x)
    if not np.array_equal(start, x):
        other = solve_map(pp, start)
        if other.fun < fit.fun:
            other.nfev += fit.nfev
            fit = other
    return fit


def fit_with_prior(problem: CalibrationProblem, res: OptimizeResult, prior: Prior,
                   noise: float, noise_source: str, rank_tol: float) -> PriorFit:
    """The MAP estimate of `problem` with `prior`, from the fit without it (`res`) and from
    the prior values (where the prior speaks; a non-linear fit may have more than one
    minimum): the lower posterior wins.

    Parameters
    ----------
    problem : CalibrationProblem
    res : OptimizeResult
        The fit without the prior.
    prior : Prior
    noise, noise_source
        `noise_level`.
    rank_tol : float
        Relative rank threshold (eigenvalues of the scaled posterior normal matrix below
        ``rank_tol^2`` of the largest are directions nothing decides).
    """
    pp = PriorProblem(problem, prior, noise)
    fit = map_from_both(pp, prior, np.asarray(res.x, dtype=float))
    x = np.asarray(fit.x, dtype=float)
    r_all = np.asarray(fit.residual)
    r_data = r_all[:pp.m]
    A_post = np.asarray(fit.normal_matrix)
    A_data = A_post - np.diag(pp.w**2)
    out = FitResult(fit)
    out.x = x
    out.residual = r_data
    out.fun = 0.5 * float(r_data @ r_data)
    out.normal_matrix = A_data
    out.gradient = None
    out.prior_cost = 0.5 * float(r_all[pp.m:] @ r_all[pp.m:])
    scale = column_scale(problem.model, problem.data, problem.free,
                         positions=problem.errors_from_residuals(r_data) + problem.xyz)
    unc = posterior_uncertainty(A_post, noise, scale, rank_tol)
    split = prior_split(A_data / noise**2, prior, unc, scale, rank_tol)
    return PriorFit(prior, noise, noise_source, out, A_post, unc, split)


def posterior_uncertainty(normal: Array, noise: float, scale: Array,
                          rank_tol: float) -> Uncertainty:
    """The posterior covariance ``noise^2 normal^-1`` (`normal` = data plus prior, weighted
    units) on the directions the data or the prior decide, as an `Uncertainty` (``sigma``
    is `noise`; directions neither decides are not estimable, as without a prior)."""
    D = np.asarray(scale, dtype=float)
    k = D.size
    w, V = np.linalg.eigh(normal * D[:, None] * D[None, :]) if k else (np.zeros(0),
                                                                        np.zeros((0, 0)))
    order = np.argsort(w)[::-1]
    w, V = w[order], V[:, order]
    top = float(w.max(initial=0.0))
    keep = w > rank_tol**2 * top if top > 0 else np.zeros(k, dtype=bool)
    V1, w1, null, w_null = V[:, keep], w[keep], V[:, ~keep], w[~keep]
    cov = noise**2 * (D[:, None] * ((V1 / w1) @ V1.T) * D[None, :])
    estimable = estimable_rows(np.eye(k), V1, w1, null, w_null)
    return Uncertainty(cov, float(noise), estimable, null, D, V1, w1, w_null)


def prior_split(info: Array, prior: Prior, unc: Uncertainty, scale: Array,
                rank_tol: float) -> dict:
    """Which directions and parameters the data decided and which the prior did (module
    docstring).

    Parameters
    ----------
    info : ndarray, shape (k, k)
        The data's information ``J^T W J / sigma^2`` (parameter units).
    prior : Prior
    unc : Uncertainty
        The posterior.
    scale : ndarray, shape (k,)
        Column scale (lengths 1, angles ``1 / L``) for the rank of the unpriored part.

    Returns
    -------
    dict
        ``data_share`` (per free parameter, 0..1), ``decided_by_prior`` (names),
        ``directions`` ``{"data", "prior", "undetermined"}`` (counts).
    """
    prec = prior.precision
    a = prec > 0
    b = ~a
    F = 0.5 * (info + info.T)
    if b.any():  # marginalise the parameters without a prior
        Db = scale[b]
        Fbb = F[np.ix_(b, b)] * Db[:, None] * Db[None, :]  # lengths and angles comparable
        wb = np.linalg.eigvalsh(Fbb) if Fbb.size else np.zeros(0)
        rank_b = int((wb > rank_tol**2 * max(float(wb.max(initial=0.0)), 1e-300)).sum())
        inv_b = Db[:, None] * np.linalg.pinv(Fbb, rcond=rank_tol**2, hermitian=True) * Db
        S = F[np.ix_(a, a)] - F[np.ix_(a, b)] @ inv_b @ F[np.ix_(b, a)]
    else:
        rank_b, S = 0, F
    s = 1.0 / np.sqrt(prec[a])
    lam = np.linalg.eigvalsh(s[:, None] * S * s[None, :]) if a.any() else np.zeros(0)
    share = np.ones(prec.size)
    var = np.diag(unc.covariance)
    share[a] = np.clip(1.0 - var[a] * prec[a], 0.0, 1.0)
    share[b] = np.where(unc.estimable[b], 1.0, 0.0)
    decided = [n for n, sh, p in zip(prior.names, share, a, strict=True) if p and
               sh < PRIOR_DECIDED]
    return {
        "data_share": dict(zip(prior.names, share.tolist(), strict=True)),
        "decided_by_prior": decided,
        "directions": {"data": int((lam >= 1.0).sum()) + rank_b,
                       "prior": int((lam < 1.0).sum()),
                       "undetermined": int(b.sum()) - rank_b},
    }


def prior_entry(model, spec, prior: Prior | None, fit: PriorFit | None) -> dict | None:
    """The result JSON's ``prior`` (model file units): what was asked for and used, the
    noise, each free parameter's sigma, and the data / prior split; None without a prior
    (`spec` None)."""
    if spec is None or prior is None:
        return None
    conv = np.where(model.is_angle()[model.index(prior.names)],
                    180.0 / np.pi if model.angle_unit == "deg" else 1.0, 1.0)
    entry: dict = {
        "kind": spec.kind,
        "given": "auto" if spec.kind == "auto" else prior_text(model, prior),
        "used": prior_text(model, prior) if fit is not None else "none",
        "mean": spec.mean_from or "nominal",
    }
    if spec.kind == "auto":
        entry["strength"] = prior.strength if fit is not None else None
        entry["cross_validation"] = prior.choice
    if fit is None:
        return entry
    entry["noise"] = fit.noise
    entry["noise_source"] = fit.noise_source
    entry["sigma"] = {n: float(s * c) for n, s, c in zip(prior.names, prior.sigma, conv,
                                                         strict=True) if np.isfinite(s)}
    entry.update(fit.split)
    return entry


def prior_lines(entry: dict, blind: list[str] = ()) -> list[str]:
    """The summary's lines on the prior (from the result JSON's ``prior``); `blind`: the
    free parameters the data alone do not identify (the prior bounds them)."""
    if not entry:
        return []
    used = entry.get("used", "none")
    given = "" if entry.get("kind") != "auto" else " (auto: chosen by cross-validation)"
    if used == "none":
        why = ("it would move no parameter by a tenth of its standard error"
               if (entry.get("cross_validation") or {}).get("negligible") is not None
               else "no prior lowered the held-out error")
        return [f"prior: none used{given}: {why}"]
    lines = [f"prior: {used}{given}, about {entry.get('mean', 'nominal')} values, noise "
             f"{entry['noise']:.3g} ({entry['noise_source']})"]
    d = entry.get("directions", {})
    lines.append(f"  directions decided by the data: {d.get('data', 0)}, by the prior: "
                 f"{d.get('prior', 0)}" + (f", by neither: {d['undetermined']}"
                                           if d.get("undetermined") else ""))
    if blind:
        lines.append("  not identifiable from the data alone (the prior bounds them): "
                     + ", ".join(blind))
    decided = entry.get("decided_by_prior") or []
    if decided:
        lines.append("  decided by the prior (their uncertainty is the prior's): "
                     + ", ".join(decided))
    return lines
