"""`calibrate_arm_camera`: the arm, X, the board pose (and the intrinsics) from corner pixels.

1. start: X and the board pose by a hand-eye closed form on the nominal flange poses and
   the per-image board poses (`kinecal.calibration.camera.start`);
2. hand-eye refinement with the arm at nominal (X, board, intrinsics on the pixels): the
   "before" of the report, and what the arm's errors cost in pixels;
3. identifiability of the arm beside the nuisance (`kinecal.calibration.camera.identify`):
   the free set, and what the camera cannot see, in words;
4. the bundle adjustment: the free arm parameters and the nuisance together, on every
   corner, robust loss optional (`kinecal.calibration.camera.lm`), outlier stations by the
   rule of the hand-eye image refinement (left out of a final pass with a robust loss,
   reported with ``linear``, as poses are on the tracker path);
5. the covariance on the identifiable subspace (`kinecal.calibration.uncertainty`), the
   corner noise estimated from the residual.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.camera.block import PixelBlock
from kinecal.calibration.camera.checks import check_camera_fit
from kinecal.calibration.camera.identify import camera_identifiability
from kinecal.calibration.camera.lm import LOSSES, robust_lm
from kinecal.calibration.camera.result import ArmCameraResult, Stations
from kinecal.calibration.camera.start import closed_form_start
from kinecal.calibration.handeye.images import _outlier_stations
from kinecal.calibration.serial.problem import candidate_names
from kinecal.calibration.uncertainty import subspace_uncertainty
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

Array = NDArray[np.float64]

__all__ = ["calibrate_arm_camera"]

#: rank threshold of the arm's analysis (that of calibrate's free="identifiable")
RANK_TOL = 1e-4


def _fit(block: PixelBlock, params0: Array, index: Array, z0: Array, keep: Array,
         loss: str, f_scale: float):
    """LM on ``z = [arm values at index, nuisance]`` over the corners of kept stations."""
    k = index.size
    mask = keep[block.sid]
    m = int(mask.sum())

    def fun(z: Array, jac: bool):
        p = params0.copy()
        p[index] = z[:k]
        uv, Ja, Jn = block.predict(p, z[k:], index, jac)
        r = (uv - block.uv)[mask].ravel()
        if not jac:
            return r, None
        J = np.concatenate([Ja[mask], Jn[mask]], axis=2).reshape(2 * m, -1)
        return r, J

    return robust_lm(fun, z0, loss=loss, f_scale=f_scale)


def _scale_of(r: Array) -> float:
    """3 x the median corner error (px): the robust loss' scale."""
    return 3.0 * max(float(np.median(np.linalg.norm(r.reshape(-1, 2), axis=1))), 1e-6)


def _flag(block: PixelBlock, srms: Array, r: Array, keep: Array) -> Array:
    sel = r.reshape(-1, 2)[keep[block.sid]].ravel()
    sigma = max(1.4826 * float(np.median(np.abs(sel))), 1e-6)
    return _outlier_stations(srms, block.counts, sigma, 0.999)


def calibrate_arm_camera(
    model: SerialModel,
    stations: Stations,
    K: Array,
    dist: Array | None,
    *,
    setup: str = "eye-in-hand",
    free: str | Sequence[str] = "identifiable",
    refine_intrinsics: bool = False,
    rational: bool = False,
    loss: str = "linear",
    f_scale: float | None = None,
    validate: Stations | None = None,
    X0: Array | None = None,
    Y0: Array | None = None,
    method: str = "park",
    rank_tol: float = RANK_TOL,
    extra: dict[str, Any] | None = None,
) -> ArmCameraResult:
    """Calibrate the arm's geometry, X and the board pose on the corner pixels.

    Parameters
    ----------
    model : SerialModel
        Nominal arm (length unit = the board's).
    stations : Stations
        Joints, detected corners and (for the start) PnP board poses of the used stations.
    K, dist
        Camera matrix and OpenCV distortion coefficients.
    setup : {"eye-in-hand", "eye-to-hand"}
    free : {"identifiable", "all"} or sequence of str
        The arm's free parameters (as in `kinecal.calibrate`).
    refine_intrinsics, rational : bool
        Free ``fx, fy, cx, cy, k1, k2, p1, p2, k3`` (and ``k4..k6`` for the rational model).
    loss : str
        ``linear`` or a robust loss on each corner (`kinecal.calibration.camera.lm.LOSSES`);
        robust: outlier stations left out of a final pass.
    f_scale : float, optional
        Robust loss scale (px); default 3x the median corner error with the arm at nominal.
    validate : Stations, optional
        Held-out stations: their reprojection before (arm nominal) and after.
    X0, Y0 : ndarray, shape (4, 4), optional
        Start of X and the board pose (default: the closed form).
    method : str
        Hand-eye closed form of the start.
    rank_tol : float
        Rank threshold of the identifiability analysis.
    extra : dict, optional
        Entries added to the result's JSON (image folder, board spec, rejected images).

    Returns
    -------
    ArmCameraResult

    Raises
    ------
    InputError
        Bad arguments, fewer than 3 stations, motions that do not determine X, a board
        behind the camera (joints that do not fit the images).
    """
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate(model, stations, K, dist, setup, free, refine_intrinsics, rational,
                         loss, f_scale, validate, X0, Y0, method, rank_tol)
    res.warnings = list(found)
    res.extra.update(extra or {})
    return res


