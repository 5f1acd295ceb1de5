"""The statistics of a check: today's residuals judged against the calibration's own
uncertainty and the instrument's noise.

Model. Today's residuals ``r`` (``m`` rows: measured minus predicted by the current
calibration, each measurement set's own unknowns, e.g. a ballbar's pivot, fitted) are,
if the robot has not changed, ``r = R (e + A d)`` to first order: ``e`` the instrument's
noise (``diag(s^2)``), ``d`` the calibration's own error (covariance ``C`` of its free
parameters, ``A`` their Jacobian at today's poses), ``R`` the projection that fitting the
unknowns (Jacobian ``N``) applies. So ``Cov0 = diag(s^2) + A C A^T`` (JCGM 100:2008's
propagation), and after whitening by ``L`` (``Cov0 = L L^T``) and projecting out the
whitened unknowns, ``T = |t|^2`` follows chi-square with ``m - rank(N)`` degrees of
freedom: the overall test (Teunissen 2000, *Testing Theory*, the overall model test).
When the noise is not stated but the calibration's residual estimate (``nu`` degrees of
freedom), which scales ``C`` as well, ``T / dof`` follows F(dof, nu) instead.
The directed test projects ``t`` on the directions robots usually suffer (``D``: joint
offsets, base), chi-square with their rank as degrees of freedom (Teunissen's w-test
generalised to a subspace); it is the more powerful for such a change. Each test is
taken at ``alpha / 2`` (Bonferroni): an unchanged robot fails either with probability
at most ``alpha``.

The change along the directions is estimated by least squares on the whitened, projected
rows (with its standard error); the size of the systematic error, ``deviation``, is the
root of ``(|r|^2 - E|r|^2) / n_obs`` (the excess of the residual over what noise and the
calibration's uncertainty explain, per observation, not below 0), in the length unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["Judgement", "chi2_sf", "f_sf", "judge"]

Array = NDArray[np.float64]

#: relative pivot below which a direction counts as not seen by today's poses
DIRECTION_TOL = 1e-3


def _gamma_q_series(a: float, x: float) -> float:
    """``Q(a, x) = 1 - P(a, x)`` from P's series (x < a + 1)."""
    term = total = 1.0 / a
    n = a
    for _ in range(10_000):
        n += 1.0
        term *= x / n
        total += term
        if abs(term) < abs(total) * 1e-16:
            break
    log_p = math.log(total) - x + a * math.log(x) - math.lgamma(a)
    return -math.expm1(log_p) if log_p < 0 else 0.0


def _gamma_q_fraction(a: float, x: float) -> float:
    """``Q(a, x)`` by Lentz's continued fraction (x >= a + 1)."""
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-16:
            break
    return math.exp(-x + a * math.log(x) - math.lgamma(a)) * h


def chi2_sf(x: float, dof: float) -> float:
    """The chi-square survival function ``P(X > x)`` with `dof` degrees of freedom (the
    regularised upper incomplete gamma function ``Q(dof/2, x/2)``, to about 1e-14
    relative; scipy.special.chdtrc without scipy's import time)."""
    if dof <= 0:
        return float("nan")
    if x <= 0:
        return 1.0
    if not math.isfinite(x):
        return 0.0
    a, y = 0.5 * dof, 0.5 * x
    return _gamma_q_series(a, y) if y < a + 1.0 else _gamma_q_fraction(a, y)


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of the incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (tiny if abs(d) < tiny else d)
    h = d
    for m in range(1, 10_000):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + num * d
            d = 1.0 / (tiny if abs(d) < tiny else d)
            c = 1.0 + num / c
            c = tiny if abs(c) < tiny else c
            h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    return h


