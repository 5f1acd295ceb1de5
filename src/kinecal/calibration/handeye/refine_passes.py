"""The weighted Levenberg-Marquardt passes of `kinecal.calibration.handeye.refine.lm`:
each station's residual whitened by its noise model (`kinecal.calibration.handeye.noise`),
the model's components re-estimated between passes, Cauchy weights on the whitened
station distances."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.residuals import (
    _CAUCHY_C,
    _MIN_ESTIMATED,
    _chi2_isf6,
    _jacobian,
    _scales,
    _update,
    camera_residuals,
    residuals_and_jacobian,
)
from kinecal.spatial import invert_transform

Array = NDArray[np.float64]

__all__ = ["Passes"]


class Passes:
    """The weighted Levenberg-Marquardt passes of `lm` on stations (G, C), each station's
    residual whitened by its noise model (`kinecal.calibration.handeye.noise`)."""

    def __init__(self, G: Array, C: Array, rotation_weight: float | None,
                 eye_in_hand: bool = True) -> None:
        self.G, self.C, self.rotation_weight = G, C, rotation_weight
        self.eye_in_hand = eye_in_hand
        self.Ginv = invert_transform(G)  # every evaluation's, computed once
        self.L = max(float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1)))), 1e-300)
        # exact readings (a component at zero) stay invertible: round-off of rotations and
        # lengths, as the scales' floors
        self.floor = np.r_[[1e-26] * 3, [(1e-13 * self.L) ** 2] * 3]
        #: three components need stations to spare (24 degrees of freedom at 6 stations)
        self.estimates = rotation_weight is None and len(G) >= _MIN_ESTIMATED
        self.source = ("rotation_weight" if rotation_weight is not None
                       else "estimated" if self.estimates else "scales")
        self.nfev = 0
        self.history: list[float] = []

    def whitening(self, X: Array, Y: Array, theta: Array) -> Array:
        """``L_i^-1`` ``(n, 6, 6)`` of every station at X, Y."""
        from kinecal.calibration.handeye.noise import station_components, whitening

        if not self.estimates:  # diagonal: no robot component
            w = 1.0 / np.sqrt(np.r_[[theta[0]] * 3, [theta[1]] * 3] + self.floor)
            return np.broadcast_to(np.diag(w), (len(self.G), 6, 6))
        rot, _ = camera_residuals(self.G, self.C, X, Y, self.Ginv)
        V = station_components(self.G, self.C, X, Y, rot, self.eye_in_hand)
        return whitening(theta, V, self.floor)

    def distances(self, X: Array, Y: Array, theta: Array) -> Array:
        """Whitened station distances ``(n,)`` (chi with 6 dof for inliers)."""
        rot, tr = camera_residuals(self.G, self.C, X, Y, self.Ginv)
        Li = self.whitening(X, Y, theta)
        return np.linalg.norm(Li @ np.concatenate([rot, tr], axis=1)[..., None], axis=(1, 2))

    def solve(self, X: Array, Y: Array, w: Array, Li: Array) -> tuple[Array, Array]:
        """Minimise the station residuals whitened by `Li` ``(n, 6, 6)`` and weighted by `w`
        ``(n,)`` (MINPACK's Levenberg-Marquardt with the analytic Jacobian)."""
        G, C, Gi = self.G, self.C, self.Ginv
        keep = w > 0
        sw = np.sqrt(w[keep])[:, None]
        Lk = np.ascontiguousarray(Li[keep])
        G, C, Gi = G[keep], C[keep], Gi[keep]

        last: list[tuple[Array, ...]] = []  # MINPACK asks the Jacobian where it last
        # evaluated the residuals: their poses and residuals are reused there

        def fun(p: Array) -> Array:
            Xp, Yp = _update(X, p[:6]), _update(Y, p[6:])
            rot, tr = camera_residuals(G, C, Xp, Yp, Gi)
            last[:] = [(p.copy(), Xp, Yp, rot, tr)]
            r = np.concatenate([rot, tr], axis=1)
            return (sw * np.einsum("nij,nj->ni", Lk, r)).ravel()

        def jac(p: Array) -> Array:
            if last and np.array_equal(last[0][0], p):
                J = _jacobian(G, C, *last[0][1:], p)
            else:
                J = residuals_and_jacobian(G, C, X, Y, p, Gi)[2]  # (n, 6, 12)
            return ((Lk @ J) * sw[:, :, None]).reshape(-1, 12)

        from scipy.optimize import least_squares

        sol = least_squares(fun, np.zeros(12), jac=jac, method="lm", x_scale="jac")
        self.nfev += int(sol.nfev)
        self.history.append(float(2.0 * sol.cost))
        return _update(X, sol.x[:6]), _update(Y, sol.x[6:])

    def start_noise(self, X: Array, Y: Array, mask: Array) -> Array:
        """Robust (median-based) scales of the stations in `mask` as a start: camera
        rotation and translation, no robot component."""
        rot, tr = camera_residuals(self.G[mask], self.C[mask], X, Y, self.Ginv[mask])
        sr, st = _scales(rot, tr, self.L)
        if self.rotation_weight is not None:
            sr = st / self.rotation_weight
        return np.array([sr**2, st**2, 0.0])

    def noise(self, X: Array, Y: Array, mask: Array, theta: Array,
              final: bool = False) -> Array:
        """The noise components re-estimated on the stations in `mask` ``(n,)`` (REML,
        `noise.estimate_components`); without estimation, the scales of the residuals
        (robust ones while reweighting, their rms in the `final` pass)."""
        G, C, Gi = self.G[mask], self.C[mask], self.Ginv[mask]
        if not self.estimates:
            if not final:
                return self.start_noise(X, Y, mask)
            rot, tr = camera_residuals(G, C, X, Y, Gi)
            st = max(float(np.sqrt(np.mean(np.sum(tr**2, 1)) / 3.0)), 1e-13 * self.L)
            sr = (st / self.rotation_weight if self.rotation_weight is not None else
                  max(float(np.sqrt(np.mean(np.sum(rot**2, 1)) / 3.0)), 1e-13))
            return np.array([sr**2, st**2, 0.0])
        from kinecal.calibration.handeye.noise import estimate_components, station_components

        rot, tr, J = residuals_and_jacobian(G, C, X, Y, np.zeros(12), Gi)
        V = station_components(G, C, X, Y, rot, self.eye_in_hand)
        # while reweighting, a few steps from the last estimate suffice (the weights move it)
        theta = estimate_components(np.concatenate([rot, tr], axis=1), J, V, theta,
                                    self.floor, max_iter=30 if final else 4)
        if final:  # below the round-off floor a component is zero (noise-free readings)
            theta = np.where(theta < self.floor[[0, 3, 0]], 0.0, theta)
        return theta

    def reweighted(self, X: Array, Y: Array, robust: bool, outlier_level: float,
                   max_outer: int, start_inliers: Array | None
                   ) -> tuple[Array, Array, NDArray[np.bool_], Array]:
        """Cauchy-reweighted passes (robust), the inlier mask ``(n,)`` they leave (all
        stations when fewer than 3 remain, or not robust) and the noise components."""
        n = len(self.G)
        w = np.ones(n)
        trusted = np.ones(n, bool)
        if robust and start_inliers is not None and len(start_inliers) >= 3:
            trusted = np.zeros(n, bool)
            trusted[np.asarray(start_inliers, dtype=np.intp)] = True
            w = trusted.astype(float)
        theta = self.start_noise(X, Y, trusted)
        if not robust:
            return X, Y, np.ones(n, bool), theta
        for k in range(max_outer):
            X, Y = self.solve(X, Y, w, self.whitening(X, Y, theta))
            mask = w > 0.5 if start_inliers is not None else np.ones(n, bool)
            # the first pass's robust scales judge the stations; the estimate (on the
            # stations weighted above 1/2) then refines them
            theta = self.start_noise(X, Y, mask) if k == 0 else \
                self.noise(X, Y, mask & (w > 0.5), theta)
            d = self.distances(X, Y, theta)
            w_new = 1.0 / (1.0 + (d / (np.sqrt(6.0) * _CAUCHY_C)) ** 2)
            done = np.max(np.abs(w_new - w)) < 1e-3
            w = w_new
            if done and k > 0:
                break
        d = self.distances(X, Y, theta)
        inlier = d**2 <= _chi2_isf6(1.0 - outlier_level)
        if inlier.sum() < 3:
            inlier = np.ones(n, bool)
        return X, Y, inlier, theta