def _calibrate(model, st, K, dist, setup, free, refine_intrinsics, rational, loss, f_scale,
               validate, X0, Y0, method, rank_tol) -> ArmCameraResult:
    t0 = time.perf_counter()
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if len(st.q) < 3:
        raise InputError(f"{len(st.q)} usable stations: calibrating an arm from images needs "
                         "at least 3 (many more in practice: 20-40)")
    if X0 is None or Y0 is None:
        X0, Y0, _ = closed_form_start(model, st.q, st.target2cam, setup, method=method,
                                      robust=loss != "linear")
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    block = PixelBlock(model, st.q, st.points, st.pixels, setup, K, dist, X0, Y0, n_int)
    p0 = model.nominal
    n, nn = block.n_stations, block.n_nuisance
    keep = np.ones(n, bool)
    # 2. hand-eye only (arm nominal)
    r0 = block.residuals(p0, np.zeros(nn))
    scale = f_scale if f_scale is not None else _scale_of(r0)
    he = _fit(block, p0, np.zeros(0, np.intp), np.zeros(nn), keep, loss, scale)
    nu_he = he.x
    r_he = block.residuals(p0, nu_he)
    # 3. what the pixels identify
    cands = candidate_names(model, free)
    ident = camera_identifiability(block, p0, nu_he, cands, tol=rank_tol)
    names = ident.report.identifiable if free == "identifiable" else cands
    index = model.index(names)
    if 2 * block.n_corners < index.size + nn:
        raise InputError(f"{block.n_corners} corners give {2 * block.n_corners} equations for "
                         f"{index.size + nn} unknowns")
    # 4. the bundle adjustment
    if f_scale is None:
        scale = _scale_of(r_he)
    z0 = np.concatenate([p0[index], nu_he])
    sol = _fit(block, p0, index, z0, keep, loss, scale)
    nit, nfev, history = he.nit + sol.nit, he.nfev + sol.nfev, list(sol.history)
    params = p0.copy()
    params[index] = sol.x[:index.size]
    r = block.residuals(params, sol.x[index.size:])
    srms = block.station_rms(r)
    flagged = _flag(block, srms, r, keep)
    if flagged.sum() > 0 and loss != "linear" and (~flagged).sum() >= 3:
        keep = ~flagged
        sol = _fit(block, p0, index, sol.x, keep, loss, scale)
        nit, nfev = nit + sol.nit, nfev + sol.nfev
        history += sol.history[1:]
        params[index] = sol.x[:index.size]
        r = block.residuals(params, sol.x[index.size:])
        srms = block.station_rms(r)
    nu = sol.x[index.size:]
    # 5. covariance on the kept stations (unit weights)
    _, J = sol.residual, sol.jacobian
    rk = r.reshape(-1, 2)[keep[block.sid]].ravel()
    colnorm = np.linalg.norm(J, axis=0)
    unc = subspace_uncertainty(J.T @ J, float(rk @ rk), rk.size,
                               ident.report.rank + nn if free != "identifiable"
                               else index.size + nn,
                               1.0 / np.where(colnorm > 0, colnorm, 1.0))
    val = None
    if validate is not None and len(validate.q):
        vb = PixelBlock(model, validate.q, validate.points, validate.pixels, setup, K, dist,
                        X0, Y0, n_int)
        val = (vb.station_rms(vb.residuals(p0, nu_he)), vb.station_rms(vb.residuals(params, nu)))
    res = ArmCameraResult.build(
        model, block, st, names, params, nu, nu_he, unc, ident, loss,
        before=block.station_rms(r_he), after=srms, r_after=r,
        outliers=[int(i) for i in np.flatnonzero(flagged)], validation=val,
        iterations=nit, evaluations=nfev, history=history, success=sol.success,
        seconds=time.perf_counter() - t0)
    check_camera_fit(res)
    return res