def beta_inc(a: float, b: float, x: float) -> float:
    """The regularised incomplete beta function ``I_x(a, b)``."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    log_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
                 + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _beta_fraction(a, b, x) / a
    return 1.0 - math.exp(log_front) * _beta_fraction(b, a, 1.0 - x) / b


def f_sf(x: float, d1: float, d2: float) -> float:
    """The F distribution's survival function ``P(F > x)`` with `d1`, `d2` degrees of
    freedom: ``I_{d2 / (d2 + d1 x)}(d2 / 2, d1 / 2)`` (scipy.special.fdtrc)."""
    if d1 <= 0 or d2 <= 0:
        return float("nan")
    if x <= 0:
        return 1.0
    if not math.isfinite(x):
        return 0.0
    return beta_inc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * x))


def p_value(stat: float, dof: int, noise_dof: float | None) -> float:
    """P-value of a whitened sum of squares `stat` with `dof` degrees of freedom:
    chi-square when the noise is known, F(dof, noise_dof) when it was estimated with
    `noise_dof` degrees of freedom (the whitening then divided by that estimate)."""
    if dof <= 0:
        return 1.0
    if noise_dof is None or not math.isfinite(noise_dof):
        return chi2_sf(stat, dof)
    return f_sf(stat / dof, dof, noise_dof)


@dataclass
class Judgement:
    """What `judge` finds (module docstring).

    Attributes
    ----------
    statistic, dof, p_value : float
        The overall test.
    directed_statistic, directed_dof, directed_p_value : float
        The test along the usual directions (dof 0 and p 1 when none is seen).
    changed : bool
        Either test rejects at ``alpha / 2``.
    deviation : float
        Estimated RMS systematic error per observation (length unit).
    expected : ndarray, shape (n_obs,)
        Expected squared error of each observation when nothing changed.
    change, change_std : ndarray, shape (k,)
        Estimated change along each direction and its standard error (NaN where today's
        poses do not see it).
    """

    statistic: float
    dof: int
    p_value: float
    directed_statistic: float
    directed_dof: int
    directed_p_value: float
    changed: bool
    deviation: float
    expected: Array
    change: Array = field(default_factory=lambda: np.zeros(0))
    change_std: Array = field(default_factory=lambda: np.zeros(0))
    explained: dict[str, float] = field(default_factory=dict)
    explained_p: dict[str, float] = field(default_factory=dict)


def _basis(M: Array, tol: float = 1e-10) -> Array:
    """Orthonormal basis ``(m, r)`` of the columns of `M`."""
    if M.size == 0:
        return np.zeros((M.shape[0], 0))
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    keep = s > tol * max(s[0], 1e-300) if s.size else np.zeros(0, bool)
    return U[:, keep]


def _directions(Dt: Array, t: Array) -> tuple[float, int, Array, Array]:
    """The directed test and the estimated change along the columns of `Dt` (whitened,
    projected), each column judged seen or not by a pivoted QR of the unit columns."""
    from kinecal.calibration.identifiability import pivoted_qr_diagonal

    k = Dt.shape[1]
    change = np.full(k, np.nan)
    std = np.full(k, np.nan)
    norms = np.linalg.norm(Dt, axis=0)
    live = np.flatnonzero(norms > 0)
    if live.size == 0:
        return 0.0, 0, change, std
    U = Dt[:, live] / norms[live]
    diag, piv = pivoted_qr_diagonal(U)
    seen = live[np.sort(piv[: int(np.sum(diag > DIRECTION_TOL))])]
    if seen.size == 0:
        return 0.0, 0, change, std
    B = Dt[:, seen]
    G = B.T @ B
    est = np.linalg.solve(G, B.T @ t)
    change[seen] = est
    std[seen] = np.sqrt(np.clip(np.diag(np.linalg.inv(G)), 0, None))
    stat = float(est @ G @ est)  # |projection of t on span(B)|^2
    return stat, int(seen.size), change, std


def judge(r: Array, s: Array, A: Array, C: Array, N: Array, D: Array,
          obs_index: NDArray[np.intp], n_obs: int, alpha: float,
          noise_dof: float | None = None,
          groups: dict[str, NDArray[np.intp]] | None = None) -> Judgement:
    """Judge today's residuals (module docstring).

    Parameters
    ----------
    r : ndarray, shape (m,)
        Residual rows (length unit, or the block's unit).
    s : ndarray, shape (m,)
        The instrument's 1-sigma noise of each row.
    A : ndarray, shape (m, k)
        Jacobian of the rows w.r.t. the calibration's free parameters.
    C : ndarray, shape (k, k)
        Their covariance.
    N : ndarray, shape (m, u)
        Jacobian w.r.t. the unknowns fitted today (each set's own; the base when it is
        registered again).
    D : ndarray, shape (m, q)
        Jacobian w.r.t. the directions of the directed test.
    obs_index : ndarray of int, shape (m,)
        The observation of each row.
    n_obs : int
        Number of observations.
    alpha : float
        Probability of a false alarm on an unchanged robot.
    noise_dof : float, optional
        When the noise `s` and `C` both scale with one estimated variance (the
        calibration's residual), its degrees of freedom: F tests instead of chi-square.
    groups : dict of str to ndarray of int, optional
        Named groups of the columns of `D`: ``explained[name]`` is the share of the overall
        statistic's excess over its degrees of freedom that a change of that group alone
        explains, ``explained_p[name]`` the p-value of that group's own test.
    """
    m = r.size
    cov = np.diag(s**2) + A @ C @ A.T
    L = np.linalg.cholesky(cov)
    z = np.linalg.solve(L, r)
    Nw = np.linalg.solve(L, N) if N.size else np.zeros((m, 0))
    UN = _basis(Nw)
    t = z - UN @ (UN.T @ z)
    dof = m - UN.shape[1]
    stat = float(t @ t)
    p = p_value(stat, dof, noise_dof)
    Dw = np.linalg.solve(L, D) if D.size else np.zeros((m, 0))
    Dt = Dw - UN @ (UN.T @ Dw)
    dstat, ddof, change, change_std = _directions(Dt, t)
    dp = p_value(dstat, ddof, noise_dof)
    # expected squared residual of each row when nothing changed: diag(R cov R^T), R the
    # projection of the unknowns' fit (weights 1/s^2), as the fit made r
    if N.size:
        W = N / s[:, None] ** 2
        R = np.eye(m) - N @ np.linalg.pinv(N.T @ W) @ W.T
    else:
        R = np.eye(m)
    expected_rows = np.einsum("ij,jk,ik->i", R, cov, R)
    expected = np.bincount(obs_index, weights=expected_rows, minlength=n_obs)
    excess = (float(r @ r) - float(expected.sum())) / max(n_obs, 1)
    changed = (p < alpha / 2) or (ddof > 0 and dp < alpha / 2)
    explained, explained_p = {}, {}
    for name, cols in (groups or {}).items():
        B = _basis(Dt[:, cols]) if len(cols) else np.zeros((m, 0))
        g = float(np.sum((B.T @ t) ** 2))
        explained[name] = g / max(stat - dof, 1e-300)
        explained_p[name] = p_value(g, B.shape[1], noise_dof)
    return Judgement(stat, int(dof), float(p), dstat, ddof, float(dp), bool(changed),
                     math.sqrt(max(excess, 0.0)), expected, change, change_std, explained,
                     explained_p)
