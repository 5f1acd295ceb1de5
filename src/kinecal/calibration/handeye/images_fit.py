"""The passes of the reprojection refinement
(`kinecal.calibration.handeye.images.refine_reprojection`): residual statistics, the
robust corner scale, Huber passes with Cauchy station weights, and one weighted (robust)
least-squares solve on the structured normal equations of
`kinecal.calibration.handeye.bundle`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.bundle import normal_equations, robust_residuals, schur_solve
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    predict_blocks,
    predict_pixels,
)
from kinecal.optimize.lm import solve_normal_equations

Array = NDArray[np.float64]

__all__ = ["Fit", "reweighted_passes"]

#: Huber threshold of a corner residual (units of the corner noise)
HUBER = 3.0
#: Cauchy constant of the station weights (units of the median station RMS)
CAUCHY = 2.5


def reweighted_passes(fit: Fit, p: Array, r: Array, max_outer: int, history: list[float]
                       ) -> tuple[Array, Array, Array, float]:
    """Huber passes with Cauchy station weights on the station RMS relative to the median
    station (until the weights settle); returns p, residuals, station RMS and sigma."""
    usable = fit.usable
    w = usable.astype(float)
    sigma = fit.sigma_of(r, usable)
    srms = np.zeros(fit.pr.n)
    for _ in range(max_outer):
        p, cost, _, _ = fit.solve(p, w, sigma, "huber")
        history.append(cost)
        r, srms = fit.residual_stats(p)
        sigma = fit.sigma_of(r, w > 0.5)
        med = float(np.median(srms[usable]))
        w_new = np.where(usable, 1.0 / (1.0 + (srms / (CAUCHY * max(med, sigma))) ** 2), 0.0)
        done = np.max(np.abs(w_new - w)) < 1e-3
        w = w_new
        if done:
            break
    return p, r, srms, sigma


class Fit:
    """The reprojection problem's passes: residual statistics, robust scale, and one
    weighted (robust) least-squares solve on the structured normal equations."""

    def __init__(self, pr: ReprojectionProblem, counts: NDArray[np.intp]) -> None:
        self.pr = pr
        self.counts = counts
        self.starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
        self.g = 12 + pr.n_int
        self.prior = (np.r_[[1.0 / pr.robot[0]] * 3, [1.0 / pr.robot[1]] * 3]
                      if pr.robot else None)
        self.nfev = 0
        self._last: tuple[Array, tuple] | None = None
        #: stations the passes may weigh (not those with a board behind the camera at the
        #: start); the others' residuals are infinite
        self.usable = np.ones(pr.n, bool)

    def blocks(self, p: Array) -> tuple[Array, Array, Array | None]:
        """`predict_blocks` at `p`, kept for the next call at the same point (the end of
        one pass is where the next starts and where the statistics are taken)."""
        if self._last is None or not np.array_equal(self._last[0], p):
            self._last = (p.copy(), predict_blocks(self.pr, p))
        return self._last[1]

    def residual_stats(self, p: Array) -> tuple[Array, Array]:
        """Residuals ``(M, 2)`` (predicted minus observed, px) and station RMS ``(n,)``."""
        pred = self.blocks(p)[0] if self._last is not None and \
            np.array_equal(self._last[0], p) else predict_pixels(self.pr, p, False)[0]
        r = pred - self.pr.uv
        ss = np.bincount(self.pr.sid, weights=np.sum(r * r, axis=1), minlength=self.pr.n)
        rms = np.sqrt(ss / np.maximum(self.counts, 1))
        return r, np.where(np.isfinite(rms), rms, np.inf)

    def sigma_of(self, r: Array, mask: Array) -> float:
        """Robust corner noise (px per axis) over the stations in `mask`."""
        sel = r[(mask & self.usable)[self.pr.sid]].ravel()
        sel = sel[np.isfinite(sel)]
        s = 1.4826 * float(np.median(np.abs(sel))) if sel.size else 1.0
        return max(s, 1e-6)

    def solve(self, p: Array, w: Array, sigma: float, loss: str, final: bool = False
              ) -> tuple[Array, float, Array | None, Array | None]:
        """Minimise ``sum rho(r^2)`` over corners weighted by station weights `w` ``(n,)``
        (residuals in units of `sigma`, Huber threshold `HUBER`) and the robot prior.

        Returns p, the cost (twice scipy's ``0.5 sum rho``) and, for the `final` pass, the
        normal matrix with scipy's robust scaling of the Jacobian (for the covariance) and
        the raw residuals of the weighted rows (zero-weight stations left out)."""
        pr, g, prior = self.pr, self.g, self.prior
        scale = (np.sqrt(w) / sigma)[pr.sid]  # (M,) per corner

        off = scale == 0  # stations without weight: no rows (their pixels may be NaN)

        def rows(q: Array) -> tuple[Array, Array, Array | None, Array | None]:
            pred, Jg, Je = self.blocks(q)
            res = (pred - pr.uv) * scale[:, None]
            Jg = Jg * scale[:, None, None]
            if off.any():
                res[off], Jg[off] = 0.0, 0.0
            if Je is not None:
                Je = Je * scale[:, None, None]
                Je[off] = 0.0
            rp = None if prior is None else q[g:].reshape(-1, 6) * prior
            return res, Jg, Je, rp

        def equations(q: Array) -> tuple[Array, Array, Array]:
            res, Jg, Je, rp = rows(q)
            pseudo, wr, _ = robust_residuals(res, loss, HUBER)
            pri = None
            out = [pseudo.ravel()]
            if rp is not None:
                pp, wp, _ = robust_residuals(rp, loss, HUBER)
                pri = (np.broadcast_to(prior, rp.shape), wp, rp)
                out.append(pp.ravel())
            A, b = normal_equations(Jg, Je, wr, res, self.starts, pri)
            return np.concatenate(out), A, b

        # the passes before the last only set the station weights: 1e-9 suffices there
        tol = 1e-12 if final else 1e-9
        sol = solve_normal_equations(equations, p,
                                     linear_solver=lambda A, d, b: schur_solve(A, d, b, g),
                                     ftol=tol, xtol=tol, gtol=tol, max_nfev=200,
                                     damping=(1e-9, 1e-3))
        self.nfev += int(sol.nfev)
        q = sol.x
        if not final:
            return q, float(2.0 * sol.fun), None, None
        res, Jg, Je, rp = rows(q)
        _, _, c = robust_residuals(res, loss, HUBER)
        pri = None
        raw = res[w[pr.sid] > 0].ravel()
        if rp is not None:
            pri = (np.broadcast_to(prior, rp.shape), robust_residuals(rp, loss, HUBER)[2], rp)
            raw = np.concatenate([raw, rp.ravel()])
        A_cov, _ = normal_equations(Jg, Je, c, res, self.starts, pri)
        return q, float(2.0 * sol.fun), A_cov, raw
